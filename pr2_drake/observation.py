"""The original platform's observation and action dictionaries, to and from the testbed ports.

Observation (``obs``)::

    obs["agent"]["joint_state"]["arms_positions" | "arms_velocities" | "arms_applied_effort"
                                | "legs_positions" | "legs_velocities" | "legs_applied_effort"]
    obs["agent"]["body_state"]["world_pos" (3) | "world_orient" (w, x, y, z)
                               | "linear_velocities" (3) | "angular_velocities" (3)]
    obs["cam"]["rgb"] (H x W x 3 uint8), obs["cam"]["distance_to_image_plane"] (H x W float32, m)
    obs["cam"]["time"]           simulated time the frame was rendered at [s] (older than
                                 ``time`` when the action's ``camera_capture`` was False)
    obs["pick"]                  bool: something is attached to a hand
    obs["pick_state"]            {"hand": ..., "object": ...}
    obs["time"]                  simulated time [s]
    obs["start_pos"], obs["start_orient"]    the episode's start pose (w, x, y, z)
    obs["language_instruction"]  the task sentence (task 6), "" otherwise
    obs["goal"], ...             the task's priors and feedback, under their own keys
                                 (``goal`` repeats ``goal_center`` where a task has one)

The original platform's keys and places, in addition (a solver written for it reads them)::

    obs["current_sim_step"]      int: physics steps since the episode started
                                 (round(time / physics time step); 0 in the first observation),
                                 the original's step counter
    obs["agent"]["start_pos"], obs["agent"]["start_orient"]   the start pose again, where the
                                 original put it (position [m]; quaternion w, x, y, z)
    obs["agent"]["stiffness"], obs["agent"]["dampings"]   (18,) the spring-damper gains in
                                 effect per joint [Nm/rad], [Nm s/rad], arms (8) then legs (10)
                                 in the original order: those of the group's last command if it
                                 carried gains, else the testbed's defaults (``arm_gains``,
                                 ``leg_gains``), capped for stability as the actuation applies
                                 them (:class:`pr2_drake.actuation.ActuationAdapter`); they act
                                 in position and velocity modes only
    obs["obstacle"]              task 3: {"position": the bar centre (3) [m], "orientation":
                                 the bar's (fixed) orientation (w, x, y, z)}, world frame, from
                                 the task feedback (``bar_position``, ``bar_orientation``)
    obs["goal"]                  task 6: the instruction sentence (the original's ``goal``
                                 text; the same as ``language_instruction``)

Action::

    {"arms": {"ctrl_mode": "position" | "velocity" | "effort", "joint_values": [8],
              "stiffness": [8] or None, "dampings": [8] or None},
     "legs": {... same with 10 values ...},
     "pick": "left_hand" | "right_hand" | None,
     "release": bool,
     "camera_capture": bool}   optional; False: the head camera renders no new frame while
                               this action holds (``obs["cam"]`` keeps the last one); absent
                               or None: it renders at every sample (its ``fps``)

All angles in rad, positions in m, in the world frame; joints in the original order
(:data:`pr2_drake.robot.params.ARM_JOINTS`, :data:`LEG_JOINTS`). A malformed action is a
ValueError naming the key path and the fault (see :func:`parse_action`). Empty ``stiffness`` /
``dampings`` lists (what the original's solvers send with effort commands) mean None.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pr2_drake.ports import (
    EFFORT_ARMS,
    EFFORT_LEGS,
    N_ARMS,
    N_LEGS,
    P_WB,
    PICK_VALUES,
    Q_ARMS,
    Q_LEGS,
    QUAT_WB,
    V_ARMS,
    V_LEGS,
    V_WB,
    W_WB,
    JointGroupCommand,
    check_mode,
    real_vector,
    validate_command,
)

ACTION_KEYS = ("arms", "legs", "pick", "release", "camera_capture")
GROUP_KEYS = ("ctrl_mode", "joint_values", "stiffness", "dampings")
GROUP_SIZES = {"arms": N_ARMS, "legs": N_LEGS}


def joint_and_body_obs(joint_state: np.ndarray, body_state: np.ndarray) -> dict[str, Any]:
    """obs["agent"] from the testbed's ``joint_state`` and ``body_state`` vectors."""
    return {
        "joint_state": {
            "arms_positions": joint_state[Q_ARMS].copy(),
            "arms_velocities": joint_state[V_ARMS].copy(),
            "arms_applied_effort": joint_state[EFFORT_ARMS].copy(),
            "legs_positions": joint_state[Q_LEGS].copy(),
            "legs_velocities": joint_state[V_LEGS].copy(),
            "legs_applied_effort": joint_state[EFFORT_LEGS].copy(),
        },
        "body_state": {
            "world_pos": body_state[P_WB].copy(),
            "world_orient": body_state[QUAT_WB].copy(),
            "linear_velocities": body_state[V_WB].copy(),
            "angular_velocities": body_state[W_WB].copy(),
        },
    }


def observation_from_ports(values: dict[str, Any], time: float, priors: dict[str, Any],
                           start_pos: np.ndarray, start_orient: np.ndarray) -> dict[str, Any]:
    """The observation dictionary from the testbed's output values (``joint_state``,
    ``body_state``, ``pick_state``; ``rgbd`` where there is a camera; ``task_feedback``,
    ``instruction`` and ``score`` where there is a task; ``sim_step`` (int) and
    ``joint_gains`` ((stiffness (18), damping (18)), see
    :meth:`pr2_drake.testbed.Testbed.joint_gains`) where known), the time [s], the task's priors
    and the start pose (position [m], quaternion w, x, y, z).
    :meth:`pr2_drake.env.Env.observation` and the competition sandbox both build it here."""
    obs: dict[str, Any] = dict(priors)
    if "goal_center" in obs:  # the original platform's key for the goal prior
        obs["goal"] = obs["goal_center"]
    elif isinstance(obs.get("instruction"), str):  # task 6: the original's goal is the sentence
        obs["goal"] = obs["instruction"]
    obs["agent"] = joint_and_body_obs(values["joint_state"], values["body_state"])
    obs["agent"]["start_pos"] = np.array(start_pos, dtype=float)
    obs["agent"]["start_orient"] = np.array(start_orient, dtype=float)
    gains = values.get("joint_gains")
    if gains is not None:
        obs["agent"]["stiffness"] = np.array(gains[0], dtype=float)
        obs["agent"]["dampings"] = np.array(gains[1], dtype=float)
    if values.get("sim_step") is not None:
        obs["current_sim_step"] = int(values["sim_step"])
    pick_state = values["pick_state"]
    obs["pick"] = bool(pick_state.attached)
    obs["pick_state"] = {"hand": pick_state.hand, "object": pick_state.object}
    obs["time"] = time
    obs["start_pos"] = np.array(start_pos, dtype=float)
    obs["start_orient"] = np.array(start_orient, dtype=float)
    obs["language_instruction"] = ""
    if "rgbd" in values:
        frame = values["rgbd"]
        obs["cam"] = {"rgb": frame.color, "distance_to_image_plane": frame.depth,
                      "time": float(frame.time)}
    if "task_feedback" in values:
        feedback = values["task_feedback"]
        obs.update(feedback)
        obs["language_instruction"] = values["instruction"]
        obs["score"] = float(values["score"][0])
        if "bar_position" in feedback:  # task 3: the original's obstacle entry
            obs["obstacle"] = {
                "position": np.array(feedback["bar_position"], dtype=float),
                "orientation": np.array(feedback.get("bar_orientation", (1.0, 0.0, 0.0, 0.0)),
                                        dtype=float),
            }
    return obs


def state_vectors(obs: dict[str, Any], check_finite: bool = True
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The ``joint_state`` (54) and ``body_state`` (13) vectors of an observation dictionary:
    the inverse of :func:`joint_and_body_obs`, and the one converter every controller's and
    agent's dictionary interface uses.

    Reads ``obs["agent"]["joint_state"]`` (arms optional: zeros; arm efforts from
    ``arms_efforts`` or ``arms_applied_effort``, NaN = unknown when absent; leg efforts from
    ``legs_applied_effort``, zeros when absent) and ``obs["agent"]["body_state"]`` (world_pos,
    world_orient (w, x, y, z), linear_velocities, angular_velocities).

    Raises:
        ValueError: an entry is missing or malformed, or (``check_finite``) a position,
            velocity or pose is not finite; the message names it.
    """
    try:
        agent = obs["agent"]
        js = agent["joint_state"]
        bs = agent["body_state"]
        legs_q = np.asarray(js["legs_positions"], dtype=float).reshape(-1)
        legs_v = np.asarray(js["legs_velocities"], dtype=float).reshape(-1)
        arms_q = np.asarray(js.get("arms_positions", np.zeros(N_ARMS)), dtype=float).reshape(-1)
        arms_v = np.asarray(js.get("arms_velocities", np.zeros(N_ARMS)), dtype=float).reshape(-1)
        arms_e = js.get("arms_efforts", js.get("arms_applied_effort"))
        arms_e = (np.full(N_ARMS, np.nan) if arms_e is None
                  else np.asarray(arms_e, dtype=float).reshape(-1))
        legs_e = np.asarray(js.get("legs_applied_effort", np.zeros(N_LEGS)),
                            dtype=float).reshape(-1)
        pos = np.asarray(bs["world_pos"], dtype=float).reshape(-1)
        quat = np.asarray(bs["world_orient"], dtype=float).reshape(-1)
        lin = np.asarray(bs["linear_velocities"], dtype=float).reshape(-1)
        ang = np.asarray(bs["angular_velocities"], dtype=float).reshape(-1)
    except (KeyError, TypeError) as err:
        raise ValueError(f"obs: missing or malformed observation entry: {err}") from err
    for name, arr, n in (("legs_positions", legs_q, N_LEGS), ("legs_velocities", legs_v, N_LEGS),
                         ("arms_positions", arms_q, N_ARMS), ("arms_velocities", arms_v, N_ARMS),
                         ("world_pos", pos, 3), ("world_orient", quat, 4),
                         ("linear_velocities", lin, 3), ("angular_velocities", ang, 3)):
        if arr.shape != (n,) or (check_finite and not np.all(np.isfinite(arr))):
            raise ValueError(f"obs: {name} must be {n} finite values, got {arr}")
    for name, arr, n in (("arms_efforts", arms_e, N_ARMS), ("legs_applied_effort", legs_e, N_LEGS)):
        if arr.shape != (n,):
            raise ValueError(f"obs: {name} must be {n} values, got {arr}")
    joint_state = np.concatenate([arms_q, legs_q, arms_v, legs_v, arms_e, legs_e])
    body_state = np.concatenate([pos, quat, lin, ang])
    return joint_state, body_state


def group_command(action: dict[str, Any], group: str) -> JointGroupCommand:
    """Parse ``action[group]`` (a group dict or a :class:`JointGroupCommand`) into a new,
    validated command with a plain-str mode and float64 arrays.

    Raises:
        ValueError: naming the key path (e.g. ``action['legs']['joint_values']``) and the fault.
    """
    where = f"action[{group!r}]"
    n = GROUP_SIZES[group]
    entry = action[group]
    if isinstance(entry, JointGroupCommand):
        validate_command(where, entry, n)
        return JointGroupCommand(
            str(entry.mode),
            real_vector(entry.values, n, f"{where}: values"),
            None if entry.stiffness is None else real_vector(entry.stiffness, n, where),
            None if entry.damping is None else real_vector(entry.damping, n, where),
        )
    if not isinstance(entry, dict):
        raise ValueError(f"{where}: expected a dict with keys {GROUP_KEYS} or a "
                         f"JointGroupCommand, got {type(entry).__name__}")
    unknown = set(entry) - set(GROUP_KEYS)
    if unknown:
        raise ValueError(f"{where}: unknown keys {_names(unknown)}; expected {GROUP_KEYS}")
    if "joint_values" not in entry:
        raise ValueError(f"{where}['joint_values'] is missing")

    def gains(key):
        value = entry.get(key)
        if value is None or (isinstance(value, (list, tuple, np.ndarray)) and len(value) == 0):
            return None  # the original's solvers send [] with effort commands
        return real_vector(value, n, f"{where}[{key!r}]", non_negative=True)

    return JointGroupCommand(
        mode=check_mode(entry.get("ctrl_mode", "position"), f"{where}['ctrl_mode']"),
        values=real_vector(entry["joint_values"], n, f"{where}['joint_values']"),
        stiffness=gains("stiffness"),
        damping=gains("dampings"),
    )


def parse_action(action: dict[str, Any]) -> dict[str, Any]:
    """Validate a PR2 action; returns {"arms": cmd|None, "legs": cmd|None, "pick": str,
    "release": bool, "camera_capture": bool}. Groups absent from the action (or None) are None: keep the previous
    command. Everything is checked before anything is returned, so a refused action changes
    nothing.

    Accepted: group dicts as in the module docstring (``ctrl_mode`` defaults to "position";
    values as lists of ints/floats or real numpy arrays of the group's length, see
    :func:`pr2_drake.ports.real_vector`) or :class:`JointGroupCommand` objects; ``pick`` None,
    "" (no pick), "left_hand" or "right_hand" (str, numpy str too); ``release`` a bool or
    numpy bool, None = False; ``camera_capture`` a bool or numpy bool, None or absent = True
    (the camera renders at every sample).

    Raises:
        ValueError: naming the key (``action['legs']['joint_values']``, ``action['pick']``...)
            and the fault.
    """
    if not isinstance(action, dict):
        raise ValueError(f"action: expected a dict with keys {ACTION_KEYS}, got {type(action).__name__}")
    unknown = set(action) - set(ACTION_KEYS)
    if unknown:
        raise ValueError(f"action: unknown keys {_names(unknown)}; expected some of {ACTION_KEYS}")
    out: dict[str, Any] = {}
    for group in ("arms", "legs"):
        out[group] = group_command(action, group) if action.get(group) is not None else None
    pick = action.get("pick")
    if pick is None:
        pick = ""
    if not isinstance(pick, str) or pick not in PICK_VALUES:
        shown = repr(pick) if isinstance(pick, str) else f"{type(pick).__name__} {pick!r:.60}"
        raise ValueError(f"action['pick']: expected 'left_hand', 'right_hand' or None, got {shown}")
    out["pick"] = str(pick)
    out["release"] = _bool_field(action, "release", False)
    out["camera_capture"] = _bool_field(action, "camera_capture", True)
    return out


def _bool_field(action: dict, key: str, default: bool) -> bool:
    """``action[key]`` as a bool (missing or None: ``default``); ValueError naming the key."""
    value = action.get(key)
    if value is None:
        return default
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"action[{key!r}]: expected a bool, got "
                         f"{type(value).__name__} {value!r:.60}")
    return bool(value)


def _names(keys) -> list:
    """Unknown keys for a message, sorted whatever their types."""
    return sorted(keys, key=repr)


def command_to_dict(cmd: JointGroupCommand) -> dict[str, Any]:
    """A JointGroupCommand as the original action's group dict."""
    return {
        "ctrl_mode": cmd.mode,
        "joint_values": np.asarray(cmd.values, dtype=float),
        "stiffness": None if cmd.stiffness is None else np.asarray(cmd.stiffness, dtype=float),
        "dampings": None if cmd.damping is None else np.asarray(cmd.damping, dtype=float),
    }

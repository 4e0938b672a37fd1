"""One connection's controller behind the walking-controller protocol, and how it is set up.

:class:`ControllerServerConfig` says which controller a session runs (walking and jump
parameters, terrain, timing); :meth:`ControllerServerConfig.for_task` gives task N's, as the
original platform's ``taskN_controller`` (table: params/controllers/task_servers.yaml).
:class:`WalkingSession` answers decoded requests (:mod:`pr2_drake.porting.protocol`) with the
built-in whole-body controller (:class:`pr2_drake.controllers.jumping.JumpController`).

Time: a request's ``time`` field, when present, is the simulation time; otherwise the n-th
valid request (from 0) of the session is at ``n * request_period`` (default one physics step:
the testbed's default, 4 ms, or the task's for :meth:`ControllerServerConfig.for_task`; the
original's solvers call the server once per step). The control law runs
every ``control_period`` of that time (4 ms, in walking.yaml) and the torques are held in
between. A time earlier than the last one restarts the controller (a new episode).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from pr2_drake.porting.protocol import JUMP_STATE, ProtocolError, parse_request
from pr2_drake.testbed import DEFAULT_TIME_STEP, task_time_step

#: The folder (in the data root) of the walking and jump parameter files.
PARAMS_DIR = "params/controllers"
TERRAINS = ("flat", "rough", "slope", "stairs")
#: Each task's server settings (fields of ControllerServerConfig), in the data root.
TASK_SERVERS = f"{PARAMS_DIR}/task_servers.yaml"


@dataclass
class ControllerServerConfig:
    """How a session's controller is built and timed.

    Attributes:
        task: the task id whose priors give the ``slope`` and ``stairs`` terrains (None: none).
        walking: walking parameters (a YAML file; a bare name that is no file here is the
            built-in file of that name, see :func:`param_file`).
        overrides: a partial walking YAML applied on top (e.g. walking_rough.yaml).
        terrain: footholds: "flat"; "rough" (unknown stones: the swing sole aims
            ``rough_drop`` below the stance sole and touches down on contact, as the task-1
            reference agent does); "slope" (task 4's incline, from its priors); "stairs"
            (task 5's steps, from its priors: every sole on a tread).
        rough_drop: [m] see ``terrain``.
        jumping: jump parameters (YAML); ``jump_overrides``: a partial jump YAML on top.
        jump_apex: [m] CoM rise of a jump asked for with ``change_state`` 2.
        request_period: [s] simulated time between two requests without a ``time`` field.
    """

    task: int | None = None
    walking: str = "walking.yaml"
    overrides: str | None = None
    terrain: str = "flat"
    rough_drop: float = 0.025
    jumping: str = "jumping.yaml"
    jump_overrides: str | None = None
    jump_apex: float = 0.18
    request_period: float = DEFAULT_TIME_STEP

    def validate(self) -> None:
        if self.terrain not in TERRAINS:
            raise ValueError(f"terrain must be one of {TERRAINS}, got {self.terrain!r}")
        if self.terrain in ("slope", "stairs") and self.task is None:
            raise ValueError(f"terrain {self.terrain!r} comes from a task's priors: give a task")
        if not (math.isfinite(self.request_period) and 0 < self.request_period <= 1.0):
            raise ValueError(f"request_period must be in (0, 1] s, got {self.request_period!r}")
        if not (math.isfinite(self.jump_apex) and self.jump_apex > 0):
            raise ValueError(f"jump_apex must be > 0 m, got {self.jump_apex!r}")
        if not (math.isfinite(self.rough_drop) and self.rough_drop >= 0):
            raise ValueError(f"rough_drop must be >= 0 m, got {self.rough_drop!r}")

    @staticmethod
    def for_task(task: int | str) -> "ControllerServerConfig":
        """Task N's server, as the original's ``taskN_controller`` (see task_servers.yaml)."""
        from pr2_drake.tasks import task_id

        i = task_id(task)
        entry = _task_table().get(i)
        if entry is None:
            raise ValueError(f"{TASK_SERVERS}: no entry for task {i}")
        known = {f.name for f in fields(ControllerServerConfig)}
        unknown = sorted(set(entry) - known)
        if unknown:
            raise ValueError(f"{TASK_SERVERS}: task {i}: unknown key(s) {unknown}; "
                             f"expected {sorted(known)}")
        return replace(ControllerServerConfig(task=i, request_period=task_time_step(i)), **entry)


def param_file(name: str) -> str:
    """A parameter file's path: ``name`` if it is a file or a path, else the built-in file of
    that name (in :data:`PARAMS_DIR` of the data root)."""
    if "/" in name or Path(name).is_file():
        return name
    return f"{PARAMS_DIR}/{name}"


@lru_cache(maxsize=1)
def _task_table() -> dict[int, dict[str, Any]]:
    from pydrake.common.yaml import yaml_load_file

    from pr2_drake.paths import data_root

    table = yaml_load_file(str(data_root() / TASK_SERVERS))
    return {int(k): dict(v or {}) for k, v in table.items()}


@lru_cache(maxsize=None)
def task_priors(task: int) -> dict[str, Any]:
    """A task's priors (what its agents are told), from its scene built on a scratch plant.
    Tasks 1-5 place their terrain independently of the episode seed."""
    from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
    from pydrake.systems.framework import DiagramBuilder

    from pr2_drake.tasks import get_task

    plant, _ = AddMultibodyPlantSceneGraph(DiagramBuilder(), 0.001)
    scene = get_task(task).build_scene(plant, np.random.default_rng(0))
    return dict(scene.priors)


def _load_params(config: ControllerServerConfig):
    """(walking, jump) parameters of ``config``.

    Raises:
        ValueError: a file is missing or malformed, naming it.
    """
    from pr2_drake.controllers.jump_params import JumpParams
    from pr2_drake.controllers.walking_params import WalkingParams

    stage = config.walking
    try:
        params = WalkingParams.load(param_file(config.walking))
        if config.overrides:
            stage = config.overrides
            params = params.with_overrides(param_file(config.overrides))
        stage = config.jumping
        jump = JumpParams.load(param_file(config.jumping))
        if config.jump_overrides:
            stage = config.jump_overrides
            jump = jump.with_overrides(param_file(config.jump_overrides))
    except FileNotFoundError:
        raise ValueError(f"{stage}: not found (neither as given nor as a built-in parameter "
                         f"file)") from None
    except Exception as e:  # the YAML parser's and the schema's errors
        raise ValueError(f"{stage}: {' '.join(str(e).split())}") from None
    return params, jump


def build_controller(config: ControllerServerConfig):
    """The session's :class:`JumpController` (walking, terrain and jump set up by ``config``).

    Raises:
        ValueError: a parameter file is missing or malformed, naming it.
    """
    from pr2_drake.controllers.jumping import JumpController

    params, jump = _load_params(config)
    terrain, footsteps = None, None
    if config.terrain == "rough":
        from pr2_drake.controllers.planning.terrain import RoughTerrain

        terrain = RoughTerrain(config.rough_drop)
    elif config.terrain == "slope":
        from pr2_drake.controllers.planning.terrain import SlopeTerrain

        priors = task_priors(config.task)
        goal = np.asarray(priors["goal_center"], dtype=float)
        terrain = SlopeTerrain(math.radians(float(priors["slope_angle_deg"])), goal,
                               float(goal[2]))
    elif config.terrain == "stairs":
        from pr2_drake.controllers.planning.terrain import stairs_from_priors
        from pr2_drake.controllers.planning.tread_steps import TreadFootstepPlanner

        terrain = stairs_from_priors(task_priors(config.task))
        footsteps = TreadFootstepPlanner(params.gait, params.limits.start_threshold, terrain)
    return JumpController(params, jump, footsteps=footsteps, terrain=terrain)


class WalkingSession:
    """One episode's controller behind the protocol: :meth:`answer` takes a decoded request
    and returns the reply. Build once per connection, :meth:`reset` per episode."""

    def __init__(self, config: ControllerServerConfig | None = None):
        self.config = config or ControllerServerConfig()
        self.config.validate()
        self.controller = build_controller(self.config)
        self.reset()

    def reset(self) -> None:
        """Start a new episode: the controller's gait, jump and clock restart."""
        self.controller.reset()
        self.requests = 0  # valid requests answered in this episode
        self.last_time: float | None = None
        self.last_state = 0

    def answer(self, request: Any) -> dict[str, Any]:
        """The reply to one decoded request: ``{"mode": "effort", "effort": [10 leg torques,
        Nm], "time": t, "jump_phase": name, "jumps": n}``.

        Raises:
            ProtocolError: the request is malformed (nothing changed).
        """
        obs, command, state, t = parse_request(request)
        if t is None:
            t = self.requests * self.config.request_period
        if self.last_time is not None and t < self.last_time - 1e-9:
            self.reset()  # the simulation restarted
        jumper = self.controller.jump
        busy = jumper.pending is not None or jumper.planner.active
        jump = None
        if state == JUMP_STATE and self.last_state != JUMP_STATE and not busy:
            v = command[:2].copy()
            speed = float(np.hypot(*v))
            if speed > jumper.params.max_speed:
                v *= jumper.params.max_speed / speed
            jump = (t, v[0], v[1], self.config.jump_apex)
            busy = True
        if busy:
            command = np.zeros(3)  # the robot stands to crouch; walking resumes after landing
        try:
            action = self.controller.command(obs, *command, t=t, jump=jump)
        except ValueError as e:
            raise ProtocolError(str(e)) from None
        self.requests += 1
        self.last_time = t
        self.last_state = state
        return {"mode": "effort", "effort": [float(x) for x in action["joint_values"]],
                "time": t, "jump_phase": jumper.phase.name, "jumps": int(jumper.jumps)}

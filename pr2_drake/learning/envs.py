"""The gymnasium envs: :class:`CommandEnv` (command level) and :class:`JointEnv` (joint level).

Both run one :class:`pr2_drake.episode.Episode` per env (the same path as ``pr2-drake run``),
reset it in place to a new seed where the task's seed only moves the start pose (tasks 1-5:
about 0.05 s instead of a ~1 s rebuild; :func:`pr2_drake.env.reseed`), observe with
:class:`pr2_drake.learning.observe.Observer` (a Dict; ``FlattenObservation`` gives the flat
form) and reward with :class:`pr2_drake.learning.rewards.Reward`.

- ``reset(seed=s)`` runs the episode of seed s (the seed of ``pr2-drake run --seed s``);
  ``reset()`` draws the next seed from ``np_random`` (so it starts somewhere new).
- ``terminated``: the episode ended for any reason but the time limit (fell, left the arena,
  completed, diverged); ``truncated``: the time limit (the task's, or ``seconds``).
- ``info``: ``time`` [s], ``score``, ``termination``, ``seed``, ``reward_terms`` (summing to the
  reward), ``items`` (the rubric items earned); at reset also ``action_names``.
- ``render()`` (``render_mode="rgb_array"``): an overview camera's picture of the scene now.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from pr2_drake.env import reseed, restart
from pr2_drake.episode import Episode
from pr2_drake.learning.observe import DEPTH_MAX, Observer
from pr2_drake.learning.rewards import Reward
from pr2_drake.ports import N_ARMS, N_LEGS, JointGroupCommand
from pr2_drake.scenario import Scenario, ScenarioError

RENDER_SIZE = (320, 240)  # [px] render() picture (width, height)
SEED_RANGE = 2 ** 31  # reset() without a seed draws the episode seed from [0, this)


class _LearningEnv(gym.Env):
    """What both levels share (see the module docstring).

    Args:
        task: task id or name.
        control_dt: simulated seconds per step [s] (default: the level's rate).
        reward: "dense" (default) or "rubric" (the rubric points alone).
        camera: add the head camera's colour and depth, downsized by ``camera_scale``, to the
            observation.
        seconds: end episodes "timeout" (truncated) after this many simulated seconds
            (default: the task's time limit).
        scenario: everything else about the episodes (physics, limits); its task and seed
            are replaced.
        render_mode: None or "rgb_array".
        reuse: reset to a new seed in place where the task allows it (default); False:
            rebuild the episode at every new seed.
        randomize: turn on the scenario's domain randomisation (its ``randomize`` section,
            with its defaults unless ``scenario`` sets them); each episode's draw is in
            ``info["physics"]`` at reset.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}
    DEFAULT_DT = 0.01
    #: [s] the physics step when ``scenario`` gives none; None = the task's
    TIME_STEP: float | None = None

    def __init__(self, task: int | str = 1, *, control_dt: float | None = None,
                 reward: str = "dense", camera: bool = False, camera_scale: float = 0.25,
                 seconds: float | None = None, scenario: Scenario | None = None,
                 render_mode: str | None = None, reuse: bool = True, randomize: bool = False):
        super().__init__()
        self._reuse = bool(reuse)
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        self.control_dt = float(control_dt or self.DEFAULT_DT)
        base = scenario or Scenario()
        changes: dict[str, Any] = {"task": task, "seed": 0}
        if seconds is not None:
            changes["seconds"] = float(seconds)
        if randomize:
            changes["randomize"] = replace(base.randomize, enabled=True)
        if base.plant.time_step is None and self.TIME_STEP is not None:
            changes["plant"] = replace(base.plant, time_step=self.TIME_STEP)
        if camera:
            from pr2_drake.run import task_camera

            changes["camera"] = replace(base.camera or task_camera(replace(base, **changes)),
                                        enabled=True)
        self._scenario = replace(base, **changes)
        self._scenario.validate()
        if self._scenario.task is None:
            raise ScenarioError("the learning envs need a task")
        step = self._scenario.testbed_config().time_step
        if abs(self.control_dt / step - round(self.control_dt / step)) > 1e-6:
            raise ScenarioError(f"control_dt ({self.control_dt:g} s) must be a whole number of "
                                f"physics steps ({step:g} s)")
        self.render_mode = render_mode
        self._camera_scale = float(camera_scale)
        self._camera = bool(camera)
        self._reward = Reward(reward)
        self._episode: Episode | None = None
        self._build(0)
        self.observation_space = spaces.Dict({
            k: (spaces.Box(0, 255, shape, np.uint8) if k == "rgb" else
                spaces.Box(0.0, DEPTH_MAX, shape, np.float32) if k == "depth" else
                spaces.Box(-np.inf, np.inf, shape, np.float32))
            for k, shape in self._observer.shapes().items()})
        n = len(self.action_names)
        self.action_space = spaces.Box(-1.0, 1.0, (n,), np.float32)

    # -- to implement --------------------------------------------------------------------------
    action_names: tuple = ()

    def _wire(self, builder, testbed):
        """Add the level's blocks to the episode's diagram."""

    def _apply(self, action: np.ndarray) -> None:
        """Fix ``action`` (clipped to [-1, 1]) on the diagram's inputs."""
        raise NotImplementedError

    def _reset_blocks(self) -> None:
        """Fix the inputs' initial values, reset the blocks' memory outside the Context."""

    # -- gymnasium API -------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        episode_seed = int(seed) if seed is not None else int(self.np_random.integers(SEED_RANGE))
        ep = self._episode
        if episode_seed != ep.scenario.seed and not (self._reuse and reseed(ep, episode_seed)):
            self._build(episode_seed)
            ep = self._episode
        restart(ep)
        self._reset_blocks()
        ep.initialize()
        self._reward.reset(ep, self.action_space.shape[0])
        info = self._info({})
        info["action_names"] = self.action_names
        if getattr(ep, "physics", None) is not None:
            info["physics"] = ep.physics.report()
        return self._observe(), info

    def step(self, action):
        ep = self._episode
        a = np.clip(np.asarray(action, dtype=np.float64).reshape(self.action_space.shape),
                    -1.0, 1.0)
        if not ep.status.done:
            self._apply(a)
            ep.advance_to(ep.time + self.control_dt)
        reward, terms = self._reward.step(ep, a)
        status = ep.status
        truncated = bool(status.done and status.termination == "timeout")
        terminated = bool(status.done and not truncated)
        return self._observe(), reward, terminated, truncated, self._info(terms)

    def render(self):
        if self.render_mode != "rgb_array":
            return None
        sensor = self._overview
        return sensor.color_image_output_port().Eval(
            sensor.GetMyContextFromRoot(self._episode.context)).data[:, :, :3].copy()

    def close(self):
        self._episode = None

    # -- the episode ---------------------------------------------------------------------------
    @property
    def episode(self) -> Episode:
        """The episode being run (its testbed, diagram, context and verdict)."""
        return self._episode

    def _build(self, seed: int) -> None:
        self._episode = None  # let the old diagram go before the new one is built
        scenario = replace(self._scenario, seed=int(seed))

        def wire(builder, testbed):
            blocks = self._wire(builder, testbed)
            if self.render_mode == "rgb_array":
                self._overview = _add_overview_camera(builder, testbed)
            return blocks

        self._episode = Episode(scenario, wire)
        tb = self._episode.testbed
        camera_shape = None
        if self._camera:
            cam = tb.camera
            camera_shape = (max(1, round(cam.height * self._camera_scale)),
                            max(1, round(cam.width * self._camera_scale)))
        self._observer = Observer(tb.task.name, tb.scene.priors, camera_shape)
        self._ports = {tb.get_input_port(i).get_name(): tb.get_input_port(i)
                       for i in range(tb.num_input_ports())}

    def _observe(self) -> dict[str, np.ndarray]:
        ep = self._episode
        tb, ctx = ep.testbed, ep.tb_context
        values = {name: tb.GetOutputPort(name).Eval(ctx)
                  for name in ("joint_state", "body_state", "pick_state", "task_feedback")}
        if self._camera:
            values["rgbd"] = tb.GetOutputPort("rgbd").Eval(ctx)
        if "valve_joint" in tb.scene.data:
            values["valve_angle"] = tb.plant.get_joint(tb.scene.data["valve_joint"]).get_angle(
                ep.plant_context)
        status = ep.status
        progress = (status.score / status.max_score if status.max_score else 0.0,
                    ep.time / ep.limit if math.isfinite(ep.limit) else 0.0)
        return self._observer.observe(values, progress)

    def _info(self, terms: dict[str, float]) -> dict[str, Any]:
        ep = self._episode
        s = ep.status
        return {"time": ep.time, "score": float(s.score), "termination": s.termination,
                "seed": int(ep.scenario.seed), "reward_terms": terms,
                "items": [e.item for e in s.items]}


def _add_overview_camera(builder, testbed):
    """An RgbdSensor over the task's arena (:func:`pr2_drake.viz.default_overview_pose`); its
    image is rendered only when render() asks for it."""
    from pydrake.geometry import (ClippingRange, ColorRenderCamera, DepthRange,
                                  DepthRenderCamera, MakeRenderEngineVtk, RenderCameraCore)
    from pydrake.math import RigidTransform
    from pydrake.systems.sensors import CameraInfo, RgbdSensor

    from pr2_drake.camera import renderer_params
    from pr2_drake.viz import OVERVIEW_RENDERER, default_overview_pose

    sg = testbed.scene_graph
    if not sg.HasRenderer(OVERVIEW_RENDERER):
        sg.AddRenderer(OVERVIEW_RENDERER, MakeRenderEngineVtk(renderer_params("low")))
    w, h = RENDER_SIZE
    core = RenderCameraCore(OVERVIEW_RENDERER, CameraInfo(w, h, np.radians(55.0)),
                            ClippingRange(0.05, 100.0), RigidTransform())
    sensor = builder.AddSystem(RgbdSensor(sg.world_frame_id(), default_overview_pose(testbed),
                                          ColorRenderCamera(core, False),
                                          DepthRenderCamera(core, DepthRange(0.1, 90.0))))
    builder.Connect(testbed.GetOutputPort("geometry_query"), sensor.query_object_input_port())
    return sensor


class CommandEnv(_LearningEnv):
    """The command level (:mod:`pr2_drake.learning.command`): the action commands the task's
    built-in whole-body controller, held for ``control_dt`` (default 0.1 s, 10 Hz).

    Args (besides :class:`_LearningEnv`'s):
        command_params: a :class:`pr2_drake.learning.command.CommandLevelParams` or a YAML
            path (default params/learning/command.yaml: ranges, default rate).
    """

    def __init__(self, task: int | str = 1, *, command_params=None, **kwargs):
        from pr2_drake.learning.command import CommandLevelParams

        if command_params is None or isinstance(command_params, str):
            command_params = CommandLevelParams.load(command_params)
        self._params = command_params
        kwargs.setdefault("control_dt", command_params.control_dt)
        super().__init__(task, **kwargs)

    def _wire(self, builder, testbed):
        from pr2_drake.learning.command import CommandLevel

        level = CommandLevel(testbed.task.id, testbed.scene.priors,
                             bool(testbed.scene.graspables), self._params)
        builder.AddSystem(level)
        level.connect(builder, testbed)
        self.action_names = level.layout.names
        self._level = level
        return level

    def _reset_blocks(self) -> None:
        ep = self._episode
        ctx = self._level.GetMyMutableContextFromRoot(ep.context)
        self._level.GetInputPort("action").FixValue(ctx, np.zeros(len(self.action_names)))
        if "camera_capture" in self._ports:
            self._ports["camera_capture"].FixValue(ep.tb_context, True)
        self._level.reset()

    def _apply(self, action: np.ndarray) -> None:
        ctx = self._level.GetMyMutableContextFromRoot(self._episode.context)
        self._level.GetInputPort("action").FixValue(ctx, action)


class JointEnv(_LearningEnv):
    """The joint level: the original platform's action as a Box, held for ``control_dt``
    (default 0.01 s, 100 Hz), on a 2 ms physics step unless ``scenario`` sets one (10 ms is a
    whole number of 2 ms steps, not of the tasks' 4 ms, and the position mode's stable gains
    are 4x stiffer at 2 ms).

    The action, each entry in [-1, 1]: the legs' 10 values, then (``gains``) their 10
    stiffnesses and 10 dampings, then the arms' 8 values (and gains), then pick_left,
    pick_right, release (> 0: send it). Values by mode (``legs_mode``, ``arms_mode``):
    "position": the nominal standing angle + the value x half the joint's range, clipped to
    the range [rad] (0 holds the standing pose); "velocity": x its speed limit [rad/s];
    "effort": x its peak torque [Nm]. Gains: -1..1 -> 0..the testbed's stable maximum
    (:meth:`pr2_drake.testbed.Testbed.stable_gain_limits`); without ``gains`` the testbed's
    default gains apply.
    """

    TIME_STEP = 0.002

    def __init__(self, task: int | str = 1, *, legs_mode: str = "position",
                 arms_mode: str = "position", gains: bool = False, **kwargs):
        from pr2_drake.ports import CONTROL_MODES

        for name, mode in (("legs_mode", legs_mode), ("arms_mode", arms_mode)):
            if mode not in CONTROL_MODES:
                raise ValueError(f"{name} must be one of {CONTROL_MODES}, got {mode!r}")
        self._modes = {"legs": legs_mode, "arms": arms_mode}
        self._gains = bool(gains)
        names = []
        for group, n in (("legs", N_LEGS), ("arms", N_ARMS)):
            names += [f"{group}_{legs_or_arms_mode}_{i}" for legs_or_arms_mode in
                      ((self._modes[group], "stiffness", "damping") if gains
                       else (self._modes[group],)) for i in range(n)]
        self.action_names = tuple(names) + ("pick_left", "pick_right", "release")
        super().__init__(task, **kwargs)
        from pr2_drake.robot.params import load_robot_params

        params = load_robot_params()
        self._scale = {}
        for group in ("legs", "arms"):
            lo, hi = params.position_limits(group)
            speed = np.array([j.velocity for j in params.group(group)])
            effort = params.effort_limits(group)
            zero = np.zeros_like(lo)
            # (offset, scale, lower, upper): value = clip(offset + a * scale, lower, upper)
            self._scale[group] = {
                "position": (params.default_positions(group), 0.5 * (hi - lo), lo, hi),
                "velocity": (zero, speed, -speed, speed),
                "effort": (zero, effort, -effort, effort)}[self._modes[group]]
        self._gain_max = self._episode.testbed.stable_gain_limits()

    def _reset_blocks(self) -> None:
        tb, ctx, ports = self._episode.testbed, self._episode.tb_context, self._ports
        ports["arms_command"].FixValue(ctx, JointGroupCommand.position(
            tb.params.default_positions("arms")))
        ports["legs_command"].FixValue(ctx, JointGroupCommand.position(
            tb.params.default_positions("legs")))
        ports["pick"].FixValue(ctx, "")
        ports["release"].FixValue(ctx, False)
        if "camera_capture" in ports:
            ports["camera_capture"].FixValue(ctx, True)

    def _apply(self, action: np.ndarray) -> None:
        ctx, ports = self._episode.tb_context, self._ports
        k = 0
        for group, n in (("legs", N_LEGS), ("arms", N_ARMS)):
            offset, scale, lo, hi = self._scale[group]
            values = np.clip(offset + action[k:k + n] * scale, lo, hi)
            k += n
            stiffness = damping = None
            if self._gains:
                kmax, dmax = self._gain_max[group]
                stiffness = 0.5 * (action[k:k + n] + 1.0) * kmax
                damping = 0.5 * (action[k + n:k + 2 * n] + 1.0) * dmax
                k += 2 * n
            ports[f"{group}_command"].FixValue(ctx, JointGroupCommand(
                self._modes[group], values, stiffness, damping))
        pick_left, pick_right, release = action[k:k + 3]
        ports["pick"].FixValue(ctx, "left_hand" if pick_left > 0 else
                               "right_hand" if pick_right > 0 else "")
        ports["release"].FixValue(ctx, bool(release > 0))

"""Env: the testbed as a plain step/reset environment with the original platform's dictionaries.

>>> env = Env(task=1, seed=7)
>>> obs = env.reset()
>>> done, success, obs = env.step({"legs": {"ctrl_mode": "effort", "joint_values": legs_tau}})

The same diagram as :func:`pr2_drake.testbed.build_testbed`; each ``step`` holds the action for
``control_dt`` seconds of simulated time (default: one physics step) and returns the observation
at the end. Dictionary layouts are documented in :mod:`pr2_drake.observation`.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np
from pydrake.geometry import Meshcat
from pydrake.systems.analysis import Simulator

from pr2_drake.observation import joint_and_body_obs, parse_action
from pr2_drake.ports import P_WB, JointGroupCommand
from pr2_drake.tasks.base import EpisodeStatus
from pr2_drake.testbed import Testbed, TestbedConfig

FREE_FALL_HEIGHT = 0.35  # without a task: the robot has fallen below this base height [m]


class EpisodeOver(RuntimeError):
    """step() was called after the episode ended; call reset()."""


class Env:
    """A PR2-style environment over the testbed diagram.

    Args:
        task: task id (1..6) or name, or None for flat ground without a referee.
        seed: episode seed.
        control_dt: simulated seconds per ``step`` [s]; default = the physics time step.
        config: full testbed configuration (its task and seed are replaced by the arguments).
        meshcat: draw to this Meshcat.
        time_limit: episode length [s] without a task (default: unlimited).
    """

    def __init__(
        self,
        task: int | str | None = None,
        seed: int = 0,
        *,
        control_dt: float | None = None,
        config: TestbedConfig | None = None,
        meshcat: Meshcat | None = None,
        time_limit: float | None = None,
    ):
        self._base_config = replace(config or TestbedConfig(), task=task, seed=int(seed))
        self._meshcat = meshcat
        self._time_limit = math.inf if time_limit is None else float(time_limit)
        self.control_dt = float(control_dt or self._base_config.time_step)
        if not self.control_dt > 0:
            raise ValueError(f"control_dt must be positive, got {control_dt}")
        self.testbed: Testbed | None = None
        self._build(self._base_config)

    # -- public API ---------------------------------------------------------------------------
    def reset(self, seed: int | None = None) -> dict[str, Any]:
        """Start a new episode (a new seed rebuilds the scene); returns the first observation."""
        if seed is not None and int(seed) != self.testbed.config.seed:
            self._build(replace(self._base_config, seed=int(seed)))
        ctx = self.simulator.get_mutable_context()
        ctx.SetTimeStateAndParametersFrom(self.testbed.CreateDefaultContext())
        self._fix_defaults()
        self.simulator.Initialize()
        self._status = self._evaluate_status()
        self._diverged = False
        return self.observation()

    def step(self, action: dict[str, Any]) -> tuple[bool, bool, dict[str, Any]]:
        """Apply ``action`` for ``control_dt`` seconds; returns (done, success, obs)."""
        if self._status.done:
            raise EpisodeOver(f"the episode ended ({self._status.termination}); call reset()")
        parsed = parse_action(action)
        ctx = self._ctx
        for group in ("arms", "legs"):
            if parsed[group] is not None:
                self._ports[f"{group}_command"].FixValue(ctx, parsed[group])
        self._ports["pick"].FixValue(ctx, parsed["pick"])
        self._ports["release"].FixValue(ctx, parsed["release"])
        try:
            self.simulator.AdvanceTo(ctx.get_time() + self.control_dt)
            self._status = self._evaluate_status()
        except RuntimeError as e:  # Drake gave up on the dynamics: end the episode
            self._end_diverged(str(e))
        return self._status.done, self._status.success, self.observation()

    @property
    def status(self) -> EpisodeStatus:
        """The referee's verdict so far."""
        return self._status

    @property
    def time(self) -> float:
        return self._ctx.get_time()

    @property
    def priors(self) -> dict[str, Any]:
        return dict(self.testbed.scene.priors)

    def observation(self) -> dict[str, Any]:
        """The observation dictionary at the current time."""
        ctx, ports, tb = self._ctx, self._ports, self.testbed
        obs: dict[str, Any] = {}
        obs.update(tb.scene.priors)
        if "goal_center" in obs:  # the original platform's key for the goal prior
            obs["goal"] = obs["goal_center"]
        obs["agent"] = joint_and_body_obs(
            ports["joint_state"].Eval(ctx), ports["body_state"].Eval(ctx)
        )
        pick_state = ports["pick_state"].Eval(ctx)
        obs["pick"] = bool(pick_state.attached)
        obs["pick_state"] = {"hand": pick_state.hand, "object": pick_state.object}
        obs["time"] = ctx.get_time()
        X = tb.X_WB_start
        obs["start_pos"] = X.translation().copy()
        obs["start_orient"] = X.rotation().ToQuaternion().wxyz()
        obs["language_instruction"] = ""
        if "rgbd" in ports:
            frame = ports["rgbd"].Eval(ctx)
            obs["cam"] = {"rgb": frame.color, "distance_to_image_plane": frame.depth}
        if tb.task is not None:
            obs.update(ports["task_feedback"].Eval(ctx))
            obs["language_instruction"] = ports["instruction"].Eval(ctx)
            obs["score"] = float(ports["score"].Eval(ctx)[0])
        return obs

    def report(self) -> dict[str, Any]:
        """The episode's result in the report.json layout."""
        s = self._status
        tb = self.testbed
        return {
            "task": None if tb.task is None else tb.task.id,
            "task_name": "flat" if tb.task is None else tb.task.name,
            "seed": tb.config.seed,
            "score": s.score,
            "max_score": s.max_score,
            "success": s.success,
            "termination": s.termination,
            "items": [{"item": e.item, "points": e.points, "time": e.time} for e in s.items],
            "sim_time": self._ctx.get_time(),
        }

    # -- internals ----------------------------------------------------------------------------
    @classmethod
    def from_testbed(cls, testbed: Testbed, *, control_dt: float | None = None,
                     time_limit: float | None = None) -> "Env":
        """An Env over an already built testbed (its config and Meshcat are kept)."""
        env = cls.__new__(cls)
        env._base_config = testbed.config
        env._meshcat = testbed.meshcat
        env._time_limit = math.inf if time_limit is None else float(time_limit)
        env.control_dt = float(control_dt or testbed.config.time_step)
        env._adopt(testbed)
        return env

    def _build(self, config: TestbedConfig) -> None:
        if self._meshcat is not None:
            self._meshcat.Delete()
        self._adopt(Testbed(config, self._meshcat))

    def _adopt(self, testbed: Testbed) -> None:
        self.testbed = testbed
        self.simulator = Simulator(self.testbed)
        self._ctx = self.simulator.get_mutable_context()
        tb = self.testbed
        self._ports = {
            tb.get_output_port(i).get_name(): tb.get_output_port(i)
            for i in range(tb.num_output_ports())
        }
        self._ports.update(
            {tb.get_input_port(i).get_name(): tb.get_input_port(i)
             for i in range(tb.num_input_ports())}
        )
        self.reset()

    def _fix_defaults(self) -> None:
        tb, ctx = self.testbed, self._ctx
        self._ports["arms_command"].FixValue(
            ctx, JointGroupCommand.position(tb.params.default_positions("arms"))
        )
        self._ports["legs_command"].FixValue(ctx, JointGroupCommand.effort(np.zeros(10)))
        self._ports["pick"].FixValue(ctx, "")
        self._ports["release"].FixValue(ctx, False)

    def _evaluate_status(self) -> EpisodeStatus:
        if self.testbed.task is not None:
            return self._ports["episode"].Eval(self._ctx)
        t = self._ctx.get_time()
        status = EpisodeStatus(time=t)
        z = self._ports["body_state"].Eval(self._ctx)[P_WB][2]
        if not np.isfinite(z):
            status.done, status.termination = True, "diverged"
        elif z < FREE_FALL_HEIGHT:
            status.done, status.termination = True, "fell"
        elif t >= self._time_limit - 1e-9:
            status.done, status.termination = True, "timeout"
        return status

    def _end_diverged(self, reason: str) -> None:
        s = self._status
        self._status = EpisodeStatus(s.score, s.max_score, True, False, "diverged", list(s.items),
                                     self._ctx.get_time())
        self.divergence_message = reason

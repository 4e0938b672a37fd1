"""Env: the testbed as a plain step/reset environment with the original platform's dictionaries.

>>> from pr2_drake.env import Env
>>> env = Env(task=1, seed=7)
>>> obs = env.reset()
>>> done, success, obs = env.step({"legs": {"ctrl_mode": "effort", "joint_values": [0.0] * 10}})

An :class:`pr2_drake.episode.Episode` without agent blocks: each ``step`` validates the action,
holds it for ``control_dt`` seconds of simulated time (default: one physics step) and returns
the observation at the end. Dictionary layouts are documented in :mod:`pr2_drake.observation`.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
from pydrake.geometry import Meshcat

from pr2_drake.episode import Episode
from pr2_drake.observation import observation_from_ports, parse_action
from pr2_drake.ports import JointGroupCommand
from pr2_drake.scenario import Scenario, check_control_dt
from pr2_drake.tasks.base import EpisodeStatus


def reseed(episode: Episode, seed: int) -> bool:
    """Make ``episode`` the episode of ``seed`` without rebuilding it, where its task's seed
    draws the start pose alone (``TaskDefinition.start_of``) and the scenario fixes no start:
    the testbed's default start pose moves there. Returns False (nothing changed) where the
    scene must be built anew. Call :func:`restart` next."""
    tb = episode.testbed
    if tb.task is None or episode.scenario.start is not None:
        return False
    start = tb.task.start_of(seed)
    if start is None:
        return False
    tb.set_start(start, seed)
    episode.scenario = replace(episode.scenario, seed=int(seed))
    if getattr(episode, "physics", None) is not None:  # domain randomisation: the seed's draw
        episode.redraw_physics(int(seed))
    return True


def restart(episode: Episode) -> None:
    """Put ``episode``'s Context back to time 0 and the default state and parameters (fixed
    input values stay); then ``episode.initialize()``."""
    episode.context.SetTimeStateAndParametersFrom(episode.diagram.CreateDefaultContext())


class EpisodeOver(RuntimeError):
    """step() was called after the episode ended; call reset()."""


class InvalidAction(ValueError):
    """An action failed validation; nothing of it was applied. The message names the key."""


class Env:
    """A PR2-style environment over the testbed diagram.

    Args:
        task: task id (1..6) or name, or None for flat ground without a referee (default: the
            scenario's).
        seed: episode seed (default: the scenario's).
        control_dt: simulated seconds per ``step`` [s]; default = the physics time step.
        scenario: everything else about the episode (physics, camera, limits).
        meshcat: draw to this Meshcat.
        time_limit: end the episode "timeout" after this many simulated seconds (capped by the
            task's own limit; without a task the default is unlimited).

    Raises:
        ScenarioError (a ValueError): a bad argument, naming it.
    """

    def __init__(
        self,
        task: int | str | None = None,
        seed: int | None = None,
        *,
        control_dt: float | None = None,
        scenario: Scenario | None = None,
        meshcat: Meshcat | None = None,
        time_limit: float | None = None,
    ):
        base = scenario or Scenario()
        changes: dict[str, Any] = {"control_dt": control_dt if control_dt is not None
                                   else base.control_dt}
        if task is not None or scenario is None:
            changes["task"] = task
        if seed is not None:
            changes["seed"] = seed
        if time_limit is not None:
            changes["seconds"] = time_limit
        elif scenario is None or (base.seconds is None and changes.get("task", base.task) is None):
            changes["seconds"] = float("inf")
        self._scenario = replace(base, **changes)
        self._meshcat = meshcat
        self._episode: Episode | None = None
        self._build(self._scenario)

    # -- public API ---------------------------------------------------------------------------
    def reset(self, seed: int | None = None) -> dict[str, Any]:
        """Start a new episode; returns the first observation. A new seed moves the start
        pose in the built scene where that is all the seed changes (:func:`reseed`), else
        rebuilds the scene."""
        if seed is not None and int(seed) != self._scenario.seed:
            self._scenario = replace(self._scenario, seed=int(seed))
            if not reseed(self._episode, int(seed)):
                self._build(self._scenario)
                return self.observation()
        restart(self._episode)
        self._fix_defaults()
        self._episode.initialize()
        return self.observation()

    def step(self, action: dict[str, Any]) -> tuple[bool, bool, dict[str, Any]]:
        """Apply ``action`` for ``control_dt`` seconds; returns (done, success, obs).

        Raises:
            InvalidAction (a ValueError): the action is malformed; the message names the key
                and the fault, and nothing of the action was applied.
            EpisodeOver: the episode has ended; call reset().
        """
        ep = self._episode
        if ep.status.done:
            raise EpisodeOver(f"the episode ended ({ep.status.termination}); call reset()")
        self.apply(action)
        status = ep.advance_to(ep.time + self.control_dt)
        return status.done, status.success, self.observation()

    def apply(self, action: dict[str, Any]) -> None:
        """Validate ``action`` and fix it on the testbed's inputs, without simulating (what
        :meth:`step` does first).

        Raises:
            InvalidAction: as :meth:`step`; nothing of the action was applied.
        """
        try:
            parsed = parse_action(action)
        except ValueError as e:
            raise InvalidAction(str(e)) from None
        ctx = self._episode.tb_context
        for group in ("arms", "legs"):
            if parsed[group] is not None:
                self._ports[f"{group}_command"].FixValue(ctx, parsed[group])
        self._ports["pick"].FixValue(ctx, parsed["pick"])
        self._ports["release"].FixValue(ctx, parsed["release"])
        if "camera_capture" in self._ports:  # (without a camera the key changes nothing)
            self._ports["camera_capture"].FixValue(ctx, parsed["camera_capture"])

    @property
    def status(self) -> EpisodeStatus:
        """The verdict so far (see :meth:`pr2_drake.episode.Episode.judge`)."""
        return self._episode.status

    @property
    def message(self) -> str:
        """Why a fault ended the episode ("" otherwise)."""
        return self._episode.message

    @property
    def time(self) -> float:
        return self._episode.time

    @property
    def testbed(self):
        return self._episode.testbed

    @property
    def episode(self) -> Episode:
        return self._episode

    @property
    def control_dt(self) -> float:
        return float(self._scenario.control_dt or self.testbed.config.time_step)

    @property
    def physics(self) -> dict[str, Any] | None:
        """The episode's randomised physics as in the report's ``physics`` (None with the
        scenario's ``randomize`` off; :mod:`pr2_drake.randomize`)."""
        physics = self._episode.physics
        return None if physics is None else physics.report()

    @property
    def priors(self) -> dict[str, Any]:
        return dict(self.testbed.scene.priors)

    def observation(self) -> dict[str, Any]:
        """The observation dictionary at the current time."""
        ctx, tb = self._episode.tb_context, self.testbed
        X = tb.X_WB_start
        return observation_from_ports(self.observation_values(), ctx.get_time(), tb.scene.priors,
                                      X.translation(), X.rotation().ToQuaternion().wxyz())

    def observation_values(self) -> dict[str, Any]:
        """What an observation is built from: the values of :meth:`observation_ports`, plus
        ``sim_step`` (physics steps so far) and ``joint_gains`` (the spring-damper gains in
        effect, :meth:`pr2_drake.testbed.Testbed.joint_gains`)."""
        ctx, tb = self._episode.tb_context, self.testbed
        values = {name: self._ports[name].Eval(ctx) for name in self.observation_ports()}
        values["sim_step"] = int(round(ctx.get_time() / tb.config.time_step))
        values["joint_gains"] = tb.joint_gains(ctx)
        return values

    def observation_ports(self) -> tuple[str, ...]:
        """The testbed outputs an observation is made of (see
        :func:`pr2_drake.observation.observation_from_ports`)."""
        names = ("joint_state", "body_state", "pick_state")
        if "rgbd" in self._ports:
            names += ("rgbd",)
        if self.testbed.task is not None:
            names += ("task_feedback", "instruction", "score")
        return names

    def report(self) -> dict[str, Any]:
        """The episode's result in the report.json layout."""
        return self._episode.report()

    # -- internals ----------------------------------------------------------------------------
    @classmethod
    def from_episode(cls, episode: Episode, *, control_dt: float | None = None) -> "Env":
        """An Env over an already built episode without agent blocks (used by
        :func:`pr2_drake.run.run_episode` for ``next_action`` agents; ``control_dt``: the
        agent's own period, checked here).

        Raises:
            ScenarioError: ``control_dt`` is not a valid control period.
        """
        control_dt = control_dt or episode.scenario.control_dt
        check_control_dt(control_dt)
        env = cls.__new__(cls)
        env._scenario = replace(episode.scenario, control_dt=control_dt)
        env._meshcat = episode.testbed.meshcat
        env._adopt(episode)
        return env

    def _build(self, scenario: Scenario) -> None:
        self._episode = None  # let the old diagram go before the new one is built
        if self._meshcat is not None:
            self._meshcat.Delete()
        self._adopt(Episode(scenario, meshcat=self._meshcat))

    def _adopt(self, episode: Episode) -> None:
        self._episode = episode
        tb = episode.testbed
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
        tb, ctx = self.testbed, self._episode.tb_context
        self._ports["arms_command"].FixValue(
            ctx, JointGroupCommand.position(tb.params.default_positions("arms"))
        )
        self._ports["legs_command"].FixValue(ctx, JointGroupCommand.effort(np.zeros(10)))
        self._ports["pick"].FixValue(ctx, "")
        self._ports["release"].FixValue(ctx, False)
        if "camera_capture" in self._ports:
            self._ports["camera_capture"].FixValue(ctx, True)

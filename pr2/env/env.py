"""The original platform's ``Env(task_num, seed)`` on a pr2-drake environment.

``reset()`` and ``step(action)`` return ``(done, success, obs)`` as the original's did; a step
is one physics step of 1 ms (the original's, in every task; pr2-drake's tasks would otherwise
step 2 or 4 ms), and ``step({})`` is a valid first call. The observation and action dictionaries
are :mod:`pr2_drake.observation`'s. Differences: an invalid action ends the episode
``invalid_action`` (the message on stderr) instead of raising inside the simulator; a step
after the end returns the final ``(True, success, obs)`` again.

Run by ``pr2-drake pr2-launch`` (:mod:`pr2_drake.porting.launch`), the environment also takes
the command's seed and time limit, and writes the episode's report when the episode ends, when
the launcher shuts down or exits early (``agent_exit``), or dies of an exception
(``agent_error``, or ``interrupted`` on Ctrl-C).
"""

from __future__ import annotations

import atexit
import json
import os
import secrets
import sys
import time
from typing import Any

from pr2 import sim
from pr2_drake.porting.launch import PHYSICS_DT  # [s] the original's physics step
_HOOKS: list = []  # the exit hooks, installed once per process


class Env:
    """The original's environment (see the module docstring).

    Args:
        task_num: task 1..6.
        seed: episode seed; None: a random one (the original's random set-up), in the report.
    """

    physics_dt = PHYSICS_DT

    def __init__(self, task_num: int = 1, seed: int | None = None) -> None:
        from pr2_drake.env import Env as TestbedEnv
        from pr2_drake.porting.launch import launch_settings
        from pr2_drake.scenario import PlantSettings, Scenario

        settings = launch_settings()
        if settings.seed is not None:
            seed = settings.seed
        self._seed = secrets.randbelow(2**31) if seed is None else int(seed)
        self._task_num = task_num
        self._env = TestbedEnv(task_num, self._seed, time_limit=settings.seconds,
                               scenario=Scenario(plant=PlantSettings(time_step=PHYSICS_DT)))
        self._report_path = settings.report
        self._agent = settings.agent or f"pr2 solver (task {task_num})"
        self._reported = False
        self._obs: dict[str, Any] | None = None
        self._wall_start = time.perf_counter()
        sim.attach(self)
        _install_exit_hooks()

    # -- the original's API -----------------------------------------------------------------
    def reset(self) -> tuple[bool, bool, dict[str, Any]]:
        """Start the episode again; returns (done, success, obs)."""
        self._obs = self._env.reset(seed=self._seed)
        self._reported = False
        self._wall_start = time.perf_counter()
        status = self._env.status
        return status.done, status.success, self._obs

    def step(self, action: dict[str, Any]) -> tuple[bool, bool, dict[str, Any]]:
        """Apply ``action`` for one physics step; returns (done, success, obs)."""
        from pr2_drake.env import InvalidAction

        status = self._env.status
        if status.done:
            if self._obs is None:
                self._obs = self._env.observation()
            return True, status.success, self._obs
        try:
            done, success, obs = self._env.step(action)
        except InvalidAction as e:
            print(f"pr2: invalid action: {e}", file=sys.stderr, flush=True)
            self._env.episode.end("invalid_action", str(e))
            done, success, obs = True, False, self._env.observation()
        self._obs = obs
        if done:
            self.write_report()
        return done, success, obs

    def set_random_seed(self, seed: int | None) -> None:
        """The seed of the next :meth:`reset` (None: a random one)."""
        self._seed = secrets.randbelow(2**31) if seed is None else int(seed)

    @property
    def total_sim_time(self) -> float:
        """Simulated time since the episode started [s]."""
        return self._env.time

    @property
    def task_num(self) -> int:
        return self._task_num

    # -- pr2-drake's additions ------------------------------------------------------------
    @property
    def testbed_env(self):
        """The :class:`pr2_drake.env.Env` underneath."""
        return self._env

    def step_held(self) -> None:
        """One physics step with the last commands held (``pr2.sim.step``)."""
        self.step({})

    def report(self) -> dict[str, Any]:
        """The episode's result in the ``report.json`` layout."""
        wall = time.perf_counter() - self._wall_start
        return self._env.episode.report(agent=self._agent, wall_time=wall, sim_wall_time=wall)

    def write_report(self) -> None:
        """Write the report where ``pr2-drake pr2-launch`` asked (once per episode)."""
        if self._report_path is None or self._reported:
            return
        text = json.dumps(self.report(), indent=2)
        self._reported = True
        partial = f"{self._report_path}.partial"
        with open(partial, "w") as f:
            f.write(text)
        os.replace(partial, self._report_path)

    def finish(self, termination: str, message: str) -> None:
        """End a running episode with ``termination`` (points kept) and write the report."""
        if not self._env.status.done:
            self._env.episode.end(termination, message)
        self.write_report()


def _install_exit_hooks() -> None:
    """Write the report of an episode cut short by an exception or an early exit."""
    if _HOOKS:
        return
    previous = sys.excepthook

    def excepthook(kind, value, traceback) -> None:
        env = sim.current_env()
        if env is not None:
            if issubclass(kind, KeyboardInterrupt):
                env.finish("interrupted", "interrupted (Ctrl-C)")
            else:
                env.finish("agent_error", f"{kind.__name__}: {' '.join(str(value).split())}")
        previous(kind, value, traceback)

    sys.excepthook = excepthook
    atexit.register(sim.finish)
    _HOOKS.append(excepthook)

"""One episode with the simulator and referee here and the agent in its sandbox.

The parent builds the :class:`pr2_drake.episode.Episode` (no agent blocks) and drives it with
:func:`pr2_drake.drive.drive_policy`, as ``pr2-drake run`` drives an agent in process: the
agent is a :class:`RemoteAgent` whose calls are round trips to the sandbox, the episode a
:class:`Ticks` over :class:`pr2_drake.env.Env`. Each control tick sends copies of what the agent
may see (camera frames through shared memory) and applies the action that comes back,
validated like any other:

- a ``next_action`` agent gets the observation dictionary every ``control_dt`` (the
  scenario's, else the agent's ``control_dt`` attribute, else one physics step);
- a Drake System agent gets the values of the testbed outputs its input ports name, every
  physics step (its own diagram steps with them: see :mod:`pr2_drake.compete.child`), so it
  behaves as if wired into the testbed.

Whatever the agent does ends at most its own episode, with a named termination and the points
earned before it::

    from pr2_drake.compete.proxy import run_sandboxed_episode
    report = run_sandboxed_episode(Scenario(task=1, seed=0, seconds=5))
"""

from __future__ import annotations

import hashlib
import math
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np

from pr2_drake.compete.channel import finite_seconds
from pr2_drake.compete.child import ALLOWED_INPUTS
from pr2_drake.compete.limits import AgentFault, SandboxLimits
from pr2_drake.compete.sandbox import AgentProcess
from pr2_drake.drive import AgentEnded, drive_policy
from pr2_drake.episode import Episode
from pr2_drake.run import agent_params, agent_spec
from pr2_drake.scenario import MAX_CONTROL_DT, Scenario


class Interrupted(KeyboardInterrupt):
    """The user stopped a sandboxed episode (Ctrl-C); ``report`` ends ``interrupted``, with
    the points earned before."""

    def __init__(self, report: dict[str, Any]):
        super().__init__("interrupted")
        self.report = report


def run_sandboxed_episode(scenario: Scenario, *, submission: str | Path | None = None,
                          limits: SandboxLimits | None = None,
                          hide: tuple[Path, ...] = ()) -> dict[str, Any]:
    """Run ``scenario``'s agent (``scenario.agent`` or the task's built-in one) sandboxed.

    Args:
        scenario: the episode; ``agent`` is imported inside the sandbox.
        submission: a folder bound read-only into the sandbox and put on the agent's import
            path (its working folder too).
        limits: the sandbox's limits and isolation (default :class:`SandboxLimits`).
        hide: folders the agent must not see.

    Returns:
        The report of :meth:`Episode.report` plus ``steps``, ``step_time_mean`` and
        ``step_time_max`` (the agent's round trip per tick, wall clock [s]),
        ``agent_compute_mean`` and ``agent_compute_max`` (its own time per tick [s]),
        ``ipc_overhead_mean`` and ``ipc_overhead_median`` (round trip minus compute [s]; the
        median is robust to a busy machine's scheduling delays), ``sandbox`` ("bwrap",
        "unshare" or "none") and ``state_digest`` (a hash of the final plant state).

    Raises:
        ScenarioError: the scenario itself is bad (before anything runs).
        IsolationUnavailable (a ValueError): no isolation here and ``limits.trust`` is off.
        Interrupted: the user pressed Ctrl-C; it carries the report.
    """
    limits = limits or SandboxLimits()
    wall_start = time.perf_counter()
    scenario.validate()
    if scenario.diagram:
        raise ValueError("a sandboxed episode runs an agent, not a diagram YAML")
    spec, submission = _file_spec(agent_spec(scenario), submission)
    process = AgentProcess(None if submission is None else Path(submission), limits, hide)
    episode = Episode(scenario)
    agent = RemoteAgent(process, episode, limits)
    ticks = None
    stopped = False
    try:
        process.start()
        ticks = agent.start(spec, dict(task=scenario.task, seed=scenario.seed,
                                       priors=dict(episode.testbed.scene.priors),
                                       **agent_params(scenario)))
        drive_policy(ticks, agent, observe=agent.ports)
    except AgentEnded as f:  # the sandbox refused the submission, or the agent's set-up failed
        episode.end(f.termination, f.message)
    except KeyboardInterrupt:
        episode.end("interrupted", "stopped by the user (Ctrl-C)")
        stopped = True
    finally:
        process.close()
    sim_wall = ticks.sim_wall if ticks is not None else 0.0
    report = episode.report(spec, time.perf_counter() - wall_start, sim_wall or None)
    report.update(agent.stats(), sandbox=process.kind, state_digest=state_digest(episode))
    if stopped:
        raise Interrupted(report)
    return report


class RemoteAgent:
    """The agent in its sandbox, as :func:`pr2_drake.drive.drive_policy` calls an agent:
    :meth:`reset` and :meth:`next_action` are one round trip each, and every fault of the
    agent raises :class:`AgentFault` (an :class:`pr2_drake.drive.AgentEnded`) naming the end.

    A ``next_action`` agent is sent the observation's values (``op: act``; the child builds
    the dictionary). A System agent is ticked every physics step with the values of the
    testbed outputs its input ports name (``op: tick``), plus what its unrestricted updates
    see (``prev``, ``t_prev``: the values once the last action was applied; see
    :mod:`pr2_drake.compete.child`).
    """

    def __init__(self, process: AgentProcess, episode: Episode, limits: SandboxLimits):
        self.process, self.episode, self.limits = process, episode, limits
        self.rtts: list[float] = []
        self.computes: list[float] = []
        self.deadline = math.inf
        self.prev: dict[str, Any] | None = None
        self.t_prev: float | None = None

    def start(self, spec: str, kwargs: dict[str, Any]) -> "Ticks":
        """Build the agent in the sandbox (a System agent also gives its initialization's
        outputs); returns the episode's :class:`Ticks` at the agent's control period."""
        from pr2_drake.env import Env

        process, episode, limits = self.process, self.episode, self.limits
        X = episode.testbed.X_WB_start
        start = (X.translation().copy(), X.rotation().ToQuaternion().wxyz())
        info, _ = process.request({"op": "init", "spec": spec, "kwargs": kwargs,
                                   "start": start}, limits.startup_seconds)
        self.system = info.get("kind") == "system"
        self.discrete = info.get("discrete") is True
        self.env = Env.from_episode(episode, control_dt=self._control_dt(info))
        tb = episode.testbed
        asked = info.get("inputs") if isinstance(info.get("inputs"), list) else []
        self.inputs = {n: tb.GetOutputPort(n) for n in asked if isinstance(n, str)
                       and n in ALLOWED_INPUTS and tb.HasOutputPort(n)}
        if self.system and len(self.inputs) != len(asked):  # the harness decides what crosses
            raise AgentFault("agent_error", f"the agent reads ports that are not offered: "
                                            f"{str(asked)[:200]}; offered: {ALLOWED_INPUTS}")
        if self.system:  # the outputs of its default state: the inputs of its initialization
            reply, _ = process.request({"op": "peek", "ports": self.ports()},
                                       limits.startup_seconds)
            _apply(self.env, reply.get("action"))
        return Ticks(self.env, self.applied if self.system else None)

    def _control_dt(self, info: dict[str, Any]) -> float | None:
        """The control period [s]: the scenario's, else a next_action agent's attribute
        (at least one physics step, at most MAX_CONTROL_DT), else one physics step."""
        scenario = self.episode.scenario
        if scenario.control_dt or self.system or info.get("control_dt") is None:
            return scenario.control_dt
        step = self.episode.testbed.config.time_step
        dt = finite_seconds(info.get("control_dt"), MAX_CONTROL_DT)
        if dt is None or dt < step * (1 - 1e-9):
            raise AgentFault("agent_error", f"the agent's control_dt "
                                            f"{str(info.get('control_dt'))[:40]} is not between "
                                            f"one physics step ({step:g} s) and "
                                            f"{MAX_CONTROL_DT:g} s")
        return dt

    def ports(self) -> dict[str, Any]:
        """What the agent is sent at this time: a System agent's input values, else the
        observation's (:meth:`pr2_drake.env.Env.observation_values`)."""
        if not self.system:
            return self.env.observation_values()
        ctx = self.episode.tb_context
        return {name: port.Eval(ctx) for name, port in self.inputs.items()}

    def reset(self, ports: dict[str, Any]) -> None:
        """The episode starts: a ``next_action`` agent is told; the episode's wall-clock
        limit starts now (the set-up had its own budget)."""
        if not self.system:
            self.process.request({"op": "reset", "time": self.episode.time, "ports": ports},
                                 self.limits.startup_seconds)
        self.deadline = time.perf_counter() + self.limits.episode_seconds

    def next_action(self, ports: dict[str, Any]) -> Any:
        """One tick: the agent's action for ``ports`` (see :meth:`ports`)."""
        limits = self.limits
        if time.perf_counter() > self.deadline:
            raise AgentFault("agent_timeout", f"the episode's wall-clock limit of "
                                              f"{limits.episode_seconds:g} s")
        t = self.episode.time
        if self.system:
            msg = {"op": "tick", "time": t, "ports": ports, "prev": self.prev,
                   "t_prev": self.t_prev}
        else:
            msg = {"op": "act", "time": t, "ports": ports}
        reply, rtt = self.process.request(msg, limits.step_seconds, wall_cap=limits.step_wall_cap)
        self.rtts.append(rtt)
        c = finite_seconds(reply.get("compute"), rtt)
        self.computes.append(rtt if c is None else c)
        return reply.get("action")

    def applied(self) -> None:
        """(System agents) the action is applied: what its unrestricted updates at this tick
        see (the applied efforts follow the new action); its discrete updates see the next
        tick's values."""
        self.prev = None if self.discrete else self.ports()
        self.t_prev = self.episode.time

    def stats(self) -> dict[str, Any]:
        """Steps, round trips, the agent's compute and the boundary's overhead."""
        r = np.asarray(self.rtts) if self.rtts else np.zeros(1)
        c = np.asarray(self.computes) if self.computes else np.zeros(1)
        return dict(
            steps=len(self.rtts),
            step_time_mean=round(float(r.mean()), 7), step_time_max=round(float(r.max()), 7),
            agent_compute_mean=round(float(c.mean()), 7),
            agent_compute_max=round(float(c.max()), 7),
            ipc_overhead_mean=round(float((r - c).mean()), 7),
            ipc_overhead_median=round(float(np.median(r - c)), 7))


class Ticks:
    """The episode as :func:`pr2_drake.drive.drive_policy` steps it for a sandboxed agent:
    :meth:`step` applies the action and advances to the next tick at ``k * control_dt`` (not
    a sum of steps: ticks meet the plant's own step times). The episode is fresh: ``reset``
    gives no observation (the driver's ``observe`` does).

    Args:
        env: the episode's :class:`pr2_drake.env.Env` (its ``control_dt`` is the tick's).
        applied: called once each action is applied, before the advance.
    """

    def __init__(self, env, applied: Callable[[], None] | None = None):
        self.env, self.episode, self.applied = env, env.episode, applied
        self.tick0 = round(self.episode.time / env.control_dt)
        self.ticks = 0
        self.sim_wall = 0.0  # wall time of applying and simulating [s]

    @property
    def status(self):
        return self.episode.status

    def reset(self) -> None:
        return None

    def step(self, action: Any) -> tuple[bool, bool, None]:
        t0 = time.perf_counter()
        _apply(self.env, action)
        if self.applied is not None:
            self.applied()
        self.ticks += 1
        status = self.episode.advance_to((self.tick0 + self.ticks) * self.env.control_dt)
        self.sim_wall += time.perf_counter() - t0
        return status.done, status.success, None


def _apply(env, action: Any) -> None:
    """Apply the agent's ``action`` (as sent); whatever is wrong with it ends the episode
    ``invalid_action``."""
    from pr2_drake.env import InvalidAction

    try:
        env.apply(action)
    except InvalidAction as e:
        raise AgentFault("invalid_action", str(e)) from None
    except Exception as e:  # noqa: BLE001 (whatever the agent sent, the harness goes on)
        raise AgentFault("invalid_action", f"action: {type(e).__name__}: "
                                           f"{' '.join(str(e).split())[:300]}") from None


def _file_spec(spec: str, submission):
    """A ``path/to/file.py:Class`` spec outside a submission: its folder becomes the
    submission (bound read-only into the sandbox)."""
    module, _, cls = spec.partition(":")
    if submission is None and module.endswith(".py"):
        file = Path(module).resolve()
        if not file.is_file():
            raise ValueError(f"agent {spec!r}: file {module!r} not found")
        return f"{file.name}:{cls}", file.parent
    return spec, submission


def state_digest(episode: Episode) -> str:
    """A short hash of the plant's state (positions and velocities, exact bits)."""
    x = episode.testbed.GetOutputPort("plant_state").Eval(episode.tb_context)
    return hashlib.sha256(np.ascontiguousarray(x, dtype=np.float64).tobytes()).hexdigest()[:16]

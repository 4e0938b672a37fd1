"""One episode with the simulator and referee here and the agent in its sandbox.

The parent builds the :class:`pr2_drake.episode.Episode` (no agent blocks) and drives it
through :class:`pr2_drake.env.Env`. Each control tick it sends copies of what the agent may
see (camera frames through shared memory) and applies the action that comes back, validated
like any other:

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
import time
from pathlib import Path
from typing import Any

import numpy as np

from pr2_drake.compete.child import ALLOWED_INPUTS
from pr2_drake.compete.sandbox import AgentFault, AgentProcess, SandboxLimits
from pr2_drake.episode import Episode
from pr2_drake.run import agent_params, agent_spec
from pr2_drake.scenario import Scenario


def run_sandboxed_episode(scenario: Scenario, *, submission: str | Path | None = None,
                          limits: SandboxLimits | None = None,
                          hide: tuple[Path, ...] = ()) -> dict[str, Any]:
    """Run ``scenario``'s agent (``scenario.agent`` or the task's built-in one) sandboxed.

    Args:
        scenario: the episode; ``agent`` is imported inside the sandbox.
        submission: a folder copied into the sandbox and put on the agent's import path.
        limits: the sandbox's limits (default :class:`SandboxLimits`).
        hide: folders the agent must not see (bubblewrap only).

    Returns:
        The report of :meth:`Episode.report` plus ``steps``, ``step_time_mean`` and
        ``step_time_max`` (the agent's round trip per tick, wall clock [s]),
        ``agent_compute_mean`` and ``agent_compute_max`` (its own time per tick [s]),
        ``ipc_overhead_mean`` and ``ipc_overhead_median`` (round trip minus compute [s]; the
        median is robust to a busy machine's scheduling delays), ``sandbox`` ("bwrap" or
        "rlimits") and ``state_digest`` (a hash of the final plant state).

    Raises:
        ScenarioError: the scenario itself is bad (before anything runs).
    """
    from pr2_drake.env import Env

    limits = limits or SandboxLimits()
    wall_start = time.perf_counter()
    scenario.validate()
    if scenario.diagram:
        raise ValueError("a sandboxed episode runs an agent, not a diagram YAML")
    spec, submission = _file_spec(agent_spec(scenario), submission)
    episode = Episode(scenario)
    priors = dict(episode.testbed.scene.priors)
    kwargs = dict(task=scenario.task, seed=scenario.seed, priors=priors, **agent_params(scenario))
    agent = AgentProcess(None if submission is None else Path(submission), limits, hide)
    rtts: list[float] = []
    computes: list[float] = []
    sim_wall = 0.0
    try:
        agent.start()
        X = episode.testbed.X_WB_start
        start = (X.translation().copy(), X.rotation().ToQuaternion().wxyz())
        info, _ = agent.request({"op": "init", "spec": spec, "kwargs": kwargs, "start": start},
                                limits.startup_seconds)
        system = info.get("kind") == "system"
        dt = scenario.control_dt or (None if system else info.get("control_dt"))
        dt = float(dt) if isinstance(dt, (int, float)) and 0 < dt <= 1.0 else None
        env = Env.from_episode(episode, control_dt=dt)
        tb, ctx = episode.testbed, episode.tb_context
        asked = info.get("inputs") if isinstance(info.get("inputs"), list) else []
        inputs = {n: tb.GetOutputPort(n) for n in asked if isinstance(n, str)
                  and n in ALLOWED_INPUTS and tb.HasOutputPort(n)}
        if system and len(inputs) != len(asked):  # the parent decides what crosses
            raise AgentFault("agent_error", f"the agent reads ports that are not offered: "
                                            f"{str(asked)[:200]}; offered: {ALLOWED_INPUTS}")
        if system:  # the outputs of its default state: the inputs of its initialization
            reply, _ = agent.request({"op": "peek", "ports": _values(inputs, ctx)},
                                     limits.startup_seconds)
            _apply(env, reply)
        else:
            agent.request({"op": "reset", "time": episode.time,
                           "ports": env.observation_values()}, limits.startup_seconds)
        done = episode.status.done
        deadline = time.perf_counter() + limits.episode_seconds  # startup has its own budget
        tick0 = round(episode.time / env.control_dt)
        prev, t_prev = None, None
        while not done:
            if time.perf_counter() > deadline:
                raise AgentFault("agent_timeout", f"the episode's wall-clock limit of "
                                                  f"{limits.episode_seconds:g} s")
            t = episode.time
            if system:
                msg = {"op": "tick", "time": t, "ports": _values(inputs, ctx), "prev": prev,
                       "t_prev": t_prev}
            else:
                msg = {"op": "act", "time": t, "ports": env.observation_values()}
            reply, rtt = agent.request(msg, limits.step_seconds, wall_cap=limits.step_wall_cap)
            rtts.append(rtt)
            c = reply.get("compute")
            computes.append(float(c) if isinstance(c, (int, float)) and 0 <= c <= rtt else rtt)
            t0 = time.perf_counter()
            _apply(env, reply)
            if system:  # what its unrestricted updates at t see (the applied efforts follow
                # the new action); its discrete updates see the next tick's values instead
                prev = None if info.get("discrete") is True else _values(inputs, ctx)
                t_prev = t
            # Ticks at k * dt, not at a sum of steps: they meet the plant's own step times.
            done = episode.advance_to((tick0 + len(rtts)) * env.control_dt).done
            sim_wall += time.perf_counter() - t0
    except AgentFault as f:
        episode.end(f.termination, f.message)
    finally:
        isolated = agent.isolated
        agent.close()
    report = episode.report(spec, time.perf_counter() - wall_start, sim_wall or None)
    r = np.asarray(rtts) if rtts else np.zeros(1)
    c = np.asarray(computes) if computes else np.zeros(1)
    report.update(
        steps=len(rtts),
        step_time_mean=round(float(r.mean()), 7), step_time_max=round(float(r.max()), 7),
        agent_compute_mean=round(float(c.mean()), 7), agent_compute_max=round(float(c.max()), 7),
        ipc_overhead_mean=round(float((r - c).mean()), 7),
        ipc_overhead_median=round(float(np.median(r - c)), 7),
        sandbox="bwrap" if isolated else "rlimits",
        state_digest=state_digest(episode),
    )
    return report


def _values(ports: dict[str, Any], context) -> dict[str, Any]:
    return {name: port.Eval(context) for name, port in ports.items()}


def _apply(env, reply: dict[str, Any]) -> None:
    from pr2_drake.env import InvalidAction

    try:
        env.apply(reply.get("action"))
    except InvalidAction as e:
        raise AgentFault("invalid_action", str(e)) from None
    except (TypeError, KeyError, AttributeError, IndexError, RecursionError) as e:
        # Whatever the agent sent, the harness goes on.
        raise AgentFault("invalid_action", f"action: {type(e).__name__}: "
                                           f"{' '.join(str(e).split())[:300]}") from None


def _file_spec(spec: str, submission):
    """A ``path/to/file.py:Class`` spec outside a submission: its folder becomes the
    submission (the sandbox sees only its copy)."""
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

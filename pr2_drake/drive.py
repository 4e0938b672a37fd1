"""Driving an episode: the loops that advance it, and the one place an agent is called.

An episode's agent is either blocks wired into its diagram (a Drake System: the simulator calls
them) or an object the driver calls (``next_action(obs) -> action``, optional ``reset(obs)``).
Every driver goes through this module: :func:`pr2_drake.run.run_episode`, the benchmarks'
rigs (:mod:`pr2_drake.bench.rigs`), the tests, and the competition's parent process, whose agent
lives in a sandbox.

The API::

    status = drive_blocks(episode, on_step=show)     # the agent is in the diagram
    status = drive_policy(env, agent, on_step=show)  # the agent is called here
    result, ok = call_agent(episode, agent.method, *args)

- :func:`call_agent` calls one method of an agent. Whatever the agent does ends at most its
  episode, with a named termination (:meth:`pr2_drake.episode.Episode.end`) and the points
  earned so far: ``sys.exit`` -> ``agent_exit``; an exception -> ``agent_error`` (its type and
  message); :class:`AgentEnded` -> the termination it carries.
- :func:`drive_policy` runs a ``next_action`` agent over an :class:`pr2_drake.env.Env`: ``reset``
  (if the agent has it) with the first observation, then ``next_action`` and ``env.step`` until
  the episode ends; an action that fails validation ends it ``invalid_action``.
- A remote agent (the competition's, in its sandbox process:
  :class:`pr2_drake.compete.proxy.RemoteAgent`) is any object with the same methods. It
  reports its own faults by raising :class:`AgentEnded` (``agent_timeout``,
  ``agent_memory``, ``agent_exit``, ...). ``observe`` replaces what it is given (default
  ``env.observation``: the dictionary; e.g. ``env.observation_values``, the port values a
  sandboxed child turns into that dictionary itself), and ``env`` may be any object with
  ``reset()``, ``step(action) -> (done, success, obs)``, ``status`` and ``episode``.
"""

from __future__ import annotations

from typing import Any, Callable

from pr2_drake.env import Env, InvalidAction
from pr2_drake.episode import Episode
from pr2_drake.tasks.base import EpisodeStatus

CHECK_EVERY = 0.05  # simulated seconds between verdicts of a System agent's episode [s]

#: ``on_step(t, status)``: called after every advance (progress lines, plots, fall checks).
OnStep = Callable[[float, EpisodeStatus], Any]


class AgentEnded(Exception):
    """Raised by (or on behalf of) an agent to end its episode with a named termination.

    Attributes:
        termination: one of the episode ends of :mod:`pr2_drake.episode` (``agent_timeout``,
            ``agent_memory``, ``agent_exit``, ``agent_error``, ``invalid_action``).
        message: why, one line.
    """

    def __init__(self, termination: str, message: str):
        super().__init__(f"{termination}: {message}")
        self.termination = termination
        self.message = message


def call_agent(episode: Episode, method: Callable, *args) -> tuple[Any, bool]:
    """Call ``method(*args)`` of an agent. Returns (its result, True); or, when the agent
    raised or exited, ends the episode with the fault's name and returns (None, False)."""
    try:
        return method(*args), True
    except AgentEnded as e:
        episode.end(e.termination, e.message)
    except SystemExit as e:
        episode.end("agent_exit", f"the agent called sys.exit({e.code!r})")
    except Exception as e:
        episode.end("agent_error", f"{type(e).__name__}: {' '.join(str(e).split())}")
    return None, False


def drive_blocks(episode: Episode, on_step: OnStep | None = None,
                 every: float = CHECK_EVERY) -> EpisodeStatus:
    """Initialize ``episode`` and advance it ``every`` simulated seconds until it ends (its
    agent is blocks of its diagram); returns the last verdict."""
    status = episode.initialize()
    while not status.done:
        status = episode.advance_to(episode.time + every)
        if on_step is not None:
            on_step(episode.time, status)
    return status


def drive_policy(env: Env, agent, on_step: OnStep | None = None,
                 observe: Callable[[], Any] | None = None) -> EpisodeStatus:
    """Run a ``next_action`` agent (see the module docstring) over ``env`` until the episode
    ends; returns the last verdict."""
    episode = env.episode
    obs = env.reset()
    if observe is not None:
        obs = observe()
    if hasattr(agent, "reset") and not call_agent(episode, agent.reset, obs)[1]:
        return episode.status
    done = env.status.done
    while not done:
        action, ok = call_agent(episode, agent.next_action, obs)
        if not ok:
            break
        try:
            done, _, obs = env.step(action)
        except InvalidAction as e:
            episode.end("invalid_action", str(e))
            break
        except AgentEnded as e:
            episode.end(e.termination, e.message)
            break
        if observe is not None:
            obs = observe()
        if on_step is not None:
            on_step(episode.time, env.status)
    return episode.status

"""``pr2.sim``: the original platform's simulation context, for the loaded :class:`pr2.env.Env`.

The original's launcher loops on ``is_stopped()``, ``is_playing()`` and ``render()`` (Isaac
Sim's GUI could pause or stop the run). Here nothing pauses unless :func:`pause` is called,
and ``render`` draws nothing (there is no window; use ``pr2-drake run --meshcat`` to watch).
``step`` and ``reset`` act on the environment built last.
"""

from __future__ import annotations

from typing import Any


class _SimulationApp:
    """Which environment the module functions act on, and whether the run plays."""

    def __init__(self) -> None:
        self.env: Any = None
        self.playing = True
        self.stopped = False


_APP = _SimulationApp()


def attach(env: Any) -> None:
    """Make ``env`` (a :class:`pr2.env.Env`) the one the functions below act on; a new run
    plays."""
    _APP.env, _APP.playing, _APP.stopped = env, True, False


def current_env() -> Any:
    """The environment built last, or None."""
    return _APP.env


def loaded_env() -> Any:
    """The environment built last.

    Raises:
        RuntimeError: none was built.
    """
    if _APP.env is None:
        raise RuntimeError("pr2.sim: no environment loaded; build pr2.env.Env(task_num, seed) "
                           "first")
    return _APP.env


def is_stopped() -> bool:
    """Whether the run was stopped (:func:`stop`, :func:`pr2.shutdown`)."""
    return _APP.stopped


def is_playing() -> bool:
    """Whether the run plays (not paused and not stopped)."""
    return _APP.playing and not _APP.stopped


def play() -> None:
    _APP.playing = True


def pause() -> None:
    _APP.playing = False


def stop() -> None:
    _APP.stopped = True


def render() -> None:
    """Nothing to draw (no window)."""


def step(render: bool = True) -> None:
    """Advance the loaded environment by one physics step, its last action held."""
    loaded_env().step_held()


def reset(soft: bool = False) -> None:
    """Reset the loaded environment to the start of its episode."""
    loaded_env().reset()


def get_physics_dt() -> float:
    """The physics step [s]."""
    return loaded_env().physics_dt


def current_time() -> float:
    """Simulated time of the loaded environment [s]."""
    return loaded_env().total_sim_time


def finish() -> None:
    """Stop the run and write the loaded environment's report (if one was asked for)."""
    _APP.stopped = True
    if _APP.env is not None:
        _APP.env.finish("agent_exit", "the launcher shut down before the episode ended")

"""Agents: the solvers that drive the testbed, and how a CLI agent spec is resolved.

An agent is either
- a Drake System whose port names match the testbed's (inputs such as ``joint_state``,
  ``body_state``; outputs such as ``legs_command``, ``arms_command``, ``pick``, ``release``),
  wired by name, or
- any object with ``next_action(obs) -> action`` using the PR2 dictionaries
  (:mod:`pr2_drake.observation`), driven through :class:`pr2_drake.env.Env`.

Agents are named ``module:Class``. The class is built with the keyword arguments it accepts
among ``priors`` (the task's priors dict), ``task`` (task id or None) and ``seed``.
"""

from __future__ import annotations

import importlib
import inspect
from typing import Any

# Built-in default agent per task id (None = flat ground). Replaced by reference solvers as
# they land.
DEFAULT_AGENTS: dict[int | None, str] = {
    None: "pr2_drake.controllers.standing:StandingController",
    1: "pr2_drake.agents.walk_to_goal:RockyRoadAgent",
    2: "pr2_drake.agents.valve:ValveAgent",
    3: "pr2_drake.controllers.standing:StandingController",
    4: "pr2_drake.agents.walk_to_goal:SlopeAgent",
    5: "pr2_drake.controllers.standing:StandingController",
    6: "pr2_drake.controllers.standing:StandingController",
}


def load_agent_class(spec: str) -> type:
    """Import ``module:Class``; raises ValueError with a clear message on a bad spec."""
    if not isinstance(spec, str) or spec.count(":") != 1:
        raise ValueError(f"agent must be given as 'module:Class', got {spec!r}")
    module_name, class_name = spec.split(":")
    try:
        module = importlib.import_module(module_name)
    except ImportError as e:
        raise ValueError(f"agent {spec!r}: cannot import module {module_name!r}: {e}") from None
    try:
        cls = getattr(module, class_name)
    except AttributeError:
        raise ValueError(f"agent {spec!r}: module {module_name!r} has no {class_name!r}") from None
    return cls


def instantiate_agent(cls: type, **available: Any) -> Any:
    """Build an agent, passing only the keyword arguments its constructor accepts."""
    try:
        params = inspect.signature(cls).parameters
    except (TypeError, ValueError):
        params = {}
    accepts_any = any(p.kind == p.VAR_KEYWORD for p in params.values())
    kwargs = {k: v for k, v in available.items() if accepts_any or k in params}
    return cls(**kwargs)


def is_system_agent(agent: Any) -> bool:
    from pydrake.systems.framework import System

    return isinstance(agent, System)


def is_policy_agent(agent: Any) -> bool:
    return callable(getattr(agent, "next_action", None))

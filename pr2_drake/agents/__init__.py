"""Agents: the solvers that drive the testbed, and how a CLI agent spec is resolved.

An agent is either
- a Drake System whose port names match the testbed's (inputs such as ``joint_state``,
  ``body_state``; outputs such as ``legs_command``, ``arms_command``, ``pick``, ``release``),
  wired by name, or
- any object with ``next_action(obs) -> action`` using the PR2 dictionaries
  (:mod:`pr2_drake.observation`), driven through :class:`pr2_drake.env.Env`.

Agents are named ``module:Class`` or ``path/to/file.py:Class``. The class is built with the
keyword arguments it accepts among ``priors`` (the task's priors dict), ``task`` (task id or
None), ``seed`` and the scenario's ``agent_params``.
"""

from __future__ import annotations

import importlib
import importlib.util
import inspect
import sys
from pathlib import Path
from typing import Any

def load_agent_class(spec: str) -> type:
    """Import ``module:Class`` or ``path/to/file.py:Class``.

    A file's folder goes on the import path (so the file may import its neighbours).

    Raises:
        ValueError: one line naming the spec and what is wrong (bad form, import failure with
            the exception's type and message, e.g. a syntax error, missing attribute, not a
            class or factory).
    """
    if not isinstance(spec, str) or spec.count(":") != 1 or not all(spec.split(":")):
        raise ValueError(
            f"agent must be given as 'module:Class' or 'path/to/file.py:Class', got {spec!r}")
    module_name, class_name = spec.split(":")
    try:
        if module_name.endswith(".py"):
            module = _import_file(module_name)
        else:
            module = importlib.import_module(module_name)
    except FileNotFoundError:
        raise ValueError(f"agent {spec!r}: file {module_name!r} not found") from None
    except ImportError as e:
        raise ValueError(f"agent {spec!r}: cannot import module {module_name!r}: {e}") from None
    except Exception as e:  # a syntax error or an exception raised while importing the module
        raise ValueError(f"agent {spec!r}: importing {module_name!r} failed: "
                         f"{_one_line(e)}") from None
    try:
        cls = getattr(module, class_name)
    except AttributeError:
        raise ValueError(f"agent {spec!r}: module {module_name!r} has no {class_name!r}") from None
    if not callable(cls):
        raise ValueError(f"agent {spec!r}: {class_name!r} is a {type(cls).__name__}, not a class")
    return cls


def _import_file(path: str):
    file = Path(path).resolve()
    if not file.is_file():
        raise FileNotFoundError(path)
    name = f"pr2_agent_{file.stem}"
    if name in sys.modules and getattr(sys.modules[name], "__file__", None) == str(file):
        return sys.modules[name]
    folder = str(file.parent)
    if folder not in sys.path:
        sys.path.insert(0, folder)
    spec = importlib.util.spec_from_file_location(name, file)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[name]
        raise
    return module


def _one_line(e: BaseException) -> str:
    """``Type: message`` on one line (a SyntaxError keeps its file and line)."""
    if isinstance(e, SyntaxError):
        return f"SyntaxError: {e.msg} ({e.filename}, line {e.lineno})"
    return f"{type(e).__name__}: {' '.join(str(e).split())}"


def instantiate_agent(cls: type, **available: Any) -> Any:
    """Build an agent, passing only the keyword arguments its constructor accepts.

    Raises:
        ValueError: the constructor failed (its exception's type and message, one line).
    """
    try:
        params = inspect.signature(cls).parameters
    except (TypeError, ValueError):
        params = {}
    accepts_any = any(p.kind == p.VAR_KEYWORD for p in params.values())
    kwargs = {k: v for k, v in available.items() if accepts_any or k in params}
    try:
        return cls(**kwargs)
    except Exception as e:
        name = getattr(cls, "__qualname__", repr(cls))
        raise ValueError(f"agent {name}: constructor failed: {_one_line(e)}") from None


def is_system_agent(agent: Any) -> bool:
    from pydrake.systems.framework import System

    return isinstance(agent, System)


def is_policy_agent(agent: Any) -> bool:
    return callable(getattr(agent, "next_action", None))

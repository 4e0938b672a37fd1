"""The task registry: one row per task in tasks/registry.yaml (:class:`TaskEntry`).

A row names a task's id and name, its spec (a YAML: scene, start region, priors, rubric,
limits), the module with its scene and referee (a class ``Task``, a
:class:`pr2_drake.tasks.base.TaskDefinition`), its default agent and that agent's parameter
files. A new task is a YAML, a module and a row (README, "Adding a task"); a program may also
add a row at run time with :func:`register_task`.

>>> from pr2_drake.tasks import get_task, list_tasks, task_entry
>>> get_task(1).name, get_task("rocky_road").id, task_entry(2).agent

(No ``from __future__ import annotations``: ``yaml_load_typed`` reads the field types.)
"""

import importlib
from dataclasses import dataclass, field
from typing import Optional, Union

from pydrake.common.yaml import yaml_load_typed

from pr2_drake.paths import data_path, resolve_user_path
from pr2_drake.tasks.base import TaskDefinition, TaskSpec


@dataclass
class AgentEntry:
    """An agent ("module:Class" or "path/to/file.py:Class") and its parameter files: keyword
    arguments of its constructor, e.g. ``{params: params/agents/valve.yaml}``."""

    agent: str = ""
    agent_params: dict[str, str] = field(default_factory=dict)


@dataclass
class TaskEntry(AgentEntry):
    """One row of the registry.

    Attributes:
        id: the task's number; name: its name (lower case, no spaces).
        spec: the task's YAML (relative to the data root, or a path).
        module: the module (importable name) whose ``Task`` builds its scene and referee.
        agent, agent_params: the default agent and that agent's parameter files (they apply
            whenever that agent runs this task, under the scenario's ``agent_params``).
    """

    id: int = 0
    name: str = ""
    spec: str = ""
    module: str = ""


@dataclass
class Registry:
    """tasks/registry.yaml: the agent of flat ground (no task) and the tasks' rows."""

    flat_ground: AgentEntry = field(default_factory=AgentEntry)
    tasks: list[TaskEntry] = field(default_factory=list)


_ROWS: dict[int, TaskEntry] = {}
_FLAT: list[AgentEntry] = []
_LOADED: dict[int, TaskDefinition] = {}


def _rows() -> dict[int, TaskEntry]:
    if not _ROWS:
        reg = yaml_load_typed(schema=Registry, filename=str(data_path("tasks", "registry.yaml")))
        _FLAT.append(reg.flat_ground)
        for row in reg.tasks:
            _ROWS[row.id] = row
    return _ROWS


def register_task(entry: TaskEntry) -> None:
    """Add a row (or replace the row of the same id). Raises ValueError when another task
    has the name, or the row lacks a field."""
    rows = _rows()
    missing = [k for k in ("name", "spec", "module", "agent") if not getattr(entry, k)]
    if missing or isinstance(entry.id, bool) or not isinstance(entry.id, int) or entry.id < 1:
        raise ValueError(f"task row {entry}: needs a positive integer id and {missing or 'all'}")
    for row in rows.values():
        if row.name == entry.name and row.id != entry.id:
            raise ValueError(f"task name {entry.name!r} is task {row.id}'s already")
    rows[entry.id] = entry
    _LOADED.pop(entry.id, None)


def task_id(task: Union[int, str]) -> int:
    """Normalise a task given as id (int or digit string) or name (any case) to its id."""
    rows = _rows()
    if isinstance(task, str):
        task = task.strip().lower()
        if task.isdigit():
            task = int(task)
    if isinstance(task, int) and not isinstance(task, bool):
        if task in rows:
            return task
    elif isinstance(task, str):
        for i, row in rows.items():
            if row.name == task:
                return i
    known = ", ".join(f"{i} ({row.name})" for i, row in rows.items())
    raise ValueError(f"unknown task {task!r}; known tasks: {known}")


def task_entry(task: Union[int, str]) -> TaskEntry:
    """The registry row of a task (id or name)."""
    return _rows()[task_id(task)]


def get_task(task: Union[int, str]) -> TaskDefinition:
    """The task definition for an id or name: its module's ``Task`` on its spec."""
    i = task_id(task)
    if i not in _LOADED:
        row = _rows()[i]
        spec = TaskSpec.load(resolve_user_path(row.spec, f"task {row.name} spec"), i, row.name)
        _LOADED[i] = importlib.import_module(row.module).Task(spec)
    return _LOADED[i]


def list_tasks() -> list[tuple[int, str]]:
    """(id, name) of every task, by id."""
    return [(i, row.name) for i, row in sorted(_rows().items())]


def agent_entry(task: Optional[Union[int, str]], agent: Optional[str] = None) -> AgentEntry:
    """The agent that runs ``task`` (None: flat ground) and its parameter files: the task's
    default agent when ``agent`` is None; ``agent`` itself, with the row's files when it is
    the task's default agent, else with none."""
    rows = _rows()
    row = rows[task_id(task)] if task is not None else _FLAT[0]
    if agent is None or agent == row.agent:
        return AgentEntry(row.agent, dict(row.agent_params))
    return AgentEntry(agent)

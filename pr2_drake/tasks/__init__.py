"""The task registry: ids 1..6 and names, each a YAML spec in tasks/ plus a module here.

>>> from pr2_drake.tasks import get_task, list_tasks
>>> get_task(1).name, get_task("rocky_road").id
"""

from __future__ import annotations

import importlib
from functools import lru_cache

from pr2_drake.paths import data_path
from pr2_drake.tasks.base import TaskDefinition, TaskSpec

# id -> (name, module). Each module defines `Task`, a TaskDefinition subclass.
REGISTRY: dict[int, tuple[str, str]] = {
    1: ("rocky_road", "pr2_drake.tasks.t1_rocky_road"),
    2: ("valve", "pr2_drake.tasks.t2_valve"),
    3: ("moving_bar", "pr2_drake.tasks.t3_moving_bar"),
    4: ("slope", "pr2_drake.tasks.t4_slope"),
    5: ("steps_button", "pr2_drake.tasks.t5_steps_button"),
    6: ("object_search", "pr2_drake.tasks.t6_object_search"),
}


def task_id(task: int | str) -> int:
    """Normalise a task given as id (1..6, int or digit string) or name (any case) to its id."""
    if isinstance(task, str):
        task = task.strip().lower()
        if task.isdigit():
            task = int(task)
    if isinstance(task, int) and not isinstance(task, bool):
        if task in REGISTRY:
            return task
    elif isinstance(task, str):
        for i, (name, _) in REGISTRY.items():
            if name == task:
                return i
    known = ", ".join(f"{i} ({n})" for i, (n, _) in REGISTRY.items())
    raise ValueError(f"unknown task {task!r}; known tasks: {known}")


@lru_cache(maxsize=None)
def get_task(task: int | str) -> TaskDefinition:
    """The task definition for an id or name (spec read from tasks/<id>_<name>.yaml)."""
    i = task_id(task)
    name, module = REGISTRY[i]
    spec = TaskSpec.load(data_path("tasks", f"{i}_{name}.yaml"))
    return importlib.import_module(module).Task(spec)


# Built-in default agent per task id (None = flat ground).
DEFAULT_AGENTS: dict[int | None, str] = {
    None: "pr2_drake.controllers.standing:StandingController",
    1: "pr2_drake.agents.walk_to_goal:RockyRoadAgent",
    2: "pr2_drake.agents.valve:ValveAgent",
    3: "pr2_drake.agents.moving_bar:MovingBarAgent",
    4: "pr2_drake.agents.walk_to_goal:SlopeAgent",
    5: "pr2_drake.agents.steps_button:StepsButtonAgent",
    6: "pr2_drake.agents.search.agent:ObjectSearchAgent",
}


def default_agent(task: int | str | None) -> str:
    """The built-in agent of a task (id or name; None = flat ground), as ``module:Class``."""
    return DEFAULT_AGENTS[None if task is None else task_id(task)]


def list_tasks() -> list[tuple[int, str]]:
    return [(i, name) for i, (name, _) in REGISTRY.items()]

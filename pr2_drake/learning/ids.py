"""The gymnasium ids of the tasks, registered when gymnasium is imported.

Every row of tasks/registry.yaml gives two ids, ``pr2_drake/<Name>-v0`` (joint level,
:class:`pr2_drake.learning.envs.JointEnv`) and ``pr2_drake/<Name>Command-v0`` (command level,
:class:`pr2_drake.learning.envs.CommandEnv`); ``<Name>`` is the task's name in CamelCase
(rocky_road -> RockyRoad). ``max_episode_steps`` is the task's time limit at the level's
default rate (:data:`DEFAULT_RATES`); an env made with another ``control_dt`` should be given
its own ``max_episode_steps`` (the env itself ends the episode "timeout" at the task's limit).

``import pr2_drake`` calls :func:`register_when_gymnasium_loads`: it registers at once if
gymnasium is already imported, else when it is, so importing pr2_drake neither imports
gymnasium (~0.3 s) nor needs it. This module imports neither pydrake nor gymnasium; the time
limits are read with PyYAML (a dependency of Drake).
"""

from __future__ import annotations

import math
import sys

NAMESPACE = "pr2_drake"
VERSION = 0
#: Simulated seconds per env step by default: joint level 100 Hz, command level 10 Hz [s].
DEFAULT_RATES = {"joint": 0.01, "command": 0.1}
ENTRY_POINTS = {"joint": "pr2_drake.learning.envs:JointEnv",
                "command": "pr2_drake.learning.envs:CommandEnv"}


def camel(name: str) -> str:
    """A registry name in CamelCase: ``rocky_road`` -> ``RockyRoad``."""
    return "".join(part.capitalize() for part in name.split("_"))


def env_id(task_name: str, level: str) -> str:
    """The gymnasium id of a task (its registry name) at ``level`` ("joint" or "command")."""
    suffix = "Command" if level == "command" else ""
    return f"{NAMESPACE}/{camel(task_name)}{suffix}-v{VERSION}"


def task_rows() -> list[tuple[int, str, float]]:
    """(id, name, time limit [s]) of every task of tasks/registry.yaml, by id."""
    import yaml

    from pr2_drake.paths import data_path, resolve_user_path

    loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
    with open(data_path("tasks", "registry.yaml")) as f:
        rows = yaml.load(f, Loader=loader)["tasks"]
    out = []
    for row in rows:
        with open(resolve_user_path(row["spec"], f"task {row['name']} spec")) as f:
            spec = yaml.load(f, Loader=loader)
        out.append((int(row["id"]), str(row["name"]), float(spec["time_limit"])))
    return sorted(out)


def all_ids() -> list[str]:
    """Every id, joint level then command level per task."""
    return [env_id(name, level) for _, name, _ in task_rows() for level in ("joint", "command")]


def register() -> list[str]:
    """Register every task's two ids with gymnasium (again: no-op); returns them."""
    from gymnasium.envs.registration import register as gym_register, registry

    ids = []
    for task, name, limit in task_rows():
        for level, dt in DEFAULT_RATES.items():
            eid = env_id(name, level)
            ids.append(eid)
            if eid in registry:
                continue
            gym_register(id=eid, entry_point=ENTRY_POINTS[level], kwargs={"task": task},
                         max_episode_steps=int(math.ceil(limit / dt - 1e-9)))
    return ids


class _RegisterOnImport:
    """A meta path finder and loader (duck-typed: importlib.abc costs 60 ms to import): finds
    gymnasium with the other finders and registers the ids once it has loaded."""

    def find_spec(self, fullname, path, target=None):
        if fullname != "gymnasium":
            return None
        import importlib.util

        sys.meta_path.remove(self)
        spec = importlib.util.find_spec(fullname)
        if spec is None or spec.loader is None:
            return spec
        self._loader = spec.loader
        spec.loader = self
        return spec

    def create_module(self, spec):
        return self._loader.create_module(spec)

    def exec_module(self, module) -> None:
        module.__spec__.loader = self._loader
        self._loader.exec_module(module)
        register()


def register_when_gymnasium_loads() -> None:
    """Register the ids now if gymnasium is imported, else as soon as it is (no-op when
    gymnasium is not installed: nothing ever imports it)."""
    if "gymnasium" in sys.modules:
        register()
    elif not any(isinstance(f, _RegisterOnImport) for f in sys.meta_path):
        sys.meta_path.insert(0, _RegisterOnImport())

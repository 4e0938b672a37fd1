"""Parameters from YAML: one typed loader for every parameter dataclass.

A parameter class is a dataclass that derives from :class:`Params` and names its default file
(under the data root's ``params/``: ``params/controllers/`` for the built-in controllers'
gains, ``params/agents/`` for the reference agents)::

    @dataclass
    class GoalPlannerParams(Params):
        FILE: ClassVar[str] = "params/agents/goal_planner.yaml"
        forward_speed: float = 0.25

    p = GoalPlannerParams.load()                              # its default file
    p = GoalPlannerParams.load("my_planner.yaml")             # another file, whole
    p = WalkingParams.load(overrides=["params/controllers/walking_rough.yaml"])
    q = p.with_overrides("tuning.yaml")                       # a copy, these entries replaced

Files are read with ``pydrake.common.yaml.yaml_load_typed`` into the dataclass (a key the class
does not have is an error, a key the file lacks keeps its default); an override file is a
partial YAML applied on top. After loading, :meth:`Params.check` raises ``ValueError`` on
inconsistent values. (A subclass module has no ``from __future__ import annotations``:
``yaml_load_typed`` reads the field types.)
"""

from __future__ import annotations

import copy
from typing import ClassVar, Sequence, TypeVar

from pydrake.common.yaml import yaml_load_typed

from pr2_drake.paths import resolve_user_path

P = TypeVar("P", bound="Params")


class Params:
    """Base of the parameter dataclasses (see the module docstring)."""

    #: The default parameter file, relative to the data root (or a path).
    FILE: ClassVar[str] = ""

    @classmethod
    def load(cls: type[P], path: str | None = None, overrides: Sequence[str] = ()) -> P:
        """Read ``path`` (default :attr:`FILE`) into this class, then each override file."""
        file = resolve_user_path(path or cls.FILE, f"{cls.__name__} parameters")
        params = yaml_load_typed(schema=cls, filename=str(file))
        params.check()
        return params.with_overrides(*overrides) if overrides else params

    def with_overrides(self: P, *paths: str) -> P:
        """A copy with the entries of each (partial) YAML file in turn replacing these."""
        params = self
        for path in paths:
            file = resolve_user_path(path, f"{type(self).__name__} parameter overrides")
            params = yaml_load_typed(schema=type(self), filename=str(file),
                                     defaults=copy.deepcopy(params))
            params.check()
        return params

    def check(self) -> None:
        """Raise ValueError on inconsistent values (a subclass says which)."""

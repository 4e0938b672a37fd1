"""What every task shares: its YAML spec, the episode status, and the referee base system.

A task is data plus code: ``tasks/<n>_<name>.yaml`` (read into :class:`TaskSpec`) and a module
with a scene builder and a :class:`Referee` subclass, named by a row of the registry
(tasks/registry.yaml, :mod:`pr2_drake.tasks`).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.common.yaml import yaml_load_file
from pydrake.math import RigidTransform
from pydrake.multibody.plant import ContactResults, MultibodyPlant
from pydrake.multibody.tree import ModelInstanceIndex
from pydrake.systems.framework import BasicVector, LeafSystem

from pr2_drake.grasp import PickState
from pr2_drake.lifetime import weak_calc
from pr2_drake.robot.model import BASE_BODY
from pr2_drake.scene import Scene, StartPose

# How an episode can end: the referee's verdicts, then the faults named by pr2_drake.episode.
TERMINATIONS = ("completed", "fell", "left_region", "timeout", "diverged", "invalid_action",
                "agent_error", "agent_timeout", "agent_memory", "agent_exit")
FALL_HEIGHT = 0.35  # default: fallen when the base is less than this above the ground [m]
# The stream of scene variation: its draws never touch the episode's own rng (start pose,
# objects), so a varied scene keeps the start pose the same seed gives the task's own scene.
VARIATION_STREAM = 0x5CE4E


@dataclass
class ScoreEvent:
    """One rubric item earned: its id, the points, and the simulated time [s]."""

    item: str
    points: float
    time: float


@dataclass
class EpisodeStatus:
    """The referee's running verdict.

    ``termination`` is "" while the episode runs, then one of :data:`TERMINATIONS`.
    """

    score: float = 0.0
    max_score: float = 0.0
    done: bool = False
    success: bool = False
    termination: str = ""
    items: list[ScoreEvent] = field(default_factory=list)
    time: float = 0.0
    # The referee's per-episode memory (timers, phases, counters): plain data, copied on update.
    memo: dict[str, Any] = field(default_factory=dict)

    def earned(self, item: str) -> bool:
        return any(e.item == item for e in self.items)

    def __deepcopy__(self, memo) -> "EpisodeStatus":
        # Drake copies the referee's abstract state at each of its updates: the generic
        # deepcopy of a dataclass costs several times this. Items are immutable once earned.
        return _copy_status(self)


@dataclass
class RubricItem:
    item: str
    points: float
    description: str = ""


@dataclass
class TaskSpec:
    """A task's YAML, parsed. Distances in m, angles in deg where the key says so, time in s.

    Attributes:
        start_region: {"center": [x, y], "size": [dx, dy]} rectangle the start is drawn from.
        nominal_heading_deg, heading_noise_deg: start heading = nominal + U(-noise, noise).
        arena: {"min": [x, y], "max": [x, y]}: leaving it ends the episode ("left_region").
        fall_height: the robot has fallen when its base is less than this above the ground.
        scene: task-specific scene parameters; priors: what the agent is told in advance.
        time_step: physics step [s] of this task's episodes unless a scenario sets one;
            None = :data:`pr2_drake.testbed.DEFAULT_TIME_STEP`.
    """

    id: int
    name: str
    title: str
    time_limit: float
    rubric: list[RubricItem]
    start_region: dict[str, list[float]]
    nominal_heading_deg: float = 0.0
    heading_noise_deg: float = 30.0
    arena: dict[str, list[float]] = field(default_factory=dict)
    fall_height: float = FALL_HEIGHT
    max_score: float | None = None
    camera: dict[str, Any] = field(default_factory=dict)
    feedback: list[str] = field(default_factory=list)
    priors: dict[str, Any] = field(default_factory=dict)
    scene: dict[str, Any] = field(default_factory=dict)
    time_step: float | None = None

    @staticmethod
    def load(path, task_id: int | None = None, name: str | None = None) -> "TaskSpec":
        """Read a task's YAML; ``task_id`` and ``name`` come from its registry row (a file
        may also give them, the same)."""
        try:
            raw = yaml_load_file(str(path))
        except Exception as e:  # YAML syntax: one line naming the file
            raise ValueError(f"task file {path}: {' '.join(str(e).split())}") from None
        if not isinstance(raw, dict) or not isinstance(raw.get("rubric"), list):
            raise ValueError(f"task file {path}: expected a mapping with a 'rubric' list")
        for key, value in (("id", task_id), ("name", name)):
            if value is not None and raw.setdefault(key, value) != value:
                raise ValueError(f"task file {path}: {key} {raw[key]!r} is not the registry's "
                                 f"{value!r}")
        try:
            rubric = [RubricItem(**r) for r in raw.pop("rubric")]
            spec = TaskSpec(rubric=rubric, **raw)
        except TypeError as e:
            raise ValueError(f"task file {path}: {e}") from None
        if spec.time_step is not None and not (
                isinstance(spec.time_step, (int, float)) and 0 < spec.time_step <= 0.02):
            raise ValueError(f"task file {path}: time_step must be in (0, 0.02] s, got "
                             f"{spec.time_step!r}")
        if spec.max_score is None:
            spec.max_score = float(sum(r.points for r in rubric if r.points > 0))
        return spec

    def points(self, item: str) -> float:
        for r in self.rubric:
            if r.item == item:
                return r.points
        raise KeyError(f"task {self.id}: no rubric item {item!r}")

    def sample_start(self, rng: np.random.Generator) -> StartPose:
        """Draw the start pose from the start region and heading noise."""
        cx, cy = self.start_region["center"]
        dx, dy = self.start_region["size"]
        x = cx + rng.uniform(-dx / 2, dx / 2)
        y = cy + rng.uniform(-dy / 2, dy / 2)
        noise = rng.uniform(-self.heading_noise_deg, self.heading_noise_deg)
        return StartPose(x, y, float(np.radians(self.nominal_heading_deg + noise)))


class Referee(LeafSystem):
    """Base referee: time limit, falls, leaving the arena; subclasses add the rubric.

    Input ports: ``plant_state`` (full [q; v]), ``contact_results``, ``pick_state``.
    Output ports: ``score`` (vector of 1), ``episode`` (:class:`EpisodeStatus`),
    ``task_feedback`` (dict), ``instruction`` (str).

    The verdict is updated every ``period`` seconds of simulated time. Subclasses implement
    :meth:`judge`, calling :meth:`award` for the items earned, and may override
    :meth:`feedback` and :meth:`instruction`.
    """

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    def __init__(self, spec: TaskSpec, plant: MultibodyPlant, robot: ModelInstanceIndex,
                 scene: Scene, period: float = 0.01):
        super().__init__()
        self.spec = spec
        self.plant = plant
        self.robot = robot
        self.scene = scene
        self.ctx = plant.CreateDefaultContext()
        self._base_index = plant.GetBodyByName(BASE_BODY, robot).index()
        self._state_in = self.DeclareVectorInputPort(
            "plant_state", plant.num_positions() + plant.num_velocities()
        )
        self._contacts_in = self.DeclareAbstractInputPort(
            "contact_results", AbstractValue.Make(ContactResults())
        )
        self._pick_in = self.DeclareAbstractInputPort("pick_state", AbstractValue.Make(PickState()))
        self._status = self.DeclareAbstractState(
            AbstractValue.Make(EpisodeStatus(max_score=spec.max_score))
        )
        self.DeclarePeriodicUnrestrictedUpdateEvent(period, 0.0, self._update)
        self.DeclareVectorOutputPort("score", 1, weak_calc(self._calc_score))
        self.DeclareStateOutputPort("episode", self._status)
        self.DeclareAbstractOutputPort(
            "task_feedback", lambda: AbstractValue.Make(dict()), weak_calc(self._calc_feedback)
        )
        self.DeclareAbstractOutputPort(
            "instruction", lambda: AbstractValue.Make(""), weak_calc(self._calc_instruction)
        )

    # Multibody elements (bodies, joints, frames) are kept as indices: a stored element holds its
    # plant through a reference the garbage collector cannot see (pr2_drake.lifetime).
    @property
    def base(self):
        """The robot's base body."""
        return self.plant.get_body(self._base_index)

    # -- for subclasses -----------------------------------------------------------------------
    def judge(self, context, status: EpisodeStatus) -> None:
        """Award the rubric items earned by now (self.ctx holds the plant state)."""

    def feedback(self, context) -> dict[str, Any]:
        """Task-specific feedback for the agent (e.g. the bar's position)."""
        return {}

    def instruction(self) -> str:
        return ""

    def award(self, status: EpisodeStatus, item: str, time: float) -> None:
        """Record ``item`` once, with the rubric's points."""
        if status.earned(item):
            return
        points = self.spec.points(item)
        status.items.append(ScoreEvent(item, points, time))
        status.score = float(np.clip(sum(e.points for e in status.items), 0.0, self.spec.max_score))

    def contact_results(self, context) -> ContactResults:
        return self._contacts_in.Eval(context)

    def pick_state(self, context) -> PickState:
        return self._pick_in.Eval(context)

    def X_WB(self) -> RigidTransform:
        return self.plant.EvalBodyPoseInWorld(self.ctx, self.base)

    def completed(self, status: EpisodeStatus) -> bool:
        """Whether the task is complete (default: every positive item earned)."""
        return all(status.earned(r.item) for r in self.spec.rubric if r.points > 0)

    # -- machinery ----------------------------------------------------------------------------
    def _update(self, context, state) -> None:
        status: EpisodeStatus = context.get_abstract_state(int(self._status)).get_value()
        if status.done:
            return
        status = _copy_status(status)
        t = context.get_time()
        status.time = t
        x = self._state_in.Eval(context)
        if not np.all(np.isfinite(x)):
            self._end(status, "diverged")
        else:
            self.plant.SetPositionsAndVelocities(self.ctx, x)
            self.judge(context, status)
            p = self.X_WB().translation()
            if self.completed(status):
                self._end(status, "completed", success=True)
            elif p[2] - self.scene.ground_height(p[0], p[1]) < self.spec.fall_height:
                self._end(status, "fell")
            elif self.spec.arena and not _inside(p, self.spec.arena):
                self._end(status, "left_region")
            elif t >= self.spec.time_limit:
                self._end(status, "timeout")
        state.get_mutable_abstract_state(int(self._status)).set_value(status)

    @staticmethod
    def _end(status: EpisodeStatus, reason: str, success: bool = False) -> None:
        status.done = True
        status.termination = reason
        status.success = success

    def _calc_score(self, context, output: BasicVector) -> None:
        output.SetAtIndex(0, context.get_abstract_state(int(self._status)).get_value().score)

    def _calc_feedback(self, context, output) -> None:
        output.set_value(self.feedback(context))

    def _calc_instruction(self, context, output) -> None:
        output.set_value(self.instruction())


def _copy_status(s: EpisodeStatus) -> EpisodeStatus:
    return EpisodeStatus(s.score, s.max_score, s.done, s.success, s.termination, list(s.items),
                         s.time, copy.deepcopy(s.memo))


def _inside(p: np.ndarray, box: dict[str, list[float]]) -> bool:
    lo, hi = box["min"], box["max"]
    return lo[0] <= p[0] <= hi[0] and lo[1] <= p[1] <= hi[1]


class TaskDefinition:
    """A registered task: its spec plus the code that builds its scene and referee.

    Subclasses implement :meth:`build_scene` and :meth:`make_referee`, and may implement
    :meth:`vary_scene` (scene variation).

    Attributes:
        variation: None for the task's own scene; for a varied one (:meth:`varied`), what was
            drawn (plain data, in the report as ``variation``).
    """

    #: True when ``build_scene`` draws nothing from the seed's generator but the start pose
    #: (``spec.sample_start(rng)``, its first draw): a scene built for one seed is then the
    #: scene of every seed, and a built episode can be reused with :meth:`start_of` (the
    #: learning envs' fast reset; tests/test_learning.py checks it gives the fresh build's
    #: episode bit for bit). A task whose seed places anything else leaves it False.
    SEED_DRAWS_START_ONLY = False

    def __init__(self, spec: TaskSpec, variation: dict[str, Any] | None = None):
        self.spec = spec
        self.variation = variation

    def varied(self, seed: int) -> "TaskDefinition":
        """This task on a scene drawn from ``seed`` within the ranges of its YAML's
        ``scene.variation`` block: a new definition whose spec holds the drawn scene, so its
        scene, priors and referee all follow it. A task without variation returns itself."""
        rng = np.random.default_rng([VARIATION_STREAM, int(seed)])
        scene = copy.deepcopy(self.spec.scene)
        drawn = self.vary_scene(scene, rng)
        if drawn is None:
            return self
        return type(self)(replace(self.spec, scene=scene), variation=drawn)

    def vary_scene(self, scene: dict[str, Any], rng: np.random.Generator) -> dict | None:
        """Rewrite ``scene`` (a copy of the spec's ``scene`` block) with values drawn from
        ``rng``; return what was drawn (plain data), or None: this task has no variation."""
        return None

    def start_of(self, seed: int) -> StartPose | None:
        """The start pose of ``seed`` when that is all the seed changes in the scene (see
        :attr:`SEED_DRAWS_START_ONLY`), else None. A varied scene (:meth:`varied`) is the
        scene of one seed only: None."""
        if not self.SEED_DRAWS_START_ONLY or self.variation is not None:
            return None
        return self.spec.sample_start(np.random.default_rng(seed))

    @property
    def id(self) -> int:
        return self.spec.id

    @property
    def name(self) -> str:
        return self.spec.name

    def build_scene(self, plant: MultibodyPlant, rng: np.random.Generator) -> Scene:
        raise NotImplementedError

    def make_referee(self, plant: MultibodyPlant, robot: ModelInstanceIndex,
                     scene: Scene) -> Referee:
        raise NotImplementedError

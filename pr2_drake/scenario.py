"""The scenario: everything one episode needs, as one typed dataclass read from YAML.

In the style of Drake's ``hardware_sim.py``: a :class:`Scenario` is loaded with
``pydrake.common.yaml.yaml_load_typed`` from a file, then overridden field by field (the
command line's ``--task``, ``--seed``, ... and ``--set key=value``), and
:func:`pr2_drake.run.run_episode` builds and runs it. It is validated once, where running
starts: :class:`pr2_drake.episode.Episode` calls :meth:`Scenario.validate`.

Example (see ``scenarios/valve_seed7.yaml``)::

    task: valve            # id 1..6 or name, any case; omit for flat ground
    seed: 7
    agent: my_pkg.solver:Solver    # or path/to/solver.py:Solver; omit for the built-in agent
    agent_params: {params: params/agents/goal_planner.yaml}
    seconds: 30            # stop earlier than the task's limit
    plant: {time_step: 0.004, contact_approximation: similar}
    sleep: {enabled: true, rest_time: 0.5}   # resting free objects sleep (task 6)
    scene: {variation: false}   # true: the scene itself drawn from the seed (tasks 1, 2, 4-6)
    randomize: {enabled: false}   # domain randomisation from the seed (pr2_drake.randomize)
    camera: {enabled: true, width: 320, height: 240, fps: 10}
    limits: {max_speed: 100.0}

>>> from pr2_drake.scenario import load_scenario
>>> scenario = load_scenario("scenarios/valve_seed7.yaml", overrides=["seed=3", "seconds=5"])
"""

import math
import typing
from dataclasses import dataclass, field
from pathlib import Path

from pydrake.common.yaml import yaml_dump_typed, yaml_load_typed

from pr2_drake.camera import CameraSettings
from pr2_drake.paths import resolve_user_path
from pr2_drake.randomize import RandomizeSettings
from pr2_drake.scene import StartPose
from pr2_drake.sleep import SleepSettings
from pr2_drake.tasks.base import FALL_HEIGHT
from pr2_drake.testbed import DEFAULT_CONTACT_APPROXIMATION, TestbedConfig

FREE_RUN_SECONDS = 10.0  # length of an episode without a task, unless ``seconds`` says [s]
MAX_SPEED = 100.0  # any generalized velocity beyond this [m/s or rad/s] = diverged
MAX_COORDINATE = 1000.0  # any position coordinate beyond this [m or rad] = diverged
MAX_CONTROL_DT = 1.0  # longest control period of a next_action agent [s]


class ScenarioError(ValueError):
    """A scenario that cannot be built: a bad field, file, agent spec or constructor."""


@dataclass
class PlantSettings:
    """The physics engine (Drake's discrete MultibodyPlant, SAP).

    Attributes:
        time_step: physics step [s]; None (the default) = the task's (4 ms unless its YAML
            says otherwise; :data:`pr2_drake.testbed.DEFAULT_TIME_STEP`).
        contact_approximation: "similar" (the default), "lagged", "sap" or "tamsi" (Drake's
            deprecated solver; refused where a scene drives a joint by PD, as task 3's bar).
        contact_model: "point" or "hydroelastic_with_fallback" / "hydroelastic".
    """

    time_step: typing.Optional[float] = None
    contact_approximation: str = DEFAULT_CONTACT_APPROXIMATION
    contact_model: str = "point"


@dataclass
class EpisodeLimits:
    """When an episode ends besides the referee's verdict.

    Attributes:
        fall_height: without a task, fallen when the base is this low [m] (a task's YAML
            sets its own).
        max_speed: a generalized velocity beyond this [m/s, rad/s] ends the episode
            "diverged": no robot or object of the scenes moves that fast.
        max_coordinate: a position coordinate beyond this [m, rad] ends it "diverged".
    """

    fall_height: float = FALL_HEIGHT
    max_speed: float = MAX_SPEED
    max_coordinate: float = MAX_COORDINATE


@dataclass
class SceneSettings:
    """How the task's scene is made.

    Attributes:
        variation: False (the default): the task's own scene, as its YAML gives it. True: the
            scene drawn from the episode seed within the ranges of the YAML's
            ``scene.variation`` block (task 1 a rock field, task 2 the valve's height and
            size, task 4 the slope, task 5 the risers and treads, task 6 a generated house;
            task 3 has none); the priors describe the scene drawn.
    """

    variation: bool = False


@dataclass
class Scenario:
    """One episode, fully described.

    Attributes:
        task: task id (1..6) or name (any case); None = flat ground, no referee.
        seed: episode seed; every random choice flows from it.
        agent: "module:Class" or "path/to/file.py:Class"; None = the task's built-in agent.
        agent_params: extra keyword arguments for the agent's constructor (typically
            parameter files, e.g. ``{params: params/agents/goal_planner.yaml}``); given only
            where the constructor accepts them.
        diagram: a diagram YAML (see :mod:`pr2_drake.diagrams`) whose blocks replace the agent.
        seconds: stop after this much simulated time [s]; None = the task's time limit
            (10 s without a task).
        control_dt: period of a ``next_action`` agent [s]; None = the agent's own
            ``control_dt`` attribute, else one physics step.
        realtime_rate: pace of a run drawn live in Meshcat (0 = as fast as possible).
        plant: physics settings.
        camera: head camera; None = the task's own choice (on for task 6).
        start: start pose override; None = the task's seeded start.
        limits: fall height without a task and the divergence bounds.
        sleep: when resting free objects sleep (no contacts computed until something comes
            near; :mod:`pr2_drake.sleep`); ``sleep: {enabled: false}`` turns it off.
        scene: scene variation (``--set scene.variation=true``).
        randomize: domain randomisation (:mod:`pr2_drake.randomize`), off by default: physics,
            latency, observation noise and pushes drawn from the seed.
    """

    task: typing.Union[int, str, None] = None
    seed: int = 0
    agent: typing.Optional[str] = None
    agent_params: typing.Dict[str, str] = field(default_factory=dict)
    diagram: typing.Optional[str] = None
    seconds: typing.Optional[float] = None
    control_dt: typing.Optional[float] = None
    realtime_rate: float = 1.0
    plant: PlantSettings = field(default_factory=PlantSettings)
    camera: typing.Optional[CameraSettings] = None
    start: typing.Optional[StartPose] = None
    limits: EpisodeLimits = field(default_factory=EpisodeLimits)
    sleep: SleepSettings = field(default_factory=SleepSettings)
    scene: SceneSettings = field(default_factory=SceneSettings)
    randomize: RandomizeSettings = field(default_factory=RandomizeSettings)

    def validate(self) -> None:
        """Raise :class:`ScenarioError` naming the first bad field."""
        from pr2_drake.tasks import task_id

        if self.task is not None:
            try:
                self.task = task_id(self.task)
            except ValueError as e:
                raise ScenarioError(str(e)) from None
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ScenarioError(f"seed must be a non-negative integer, got {self.seed!r}")
        if self.seconds != math.inf:  # inf: no limit (the Python API's choice; not in YAML)
            _positive("seconds", self.seconds)
        check_control_dt(self.control_dt)
        if not (isinstance(self.realtime_rate, (int, float)) and math.isfinite(self.realtime_rate)
                and self.realtime_rate >= 0):
            raise ScenarioError(f"realtime_rate must be >= 0, got {self.realtime_rate!r}")
        if self.agent is not None and self.diagram is not None:
            raise ScenarioError("give either a diagram or an agent, not both")
        for name in ("fall_height", "max_speed", "max_coordinate"):
            _positive(f"limits.{name}", getattr(self.limits, name))
        try:
            self.sleep.validate()
            self.randomize.validate()
            config = self.testbed_config()
            config.validate()
        except ValueError as e:
            raise ScenarioError(str(e)) from None
        if self.control_dt is not None and self.control_dt < config.time_step * (1 - 1e-9):
            raise ScenarioError(f"control_dt must be at least one physics step "
                                f"({config.time_step:g} s), got {self.control_dt!r}")

    def switches(self) -> list[str]:
        """The scenario switches on in this episode, by name: ``scene.variation`` (a scene
        drawn from the seed) and ``randomize`` (domain randomisation); empty for the task as
        given. Reports, ``eval``'s summary, ``compete``'s results and the leaderboard state
        them beside the scores."""
        return (["scene.variation"] if self.scene.variation else []) + (
            ["randomize"] if self.randomize.enabled else [])

    def testbed_config(self) -> TestbedConfig:
        """The testbed block's configuration for this scenario."""
        p = self.plant
        return TestbedConfig(
            task=self.task, seed=int(self.seed), time_step=p.time_step,
            contact_approximation=p.contact_approximation, contact_model=p.contact_model,
            camera=self.camera, start=self.start, variation=bool(self.scene.variation),
            randomize=self.randomize if self.randomize.enabled else None,
        )

    def time_limit(self, task_time_limit: typing.Optional[float]) -> float:
        """Simulated seconds this episode may last: ``seconds`` capped by the task's limit."""
        if task_time_limit is None:
            return FREE_RUN_SECONDS if self.seconds is None else float(self.seconds)
        return float(task_time_limit) if self.seconds is None else min(task_time_limit,
                                                                        float(self.seconds))

    def dump(self) -> str:
        """The scenario as YAML (loadable by :func:`load_scenario`)."""
        return yaml_dump_typed(self)


def check_control_dt(value) -> None:
    """Raise :class:`ScenarioError` unless ``value`` is None or a control period in
    (0, MAX_CONTROL_DT] [s] (a scenario's, or a ``next_action`` agent's own)."""
    _positive("control_dt", value, upper=MAX_CONTROL_DT)


def _positive(name: str, value, upper: float = math.inf) -> None:
    if value is None:
        return
    if (isinstance(value, bool) or not isinstance(value, (int, float))
            or not math.isfinite(value) or not 0 < value <= upper):
        bound = "" if math.isinf(upper) else f" and at most {upper:g}"
        raise ScenarioError(f"{name} must be a positive finite number{bound}, got {value!r}")


def load_scenario(path: typing.Union[str, Path, None] = None,
                  overrides: typing.Sequence[str] = (),
                  defaults: typing.Optional[Scenario] = None) -> Scenario:
    """Read a scenario YAML (or start from ``defaults``) and apply ``overrides``.

    Args:
        path: a scenario YAML file; None = start from ``defaults`` (or :class:`Scenario`()).
        overrides: each either ``key=value`` with a dotted key (``camera.fps=5``) and a YAML
            value, or a YAML mapping (``"{seed: 3, plant: {time_step: 0.002}}"``).
        defaults: the scenario the file and overrides are merged onto.

    The values are checked where running starts (:class:`pr2_drake.episode.Episode` calls
    :meth:`Scenario.validate`); here only the YAML and the field types.

    Raises:
        ScenarioError: naming the file or the override and what is wrong with it.
    """
    scenario = defaults if defaults is not None else Scenario()
    if path is not None:
        try:
            file = resolve_user_path(path, "scenario")
        except FileNotFoundError as e:
            raise ScenarioError(str(e)) from None
        scenario = _merge(scenario, file.read_text(), f"scenario {path}")
    for text in overrides:
        scenario = _merge(scenario, _override_yaml(text), f"override {text!r}")
    return scenario


def _override_yaml(text: str) -> str:
    """``a.b=value`` -> ``{a: {b: value}}``; anything else is taken as YAML as it is."""
    key, sep, value = text.partition("=")
    if not sep or not key.strip() or any(c in key for c in "{}:[] "):
        return text
    parts = key.strip().split(".")
    out = value.strip() or "null"
    for part in reversed(parts):
        out = f"{{{part}: {out}}}"
    return out


def _merge(scenario: Scenario, data: str, where: str) -> Scenario:
    try:
        return yaml_load_typed(schema=Scenario, data=data, defaults=scenario,
                               allow_schema_with_no_yaml=True)
    except Exception as e:  # yaml syntax, unknown field, wrong type: one line naming the source
        message = " ".join(str(e).split())
        raise ScenarioError(f"{where}: {type(e).__name__}: {message}") from None

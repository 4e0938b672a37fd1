"""One episode: a scenario built into a diagram, simulated, judged and reported.

This is the one place where the testbed, the agent's blocks and the ``Simulator`` are put
together (:class:`Episode`), where the scenario is validated, where an episode's end is decided
(:meth:`Episode.judge`: the referee, the time limit, divergence) and where faults are named
(:meth:`Episode.advance_to`). ``pr2-drake run`` and ``eval`` (:mod:`pr2_drake.run`),
:class:`pr2_drake.env.Env`, the gymnasium wrapper, the competition, the benchmarks and the
tests all go through it; nothing above it is imported here::

    from pr2_drake.episode import Episode, wire_system
    from pr2_drake.controllers.standing import StandingController
    episode = Episode(Scenario(task=1, seed=7), wire_system(StandingController()))
    episode.initialize()
    status = episode.advance_to(1.0)

Every end has a name (``report["termination"]``) and keeps the points earned before it:
``completed``, ``fell``, ``left_region``, ``timeout``, ``diverged`` (non-finite state, Drake's
own failure, or a state beyond :class:`pr2_drake.scenario.EpisodeLimits`), ``invalid_action``
(the action failed validation; the message names the key), ``agent_error`` (the agent raised;
its exception's type and message) and ``agent_exit`` (the agent called ``sys.exit``).
"""

from __future__ import annotations

import gc
import warnings
from dataclasses import replace
from pathlib import Path
from typing import Any, Callable

import numpy as np
from pydrake.geometry import Meshcat
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder, System

from pr2_drake.ports import P_WB
from pr2_drake.randomize import PhysicsSample, apply_physics, draw_physics
from pr2_drake.scenario import Scenario
from pr2_drake.sleep import ObjectSleeper
from pr2_drake.tasks.base import EpisodeStatus
from pr2_drake.testbed import Testbed

# Source files of the testbed's own blocks: a fault raised there is the testbed's verdict on
# its input (a ValueError: invalid_action), not the agent's error.
_PACKAGE = Path(__file__).resolve().parent
_TESTBED_FILES = {str(_PACKAGE / f) for f in (
    "actuation.py", "grasp.py", "ports.py", "camera.py", "testbed.py", "scene.py", "episode.py",
    "observation.py", "randomize.py", "randomize_systems.py")}
_TESTBED_DIRS = (str(_PACKAGE / "tasks"),)
_SLEEP_FILE = str(_PACKAGE / "sleep.py")

Wiring = Callable[[DiagramBuilder, Testbed], Any]
SceneBuilder = Callable[[Any, np.random.Generator], Any]  # f(plant, rng) -> Scene


class Episode:
    """The testbed of a scenario plus the blocks ``wire`` adds, with its Simulator.

    Args:
        scenario: what to build (validated here).
        wire: ``wire(builder, testbed)`` adds and connects the agent's blocks (the testbed is
            already in ``builder``); its return value is kept as :attr:`blocks`. None: no
            blocks (the caller fixes the testbed's inputs, as :class:`pr2_drake.env.Env` does).
        meshcat: draw to this Meshcat.
        scene_builder: ``f(plant, rng) -> Scene`` in place of the scenario's task or flat
            ground (a benchmark's own terrain, e.g. the stairs rig); the scenario's task must
            be None.

    Attributes:
        testbed, diagram, simulator, context: the built system and its root context.
        tb_context, plant_context: the testbed's and the plant's contexts in ``context``.
        sleeper: puts resting free objects to sleep (:mod:`pr2_drake.sleep`) at the check
            times of :meth:`advance_to`.
        limit: simulated time at which the episode ends "timeout" [s].
        status: the latest verdict (:class:`EpisodeStatus`); ``message`` says why a fault
            ended the episode.
        physics: the domain randomisation's draw (:class:`pr2_drake.randomize.PhysicsSample`),
            set in the context at every :meth:`initialize`; None with ``randomize`` off.
    """

    def __init__(self, scenario: Scenario, wire: Wiring | None = None,
                 meshcat: Meshcat | None = None, scene_builder: SceneBuilder | None = None):
        scenario.validate()
        # Free the diagrams of earlier episodes first: their reference cycles (see
        # pr2_drake.lifetime) wait for a full collection, and each holds ~35 MB.
        gc.collect()
        self.scenario = scenario
        config = scenario.testbed_config()
        if scene_builder is not None:
            config = replace(config, scene_builder=scene_builder)
        testbed = Testbed(config, meshcat)
        builder = DiagramBuilder()
        builder.AddSystem(testbed)
        self.blocks = wire(builder, testbed) if wire is not None else None
        self.diagram = builder.Build()
        self.testbed = testbed
        self.simulator = Simulator(self.diagram)
        self.context = self.simulator.get_mutable_context()
        self.tb_context = testbed.GetMyMutableContextFromRoot(self.context)
        self.plant_context = testbed.plant.GetMyMutableContextFromRoot(self.context)
        task = testbed.task
        self.limit = scenario.time_limit(task.spec.time_limit if task is not None else None)
        self._episode_port = testbed.GetOutputPort("episode") if task is not None else None
        self._state_port = testbed.GetOutputPort("plant_state")
        self._body_port = testbed.GetOutputPort("body_state")
        self._internal = {id(s) for s in testbed.GetSystems()}
        self.sleeper = ObjectSleeper(testbed, scenario.sleep)
        self.status = EpisodeStatus(max_score=task.spec.max_score if task is not None else 0.0)
        self.message = ""
        self.physics: PhysicsSample | None = None
        if scenario.randomize.enabled:
            self.redraw_physics(scenario.seed)

    # -- running ------------------------------------------------------------------------------
    @property
    def time(self) -> float:
        return self.context.get_time()

    def redraw_physics(self, seed: int) -> PhysicsSample:
        """Draw the randomised physics of ``seed`` for this diagram (:attr:`physics`); the
        next :meth:`initialize` sets it. A fast reset to another seed calls this."""
        self.physics = draw_physics(self.scenario.randomize, seed, self.testbed, self.limit)
        return self.physics

    def initialize(self) -> EpisodeStatus:
        """Reset the verdict, set the randomised physics (if any) and initialize the
        simulator; returns the first verdict."""
        self.message = ""
        self.status = EpisodeStatus(max_score=self.status.max_score)
        if self.physics is not None:
            apply_physics(self.testbed, self.context, self.physics)
        self.sleeper.reset(self.context)
        try:
            self.simulator.Initialize()
        except Exception as e:
            self._fault(e)
            return self.status
        self.status = self.judge()
        return self.status

    def advance_to(self, t: float) -> EpisodeStatus:
        """Simulate to ``t`` [s] (at most to the limit) and return the verdict. A fault ends
        the episode with its name (see the module docstring) instead of raising.

        With sleeping objects (:attr:`sleeper`), the advance stops at every check time
        k * check_period on the way and the sleeper updates who sleeps there: the same
        simulated times whatever chunks the caller advances in."""
        if self.status.done:
            return self.status
        try:
            self._advance(min(t, self.limit))
        except (Exception, SystemExit) as e:
            self._fault(e)
            return self.status
        self.status = self.judge()
        return self.status

    def _advance(self, target: float) -> None:
        sleeper, sim = self.sleeper, self.simulator
        if sleeper.active:
            tol = sleeper.tolerance
            while True:
                g = sleeper.next_check(self.time)
                if g > target + tol:
                    break
                sim.AdvanceTo(g)
                sleeper.check(self.context)
        if self.time < target:
            sim.AdvanceTo(target)

    def end(self, termination: str, message: str = "") -> EpisodeStatus:
        """End the episode now with ``termination``, keeping the points earned."""
        s = self.status
        self.status = EpisodeStatus(s.score, s.max_score, True, False, termination,
                                    list(s.items), self.time)
        self.message = message
        return self.status

    # -- the verdict --------------------------------------------------------------------------
    def judge(self) -> EpisodeStatus:
        """The referee's verdict (or, without a task, fall and time), overruled by
        "diverged" when the state is non-finite or beyond the scenario's limits, and ended
        "timeout" at the limit."""
        t = self.time
        if self._episode_port is not None:
            status = self._episode_port.Eval(self.tb_context)
        else:
            status = EpisodeStatus(time=t)
            z = self._body_port.Eval(self.tb_context)[P_WB][2]
            if z < self.scenario.limits.fall_height:
                status.done, status.termination = True, "fell"
        fault = self.state_fault()
        if fault:
            self.status = status
            return self.end("diverged", fault)
        if not status.done and t >= self.limit - 1e-9:
            status = replace(status, done=True, termination="timeout", items=list(status.items))
        return status

    def state_fault(self) -> str:
        """Why the plant state is not physical ("" if it is)."""
        x = self._state_port.Eval(self.tb_context)
        if not np.all(np.isfinite(x)):
            return "the state is not finite (NaN or inf)"
        nq = self.testbed.plant.num_positions()
        limits = self.scenario.limits
        q_max = float(np.max(np.abs(x[:nq]))) if nq else 0.0
        v_max = float(np.max(np.abs(x[nq:]))) if x.size > nq else 0.0
        if v_max > limits.max_speed:
            return f"a speed of {v_max:.3g} (m/s or rad/s) is beyond limits.max_speed"
        if q_max > limits.max_coordinate:
            return f"a coordinate of {q_max:.3g} (m or rad) is beyond limits.max_coordinate"
        return ""

    def report(self, agent: str | None = None, wall_time: float | None = None,
               sim_wall_time: float | None = None) -> dict[str, Any]:
        """The episode's result in the ``report.json`` layout (see the README)."""
        s, task = self.status, self.testbed.task
        t = self.time
        report = {
            "task": None if task is None else task.id,
            "task_name": "flat" if task is None else task.name,
            "seed": int(self.scenario.seed),
            "agent": agent,
            "score": float(s.score),
            "max_score": float(s.max_score),
            "success": bool(s.success),
            "termination": s.termination or "timeout",
            "items": [{"item": e.item, "points": e.points, "time": round(e.time, 4)}
                      for e in s.items],
            "sim_time": round(t, 6),
            "wall_time": None if wall_time is None else round(wall_time, 3),
            "real_time_factor": (round(t / sim_wall_time, 3) if sim_wall_time else None),
        }
        if self.scenario.switches():
            report["scenario"] = self.scenario.switches()  # the switches on (Scenario.switches)
        if task is not None and task.variation is not None:
            report["variation"] = task.variation  # the scene drawn (scene.variation)
        if self.message:
            report["message"] = self.message
        if self.physics is not None:
            report["physics"] = self.physics.report()
        return report

    # -- faults -------------------------------------------------------------------------------
    def _fault(self, e: BaseException) -> None:
        origin = self._origin(e)
        text = f"{type(e).__name__}: {' '.join(str(e).split())}"
        if isinstance(e, SystemExit) and str(e.code).startswith("Failure at "):
            origin = "drake"  # a failed condition inside Drake reaches Python as SystemExit
        if isinstance(e, SystemExit) and origin != "drake":
            self.end("agent_exit", f"the agent called sys.exit({e.code!r})")
        elif origin == "agent":
            self.end("agent_error", text)
        elif origin == "testbed" and isinstance(e, ValueError):
            self.end("invalid_action", " ".join(str(e).split()))
        elif origin == "drake":
            self.end("diverged", f"the simulation failed: {text}")
        else:  # a bug in the testbed itself: let it surface
            raise e

    def _origin(self, e: BaseException) -> str:
        """Whose code raised: "agent", "testbed" (its own blocks) or "drake" (no Python
        callback involved). Found from the innermost Python frame run on behalf of a
        System (its ``self``), else from the frame's source file."""
        frames = []
        tb = e.__traceback__
        while tb is not None:
            frames.append(tb.tb_frame)
            tb = tb.tb_next
        mine = {Episode.advance_to.__code__, Episode.initialize.__code__,
                Episode._advance.__code__}
        start = max((i for i, f in enumerate(frames) if f.f_code in mine), default=-1)
        callbacks = frames[start + 1:]
        if callbacks and callbacks[0].f_code.co_filename == _SLEEP_FILE:
            return "testbed bug"  # the sleeper's own failure: surfaces as it is
        if not callbacks:
            return "drake"
        for frame in reversed(callbacks):
            owner = frame.f_locals.get("self")
            if isinstance(owner, System):
                return "testbed" if id(owner) in self._internal else "agent"
        first = callbacks[0].f_code.co_filename
        if first in _TESTBED_FILES or first.startswith(_TESTBED_DIRS):
            return "testbed"
        return "agent"


# -- wiring -------------------------------------------------------------------------------------
def connect_by_name(builder: DiagramBuilder, testbed, agent) -> list[str]:
    """Connect every agent input to the testbed output of the same name and every agent
    output to the testbed input of the same name. Returns the connections made.

    Raises:
        ValueError: an agent input port has no testbed output of that name.
    """
    made = []
    for i in range(agent.num_input_ports()):
        port = agent.get_input_port(i)
        name = port.get_name()
        if not testbed.HasOutputPort(name):
            outputs = [testbed.get_output_port(k).get_name()
                       for k in range(testbed.num_output_ports())]
            raise ValueError(
                f"agent input port {name!r} has no testbed output of that name; testbed outputs: "
                f"{outputs}"
            )
        builder.Connect(testbed.GetOutputPort(name), port)
        made.append(f"testbed.{name} -> agent.{name}")
    for i in range(agent.num_output_ports()):
        port = agent.get_output_port(i)
        name = port.get_name()
        if testbed.HasInputPort(name):
            builder.Connect(port, testbed.GetInputPort(name))
            made.append(f"agent.{name} -> testbed.{name}")
    return made


def wire_system(system: System) -> Wiring:
    """A wiring that adds ``system`` and connects it to the testbed by port name."""

    def wire(builder: DiagramBuilder, testbed: Testbed) -> System:
        warn_if_uncollectable(system)
        builder.AddSystem(system)
        connect_by_name(builder, testbed, system)
        return system

    return wire


_WARNED: set[type] = set()


def warn_if_uncollectable(system: System) -> None:
    """Warn once per class when a Python System class lacks ``__slots__ = ()``: such a
    system keeps its whole diagram (~35 MB) alive after the episode (see
    :mod:`pr2_drake.lifetime`)."""
    cls = type(system)
    if cls in _WARNED:
        return
    for c in cls.__mro__:
        if c.__module__.startswith("pydrake"):
            break
        if "__slots__" not in c.__dict__:
            _WARNED.add(cls)
            warnings.warn(
                f"{c.__module__}.{c.__qualname__} does not declare __slots__ = (): every "
                "episode's diagram will stay in memory until the process ends; add "
                "`__slots__ = ()` to the class (see pr2_drake.lifetime)", stacklevel=3)
            return

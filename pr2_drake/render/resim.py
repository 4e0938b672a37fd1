"""Re-simulating an episode to render it.

The episode runs exactly as ``pr2-drake run`` runs it (:func:`run_episode`, the same scenario,
agent and seed), with one block beside the agent, :class:`StateRecorder`, that keeps the
plant's state at the requested times. The block only reads the testbed's ``plant_state``
after each physics step (a per-step publish event: no state, no new step boundaries), so the
trajectory is the same, step for step, as that of ``run``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence, TextIO

import numpy as np
from pydrake.systems.framework import LeafSystem

# The one import of the run path in this package.
from pr2_drake.run import run_episode

TIME_TOLERANCE = 1e-6  # [s] a step this close before a requested time counts as at it


@dataclass
class RecordedState:
    """The plant state [q; v] (``x``) at the first physics step at or after ``requested``
    [s]; ``time`` is that step's time [s]."""

    requested: float
    time: float
    x: np.ndarray


class StateRecorder(LeafSystem):
    """Keeps the plant state at given times (see the module docstring).

    Input port ``plant_state`` (the testbed's, [q; v]). Attribute ``states``: the
    :class:`RecordedState` list, in time order.
    """

    __slots__ = ()  # see pr2_drake.lifetime

    def __init__(self, size: int, times: Sequence[float]):
        super().__init__()
        self.times = sorted(float(t) for t in times)
        self.states: list[RecordedState] = []
        self._in = self.DeclareVectorInputPort("plant_state", size)
        self.DeclareInitializationPublishEvent(self._record)
        self.DeclarePerStepPublishEvent(self._record)

    def _record(self, context) -> None:
        t = context.get_time()
        k = len(self.states)
        if k < len(self.times) and t >= self.times[k] - TIME_TOLERANCE:
            x = self._in.Eval(context).copy()
            while k < len(self.times) and t >= self.times[k] - TIME_TOLERANCE:
                self.states.append(RecordedState(self.times[k], t, x))
                k += 1


def resimulate(scenario, times: Sequence[float], progress: TextIO | None = None
               ) -> tuple[dict[str, Any], list[RecordedState]]:
    """Run ``scenario`` as ``pr2-drake run`` does and keep the plant state at ``times`` [s].

    Returns:
        (the episode's report, the states recorded; times after the episode's end have none).
    """
    box: list[StateRecorder] = []

    def watch(builder, testbed) -> None:
        recorder = builder.AddNamedSystem(
            "render_state_recorder", StateRecorder(testbed.plant.num_multibody_states(), times))
        builder.Connect(testbed.GetOutputPort("plant_state"), recorder.get_input_port())
        box.append(recorder)

    report = run_episode(scenario, watchers=watch, progress=progress)
    return report, box[0].states


def episode_limit(scenario) -> float:
    """Simulated seconds the scenario's episode may last at most [s]."""
    from pr2_drake.tasks import get_task

    task = get_task(scenario.task).spec.time_limit if scenario.task is not None else None
    return scenario.time_limit(task)

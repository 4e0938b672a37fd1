"""TaskSequencer: the base of the reference agents' stage machines (valve, steps, search), and
the one helper that builds an agent of a sequencer and the walking controller.

A sequencer is a LeafSystem whose memory (stage, velocity command, hand targets, paths, ...)
is a dataclass held as abstract state in its Context, as the referees' ``EpisodeStatus`` is:
a fresh Context starts the sequence, and a simulation re-run from a saved Context goes on
from there. Its periodic unrestricted update copies the memory, lets :meth:`TaskSequencer.step`
change the copy from the inputs, and stores it; its outputs publish the memory's fields, so
they change only at its updates and depend on the state alone.

The fields every memory has (:class:`SequencerMemory`) and the outputs that publish them:
    cmd: (vx, vy, yaw rate) in the heading frame [m/s, m/s, rad/s] -> ``velocity_command``.
    targets: per hand (left, right) a position in world [m] or None -> ``hand_targets``.
    pick: "" or a hand ("left_hand", "right_hand") -> ``pick`` (with ``grasp=True``).
    release: bool -> ``release`` (with ``grasp=True``).
    stage: the stage (an IntEnum) -> ``stage`` (1, as a float); t_stage: when it began [s].
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
from typing import Any, NamedTuple, Optional

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, Diagram, DiagramBuilder, LeafSystem

from pr2_drake.controllers.planning.gait import Phase
from pr2_drake.controllers.whole_body import STATUS_FIELDS
from pr2_drake.lifetime import weak_calc

#: The walking controller's status fields by name (its ``status`` output, a vector).
WALKER_STATUS = {name: i for i, name in enumerate(STATUS_FIELDS)}
#: The agent's outputs, in this order, besides the walker's legs and arms commands.
EXPORTED = ("pick", "release", "velocity_command", "stage", "camera_capture",
            "camera_capture_color")


@dataclass
class SequencerMemory:
    """What every sequencer remembers between its updates (see the module docstring)."""

    stage: int = 0
    t_stage: float = 0.0
    cmd: np.ndarray = field(default_factory=lambda: np.zeros(3))
    targets: list = field(default_factory=lambda: [None, None])
    pick: str = ""
    release: bool = False

    def __deepcopy__(self, memo) -> "SequencerMemory":
        # Drake copies this abstract state at every update (50 Hz): copy.deepcopy's own
        # result (a new object of this class, each field deep-copied, shared references kept
        # shared through ``memo``), without its generic reduce/reconstruct path for the
        # dataclass itself and with immutable scalars taken as they are.
        new = object.__new__(type(self))
        memo[id(self)] = new
        fields = new.__dict__
        for name, value in self.__dict__.items():
            fields[name] = value if type(value) in _IMMUTABLE else copy.deepcopy(value, memo)
        return new


_IMMUTABLE = frozenset({type(None), bool, int, float, str})


class Now(NamedTuple):
    """What one update reads: time [s], base position p_WB [m] and heading [rad], whether the
    walking controller's gait stands, the time in the stage at the update's start [s], and the
    grasp's state (a :class:`pr2_drake.grasp.PickState`; None where the agent grasps nothing)."""

    t: float
    p_WB: np.ndarray
    yaw: float
    standing: bool
    elapsed: float
    pick: Optional[Any] = None


class TaskSequencer(LeafSystem):
    """See the module docstring. A subclass declares its inputs, calls
    :meth:`declare_sequencer` with its initial memory, and implements :meth:`step`; it may
    override any ``_calc_*``."""

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    def declare_sequencer(self, memory: SequencerMemory, period: float, grasp: bool) -> set:
        """Declare the memory (abstract state, initial value ``memory``), the ``walker_status``
        input, the update every ``period`` [s] and the outputs ``velocity_command``,
        ``hand_targets``, (``pick``, ``release`` when ``grasp``) and ``stage``; returns their
        prerequisites (the state), for the subclass's own outputs."""
        self._memory_index = self.DeclareAbstractState(AbstractValue.Make(memory))
        self._walker_status = self.DeclareVectorInputPort("walker_status", len(STATUS_FIELDS))
        self.DeclarePeriodicUnrestrictedUpdateEvent(period, 0.0, self._update)
        after_update = {self.all_state_ticket()}
        self.DeclareVectorOutputPort("velocity_command", 3, weak_calc(self._calc_cmd),
                                     prerequisites_of_calc=after_update)
        self.DeclareAbstractOutputPort("hand_targets", lambda: AbstractValue.Make([None, None]),
                                       weak_calc(self._calc_targets),
                                       prerequisites_of_calc=after_update)
        if grasp:
            self.DeclareAbstractOutputPort("pick", lambda: AbstractValue.Make(""),
                                           weak_calc(self._calc_pick),
                                           prerequisites_of_calc=after_update)
            self.DeclareAbstractOutputPort("release", lambda: AbstractValue.Make(False),
                                           weak_calc(self._calc_release),
                                           prerequisites_of_calc=after_update)
        self.DeclareVectorOutputPort("stage", 1, weak_calc(self._calc_stage),
                                     prerequisites_of_calc=after_update)
        return after_update

    # ---- memory ------------------------------------------------------------------------------
    def memory(self, context) -> Any:
        """The memory in ``context`` (this system's context); read it, do not change it."""
        return context.get_abstract_state(self._memory_index).get_value()

    def mutable_memory(self, context) -> Any:
        """The memory in ``context``, to change (the outputs see the change)."""
        return context.get_mutable_abstract_state(self._memory_index).get_value()

    def step(self, context, m) -> None:
        """One update: read the inputs of ``context`` and change the memory ``m`` (a copy)."""
        raise NotImplementedError

    def walker_standing(self, context) -> bool:
        """Whether the walking controller's gait stands (its ``phase`` status field)."""
        status = self._walker_status.Eval(context)
        return int(status[WALKER_STATUS["phase"]]) == Phase.STAND

    def _update(self, context, state) -> None:
        m = copy.deepcopy(self.memory(context))
        self.step(context, m)
        state.get_mutable_abstract_state(self._memory_index).set_value(m)

    # ---- outputs -----------------------------------------------------------------------------
    def _calc_cmd(self, context, output: BasicVector) -> None:
        output.SetFromVector(self.memory(context).cmd)

    def _calc_targets(self, context, output) -> None:
        output.set_value([None if x is None else np.array(x)
                          for x in self.memory(context).targets])

    def _calc_pick(self, context, output) -> None:
        output.set_value(self.memory(context).pick)

    def _calc_release(self, context, output) -> None:
        output.set_value(bool(self.memory(context).release))

    def _calc_stage(self, context, output: BasicVector) -> None:
        output.SetFromVector([float(self.memory(context).stage)])


def build_sequencer_agent(agent: Diagram, sequencer: TaskSequencer, walker: LeafSystem) -> None:
    """Build ``agent`` (call from its constructor) of ``sequencer`` and ``walker`` (a walking
    controller with its arms in the QP), with the testbed's port names.

    Inputs: each input the sequencer shares with the walker (``joint_state``, ``body_state``,
    ``pick_state``) is exported once and feeds both; the sequencer's other inputs (e.g.
    ``rgbd``) are exported; ``walker_status`` comes from the walker's ``status``. The
    sequencer's ``velocity_command`` and ``hand_targets`` drive the walker. Outputs: the
    walker's ``legs_command`` and ``arms_command``, then the sequencer's :data:`EXPORTED`
    outputs that it has.
    """
    builder = DiagramBuilder()
    seq = builder.AddNamedSystem("sequencer", sequencer)
    walker = builder.AddNamedSystem("walker", walker)
    driven = ("velocity_command", "hand_targets")
    for i in range(walker.num_input_ports()):
        name = walker.get_input_port(i).get_name()
        if name not in driven and seq.HasInputPort(name):
            port = builder.ExportInput(walker.GetInputPort(name), name)
            builder.ConnectInput(port, seq.GetInputPort(name))
    for i in range(seq.num_input_ports()):
        name = seq.get_input_port(i).get_name()
        if name != "walker_status" and not walker.HasInputPort(name):
            builder.ExportInput(seq.GetInputPort(name), name)
    builder.Connect(walker.GetOutputPort("status"), seq.GetInputPort("walker_status"))
    for name in driven:
        builder.Connect(seq.GetOutputPort(name), walker.GetInputPort(name))
    builder.ExportOutput(walker.GetOutputPort("legs_command"), "legs_command")
    builder.ExportOutput(walker.GetOutputPort("arms_command"), "arms_command")
    for name in EXPORTED:
        if seq.HasOutputPort(name):
            builder.ExportOutput(seq.GetOutputPort(name), name)
    builder.BuildInto(agent)


def smoothstep(s: float) -> float:
    """3 s^2 - 2 s^3 of ``s`` clipped to [0, 1]: 0 -> 0, 1 -> 1, flat at both ends."""
    s = min(max(s, 0.0), 1.0)
    return s * s * (3.0 - 2.0 * s)


def along_path(path: list, t0: float, t: float, segment_time: float) -> tuple[np.ndarray, float]:
    """(point, k): the point at time ``t`` [s] of a hand path (waypoints, W [m]) that starts
    at ``t0`` and takes ``segment_time`` [s] per segment, each eased by :func:`smoothstep`
    (it holds the last waypoint after the end); k = the segments travelled, fractional."""
    k = (t - t0) / segment_time
    seg = min(int(k), len(path) - 2)
    a, b = path[seg], path[seg + 1]
    return a + (b - a) * smoothstep(k - seg), k

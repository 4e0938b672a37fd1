"""TaskSequencer: the base of the reference agents' stage machines (valve, steps, search).

A sequencer is a LeafSystem whose periodic update reads the robot's state, moves through its
stages and writes what the walking controller and the testbed should do into attributes. Its
outputs publish those attributes; they change only at its updates (each update writes the
stage into the discrete state), so they are declared to depend on the state alone.

Attributes a subclass's update writes (and the outputs that publish them):
    cmd: (vx, vy, yaw rate) in the heading frame [m/s, m/s, rad/s] -> ``velocity_command``.
    targets: per hand (left, right) a position in world [m] or None -> ``hand_targets``.
    pick: "" or a hand ("left", "right") -> ``pick`` (with ``grasp=True``).
    release: bool -> ``release`` (with ``grasp=True``).
    stage: an IntEnum -> ``stage`` (1, as a float).
"""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, LeafSystem

from pr2_drake.lifetime import weak_calc


class TaskSequencer(LeafSystem):
    """See the module docstring. A subclass declares its inputs and state, then calls
    :meth:`declare_command_outputs`; it may override any ``_calc_*``."""

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    def declare_command_outputs(self, grasp: bool) -> set:
        """Declare ``velocity_command``, ``hand_targets``, (``pick``, ``release`` when
        ``grasp``) and ``stage``; returns their prerequisites (the whole state), for the
        subclass's own outputs."""
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

    def _calc_cmd(self, context, output: BasicVector) -> None:
        output.SetFromVector(self.cmd)

    def _calc_targets(self, context, output) -> None:
        output.set_value([None if x is None else np.array(x) for x in self.targets])

    def _calc_pick(self, context, output) -> None:
        output.set_value(self.pick)

    def _calc_release(self, context, output) -> None:
        output.set_value(bool(self.release))

    def _calc_stage(self, context, output: BasicVector) -> None:
        output.SetFromVector([float(self.stage)])

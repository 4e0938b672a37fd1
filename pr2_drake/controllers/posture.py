"""ArmPosture: holds the arms at a fixed pose in position mode (for walking).

Output port ``arms_command``: :class:`pr2_drake.ports.JointGroupCommand`, mode "position",
the nominal arm pose [rad] (``default_pose`` of models/kuavo/params.yaml unless given) with
stiffness [Nm/rad] and damping [Nm s/rad] per joint.
"""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import LeafSystem

from pr2_drake.lifetime import weak_calc
from pr2_drake.ports import N_ARMS, JointGroupCommand
from pr2_drake.robot.params import load_robot_params


class ArmPosture(LeafSystem):
    """Constant arm posture command (see the module docstring)."""

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    def __init__(self, q_arms: np.ndarray | None = None, stiffness: float = 60.0,
                 damping: float = 3.0):
        super().__init__()
        q = load_robot_params().default_positions("arms") if q_arms is None else q_arms
        q = np.asarray(q, dtype=float)
        if q.shape != (N_ARMS,) or not np.all(np.isfinite(q)):
            raise ValueError(f"ArmPosture: q_arms must be {N_ARMS} finite values, got {q}")
        self._cmd = JointGroupCommand.position(q, np.full(N_ARMS, stiffness),
                                               np.full(N_ARMS, damping))
        cmd = self._cmd  # the allocator must not capture self (pr2_drake.lifetime)
        # A constant: computed once, not at every physics step (the command object stays the
        # same, so the actuation adapter's per-command work is done once too).
        self.DeclareAbstractOutputPort("arms_command",
                                       lambda: AbstractValue.Make(cmd), weak_calc(self._calc),
                                       prerequisites_of_calc={self.nothing_ticket()})

    def _calc(self, context, output) -> None:
        output.set_value(self._cmd)

"""The walking control law without Drake's systems framework (kept for existing imports).

The law is a composition of parts: :class:`pr2_drake.controllers.gait.GaitPlanner` (gait state
machine, footsteps, CoM/DCM, swing, step adjustment), the tracking tasks of
:mod:`pr2_drake.controllers.tasks` and the QP of :mod:`pr2_drake.controllers.wbqp`, put together
by :class:`pr2_drake.controllers.whole_body.WholeBodyController`. ``WalkingCore`` is that
controller; ``WalkingCore.update(t, q, v, command)`` runs one tick and returns the leg torques.
"""

from __future__ import annotations

from pr2_drake.controllers.gait import Phase, rot_z, yaw_of
from pr2_drake.controllers.tasks import rotation_error
from pr2_drake.controllers.whole_body import (
    COMMAND_PORT,
    STATUS_FIELDS,
    TickInfo,
    WholeBodyController,
    check_command,
)

WalkingCore = WholeBodyController

__all__ = ["COMMAND_PORT", "STATUS_FIELDS", "Phase", "TickInfo", "WalkingCore", "check_command",
           "rot_z", "rotation_error", "yaw_of"]

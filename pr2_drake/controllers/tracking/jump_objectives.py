"""A jump's plan and the two tracking objectives it adds to the whole-body QP.

:class:`JumpPlan` is a :class:`pr2_drake.controllers.plan.WholeBodyPlan` with a 3-D CoM
acceleration (from the launch MPC, or an impedance on landing) and a reference for each sole
(flight: both soles swing). The other objectives (pelvis orientation, sole contacts, posture) read
the fields they always read. Frames: W world (z up); units m, s.
"""

from __future__ import annotations


import numpy as np

from pr2_drake.controllers.tracking.objectives import PelvisOrientationObjective, SwingSoleObjective, Objective
from pr2_drake.controllers.walking_params import ObjectiveGains


class Com3dObjective(Objective):
    """CoM acceleration rows J_com vdot = plan.com_acc - Jdot v, weighted by plan.com_weight."""

    def add_to(self, cost, model, plan) -> None:
        w = plan.com_weight
        if not np.any(w > 0):
            return
        _, _, J, jdv = model.com()
        cost.add(J, plan.com_acc - jdv, w)


class AngularMomentumObjective(Objective):
    """Rate of the centroidal angular momentum towards ``plan.L_rate``.

    The floating base's rows of M vdot + h = J_c^T f are the contact wrench about the base
    origin Bo (rotational rows) and the contact force (translational rows), in W. Moved to the
    CoM, the moment of the contact forces about the CoM, which is Ldot (gravity has none), is
    linear in vdot: Ldot = (M_r - [c - p_Bo]x M_t) vdot + (h_r - [c - p_Bo]x h_t).
    """

    def __init__(self, model):
        self.rot = np.asarray(model.maps.v_base[:3])
        self.trans = np.asarray(model.maps.v_base[3:])
        self.q_pos = np.asarray(model.maps.q_base[4:])

    def matrices(self, model) -> tuple[np.ndarray, np.ndarray]:
        """(A (3 x nv), b (3)) with Ldot = A vdot + b [N m] (W)."""
        M, h = model.mass_matrix(), model.bias()
        com = model.com()[0]
        r = com - model.q[self.q_pos]
        S = np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])
        A = M[self.rot] - S @ M[self.trans]
        b = h[self.rot] - S @ h[self.trans]
        return A, b

    def add_to(self, cost, model, plan) -> None:
        if plan.L_weight <= 0.0:
            return
        A, b = self.matrices(model)
        cost.add(A, plan.L_rate - b, np.full(3, plan.L_weight))


class ScaledPelvisObjective(PelvisOrientationObjective):
    """:class:`PelvisOrientationObjective` with its weight times ``plan.pelvis_scale``."""

    def add_to(self, cost, model, plan) -> None:
        w0 = self.w
        self.w = w0 * plan.pelvis_scale
        try:
            super().add_to(cost, model, plan)
        finally:
            self.w = w0


class _OneSwing:
    """The view of a plan that :class:`SwingSoleObjective` reads (``.swing``)."""

    __slots__ = ("swing",)

    def __init__(self):
        self.swing = None


class SolesObjective(Objective):
    """Both soles along ``plan.soles`` (the swing-sole rows of :class:`SwingSoleObjective` for each
    sole that has a reference)."""

    def __init__(self, pos: ObjectiveGains, rot: ObjectiveGains):
        self._swing = SwingSoleObjective(pos, rot)
        self._view = _OneSwing()

    def add_to(self, cost, model, plan) -> None:
        for ref in plan.soles:
            if ref is not None:
                self._view.swing = ref
                self._swing.add_to(cost, model, self._view)

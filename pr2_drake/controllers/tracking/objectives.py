"""Tracking objectives of the whole-body QP: small objects that each contribute cost rows.

A objective reads the plan (:class:`pr2_drake.controllers.plan.WholeBodyPlan`) and the robot model
(:class:`pr2_drake.controllers.model.WholeBodyModel`, already at the measured state) and
adds rows (J, desired acceleration a, weight w) to a :class:`ObjectiveCost`: the QP minimises
sum w (J vdot - a)^2 over the generalized accelerations vdot (Jdot v already subtracted from a).
Gains are :class:`pr2_drake.controllers.walking_params.ObjectiveGains` from YAML:
a = kp (x_d - x) + kd (v_d - v) + a_ff, kp [1/s^2], kd [1/s].

``objective.rows(model, plan)`` returns the rows as a list of (J, a, w) (for tests and plots); the
controller uses the faster ``objective.add_to(cost, model, plan)``.
"""

from __future__ import annotations

import math

import numpy as np
from pydrake.math import RotationMatrix

from pr2_drake.controllers.frames import rot_z
from pr2_drake.controllers.plan import WholeBodyPlan
from pr2_drake.controllers.walking_params import QpParams, ObjectiveGains
from pr2_drake.controllers.model import WholeBodyModel, index_or_slice


def rotation_error(R_d: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Axis-angle vector (in W) of R_d R^T: the rotation that takes R to R_d [rad]."""
    (e00, e01, e02), (e10, e11, e12), (e20, e21, e22) = np.dot(R_d, R.T).tolist()
    v = np.array([0.5 * (e21 - e12), 0.5 * (e02 - e20), 0.5 * (e10 - e01)])
    c = 0.5 * (e00 + e11 + e22 - 1.0)
    s = math.sqrt(np.dot(v, v))
    if s < 1e-9:
        if c > 0:
            return v
        # 180 degrees: axis from the symmetric part.
        aa = RotationMatrix(R_d @ R.T).ToAngleAxis()
        return aa.axis() * aa.angle()
    return v * (np.arctan2(s, c) / s)


class ObjectiveCost:
    """The QP cost over vdot, 0.5 vdot^T H vdot + g^T vdot, summed from objective rows.

    ``record=True`` also keeps every (J, a, w) added (slower; for tests and debugging).
    """

    def __init__(self, nv: int, record: bool = False):
        self.nv = nv
        self.H = np.zeros((nv, nv))
        self.g = np.zeros(nv)
        self._diag = self.H.reshape(-1)[::nv + 1]  # view
        self.record = record
        self.rows: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []

    def clear(self) -> None:
        self.H.fill(0.0)
        self.g.fill(0.0)
        self.rows.clear()

    def add(self, J: np.ndarray, a: np.ndarray, w: np.ndarray) -> None:
        """Rows w (J vdot - a)^2."""
        if self.record:
            self.rows.append((J, a, w))
        Jw = J * w[:, None]
        JwT = Jw.T
        self.H += np.dot(JwT, J)
        self.g -= np.dot(JwT, a)

    def add_selection(self, idx: np.ndarray | slice, a: np.ndarray, w: np.ndarray) -> None:
        """:meth:`add` for J = rows ``idx`` of the identity (same sums, no matrix products)."""
        if self.record:
            cols = np.arange(self.nv)[idx]  # (idx may be a slice)
            J = np.zeros((len(cols), self.nv))
            J[np.arange(len(cols)), cols] = 1.0
            self.rows.append((J, a, w))
        self._diag[idx] += w
        self.g[idx] -= w * a


class Objective:
    """A tracking objective: ``add_to`` adds its rows for this tick."""

    def add_to(self, cost: ObjectiveCost, model: WholeBodyModel, plan: WholeBodyPlan) -> None:
        raise NotImplementedError

    def rows(self, model: WholeBodyModel, plan: WholeBodyPlan):
        """This tick's rows as a list of (J, a, w)."""
        cost = ObjectiveCost(model.nv, record=True)
        self.add_to(cost, model, plan)
        return cost.rows


class ComObjective(Objective):
    """CoM acceleration: x, y from the plan's feedback law, z by PD to the planned height.

    In single support (``plan.com_frame_yaw`` set) the rows are expressed in the stance sole's
    yaw frame and the lateral row has ``lateral_single_weight``.
    """

    def __init__(self, xy: ObjectiveGains, z: ObjectiveGains, lateral_single_weight: float):
        self.xy, self.z = xy, z
        self.w = np.array([xy.weight, xy.weight, z.weight])
        self.w_single = np.array([xy.weight, lateral_single_weight, z.weight])

    def add_to(self, cost, model, plan) -> None:
        com, comd, J, jdv = model.com()
        ax, ay = plan.com_acc_xy.tolist()
        a_z = self.z.kp * (plan.com_z - float(com[2])) - self.z.kd * float(comd[2])
        j0, j1, j2 = jdv.tolist()
        a = np.array([ax - j0, ay - j1, a_z - j2])  # desired minus Jdot v
        if plan.com_frame_yaw is not None:
            RsT = rot_z(plan.com_frame_yaw).T
            cost.add(np.dot(RsT, J), np.dot(RsT, a), self.w_single)
        else:
            cost.add(J, a, self.w)


class PelvisOrientationObjective(Objective):
    """Pelvis (base_link) orientation towards ``plan.pelvis_R`` (rows of w_WB, in W)."""

    def __init__(self, gains: ObjectiveGains, model: WholeBodyModel):
        self.gains = gains
        self.idx = index_or_slice(model.maps.v_base[:3])
        self.w = np.full(3, gains.weight)

    def add_to(self, cost, model, plan) -> None:
        w_WB = model.v[self.idx]
        e = rotation_error(plan.pelvis_R, model.base_rotation())
        cost.add_selection(self.idx, self.gains.kp * e - self.gains.kd * w_WB, self.w)


class SoleContactObjective(Objective):
    """Stance soles do not accelerate: hard rows (``J_kin`` vdot = ``a_kin``, for the QP's
    constraints) for fully loaded soles, weighted cost rows for soles being loaded/unloaded.
    Also gathers ``J_all``, the contact-point Jacobians of both soles for the dynamics rows.

    A stance sole's points do not accelerate: 3 rows for the first point, 2 across the line to
    the second, 1 off the plane of a third (if any): independent rows only.
    """

    def __init__(self, qp: QpParams, model: WholeBodyModel):
        self.qp = qp
        m = model
        self.n_kin_foot = min(3 * m.n_points, 6) if m.n_points > 2 else 5
        self.J_all = np.zeros((6 * m.n_points, m.nv))
        self.J_kin = np.zeros((2 * self.n_kin_foot, m.nv))
        self.a_kin = np.full(2 * self.n_kin_foot, np.nan)
        self.w_soft = np.full(self.n_kin_foot, qp.contact_weight)
        # Selection rows per sole: the first point's 3 rows are constant, the others are
        # rewritten every tick (constraint_rows).
        self._E = [np.zeros((self.n_kin_foot, 3 * m.n_points)) for _ in (0, 1)]
        for E in self._E:
            E[0, 0] = E[1, 1] = E[2, 2] = 1.0

    def add_to(self, cost, model, plan) -> None:
        m = model
        self.J_kin.fill(0.0)
        self.a_kin.fill(np.nan)
        for side in (0, 1):
            Jc, jdv_c = m.contact_points(side)
            rows = slice(3 * m.n_points * side, 3 * m.n_points * (side + 1))
            self.J_all[rows] = Jc
            c = plan.contacts[side]
            if not c.active:
                continue
            a_c = -self.qp.contact_kd * np.dot(Jc, m.v) - jdv_c
            kr = slice(self.n_kin_foot * side, self.n_kin_foot * (side + 1))
            E = self.constraint_rows(m, side)
            EJ = np.dot(E, Jc)
            self.J_kin[kr] = EJ
            if c.hard:
                self.a_kin[kr] = np.dot(E, a_c)
            else:
                cost.add(EJ, np.dot(E, a_c), self.w_soft)

    def constraint_rows(self, m: WholeBodyModel, side: int) -> np.ndarray:
        """Selection E (n_kin_foot x 3n) of independent rows of a sole's point accelerations
        (this controller's array for the sole, rewritten on the next call: copy to keep)."""
        X = m.sole_pose(side)
        P = np.dot(X.rotation().matrix(), m.p_SC)  # point offsets in W (3 x n)
        n = m.n_points
        E = self._E[side]
        (x0, x1, *_), (y0, y1, *_), (z0, z1, *_) = P.tolist()
        dx, dy, dz = x1 - x0, y1 - y0, z1 - z0  # scalar math: cheaper than tiny arrays
        nd = math.sqrt(dx * dx + dy * dy + dz * dz)
        dx, dy, dz = dx / nd, dy / nd, dz / nd
        e1x, e1y, e1z = dy, -dx, 0.0  # d x z
        n1 = math.sqrt(e1x * e1x + e1y * e1y)
        if n1 < 1e-6:
            e1x, e1y, e1z = 0.0, dz, -dy  # d x x
            n1 = math.sqrt(e1y * e1y + e1z * e1z)
        e1x, e1y, e1z = e1x / n1, e1y / n1, e1z / n1
        E[3, 3:6] = (e1x, e1y, e1z)
        E[4, 3:6] = (dy * e1z - dz * e1y, dz * e1x - dx * e1z, dx * e1y - dy * e1x)
        if self.n_kin_foot > 5:
            k = 2 if n < 4 else 3  # a point off the first line
            nrm = np.cross(np.array([dx, dy, dz]), P[:, k] - P[:, 0])
            E[5, 3 * k:3 * k + 3] = nrm / np.linalg.norm(nrm)
        return E


class SwingSoleObjective(Objective):
    """Swing-sole pose along ``plan.swing``: position rows in W; orientation rows in the
    desired sole frame with no weight on roll about its x axis (the legs have no ankle roll)."""

    def __init__(self, pos: ObjectiveGains, rot: ObjectiveGains):
        self.pos, self.rot = pos, rot
        self.w_rot = np.array([0.0, rot.weight, rot.weight])
        self.w_pos = np.full(3, pos.weight)

    def add_to(self, cost, model, plan) -> None:
        s = plan.swing
        if s is None:
            return
        X, V, J, jdv = model.sole_spatial(s.side)
        # a + kp (p_d - p) + kd (v_d - v) - Jdot v per component (scalar math: 3-vectors).
        kp, kd = self.pos.kp, self.pos.kd
        w0, w1, w2, v0, v1, v2 = V.tolist()
        x = X.translation().tolist()
        j = jdv.tolist()
        a_lin = np.array([a + kp * (p - xi) + kd * (vd - vi) - ji for a, p, xi, vd, vi, ji in
                          zip(s.a.tolist(), s.p.tolist(), x, s.v.tolist(), (v0, v1, v2), j[3:])])
        e = rotation_error(s.R, X.rotation().matrix()).tolist()
        kp, kd = self.rot.kp, self.rot.kd
        a_ang = np.array([kp * ei + kd * (wd - wi) - ji for ei, wd, wi, ji in
                          zip(e, s.w.tolist(), (w0, w1, w2), j[:3])])
        RT = s.R.T
        cost.add(np.dot(RT, J[:3]), np.dot(RT, a_ang), self.w_rot)
        cost.add(J[3:], a_lin, self.w_pos)


class HandPositionObjective(Objective):
    """Hand sphere centre p_WH of one hand (0 left, 1 right) towards ``plan.hands[side].p``
    (no rows when that is None)."""

    def __init__(self, side: int, gains: ObjectiveGains):
        self.side = side
        self.gains = gains
        self.w = np.full(3, gains.weight)

    def add_to(self, cost, model, plan) -> None:
        p_d = plan.hands[self.side].p
        if p_d is None:
            return
        p, v, J, jdv = model.hand_point(self.side)
        a = self.gains.kp * (p_d - p) - self.gains.kd * v - jdv
        cost.add(J, a, self.w)


class HandUprightObjective(Objective):
    """Keeps the axis ``plan.hands[side].up`` of the hand frame H vertical in W: rows about the
    world x and y axes only (the heading about z stays free), error (R_WH u) x z_W [rad]. The
    arm has 4 joints, so with the position objective this trades tilt against position through the
    weights (no rows when ``up`` is None). The error is saturated at ``max_error``, so that a
    hand coming from a far tilt is turned without a burst of arm torque."""

    def __init__(self, side: int, gains: ObjectiveGains, max_error: float = 0.2):
        self.side = side
        self.gains = gains
        if not 0.0 < max_error <= 1.0:  # a sine; at 1 nothing is saturated
            raise ValueError(f"arms.hand_upright_max_error must be in (0, 1] (the sine of a "
                             f"tilt), got {max_error!r}")
        self.max_error = max_error  # [rad] (sine of the tilt) the error is saturated at
        self.w = np.full(2, gains.weight)

    def add_to(self, cost, model, plan) -> None:
        h = plan.hands[self.side]
        if h.up is None or h.p is None:
            return
        R, w, J, jdv = model.hand_rotation(self.side)
        e = np.cross(R @ h.up, [0.0, 0.0, 1.0])
        n = float(np.linalg.norm(e))
        if n > self.max_error:  # a large tilt (say from a carry pose) is corrected gently
            e *= self.max_error / n
        a = self.gains.kp * e - self.gains.kd * w - jdv
        cost.add(J[:2], a[:2], self.w)


class PostureObjective(Objective):
    """Joint posture: every joint towards ``q_nominal`` (18, original order: arms, legs), with
    per-joint kp [1/s^2], kd [1/s] and weights."""

    def __init__(self, model: WholeBodyModel, q_nominal: np.ndarray, kp: np.ndarray,
                 kd: np.ndarray, weight: np.ndarray):
        self.q_idx = model.maps.q_joints
        self.v_idx = model.maps.v_joints
        self.q_nominal = np.asarray(q_nominal, dtype=float)
        self.kp, self.kd, self.w = (np.asarray(x, dtype=float) for x in (kp, kd, weight))

    def add_to(self, cost, model, plan) -> None:
        a = (self.kp * (self.q_nominal - model.q[self.q_idx])
             - self.kd * model.v[self.v_idx])
        cost.add_selection(self.v_idx, a, self.w)

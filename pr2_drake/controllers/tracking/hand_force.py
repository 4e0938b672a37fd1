"""Estimate of the force on a held hand, from the arm's joint-torque residual.

While a hand holds something, the arm's rows of the equations of motion read
M_a vdot + h_a = tau_a + J_Ha^T f_H (the soles' contact forces do not act on arm joints), with
tau_a the applied arm torques, J_Ha the hand point's translational Jacobian restricted to that
arm's joints and f_H the force on the hand [N, W]. Each control tick the residual
r = M_a vdot + h_a - tau_a (vdot by finite differences of the measured velocities) gives f_H in
the least-squares sense (4 arm joints, 3 force components), low-pass filtered. The whole-body QP
then centres the hand's contact-force variable on this estimate, and the standing CoM target
leans against it, so balance plans for the reaction at the hand.
"""

from __future__ import annotations

import numpy as np

from pr2_drake.controllers.model import WholeBodyModel


class HandForceEstimator:
    """Per-hand force estimate f_H [N, W] (see the module docstring).

    Args:
        model: the controller's robot model (at the measured state when ``update`` is called).
        time_constant: [s] of the first-order low-pass filter.
    """

    def __init__(self, model: WholeBodyModel, time_constant: float = 0.05):
        self.model = model
        self.time_constant = float(time_constant)
        n = len(model.v_arms) // 2
        self.arm_v = [model.v_arms[:n], model.v_arms[n:]]
        self.arm_slices = [slice(0, n), slice(n, 2 * n)]
        self._damping = 1e-6 * np.eye(3)  # of the least-squares solve
        self.reset()

    def reset(self) -> None:
        self.f = np.zeros((2, 3))
        self._v_prev: np.ndarray | None = None
        self._t_prev = 0.0

    def update(self, t: float, tau_arms: np.ndarray | None,
               attached: tuple[bool, bool]) -> np.ndarray:
        """New estimates (2, 3) [N] from the applied arm torques ``tau_arms`` (8, original
        order) over the last control period; zero for a hand that holds nothing."""
        m = self.model
        v = m.v
        dt = t - self._t_prev
        ok = (self._v_prev is not None and dt > 1e-6 and tau_arms is not None
              and np.isfinite(tau_arms).all())
        if ok and (attached[0] or attached[1]):
            vdot = (v - self._v_prev) / dt
            M, h = m.mass_matrix(), m.bias()
            alpha = min(dt / self.time_constant, 1.0)
            for side in (0, 1):
                if not attached[side]:
                    continue
                idx = self.arm_v[side]
                r = M[idx] @ vdot + h[idx] - tau_arms[self.arm_slices[side]]
                J = m.hand_point(side)[2][:, idx]  # 3 x 4
                f = np.linalg.solve(J @ J.T + self._damping, J @ r)
                self.f[side] += alpha * (f - self.f[side])
        for side in (0, 1):
            if not attached[side]:
                self.f[side] = 0.0
        self._v_prev = v.copy()
        self._t_prev = t
        return self.f

"""Centroidal-dynamics MPC of a jump's launch: sole point forces over a short horizon.

State x = [c, cdot, L] (9): CoM position p_WCcm [m] and velocity [m/s] in W, and the centroidal
angular momentum L about the CoM [kg m^2/s] (W). Decisions: the force f_ki [N] (3, W) at every
sole contact point i of knot k, held constant over the knot (dt). Dynamics (exact for piecewise
constant forces, linearised only in the moment arms, taken from a nominal CoM path):

    m cddot = sum_i f_ki + m g,      Ldot = sum_i (p_i - c_nom,k) x f_ki.

Eliminating the states (condensing) leaves a dense QP over the forces alone:

    min  sum_k  |c_k - c_ref,k|^2_Wc + |cdot_k - v_ref,k|^2_Wv + |L_k|^2_WL      (k = 1..N)
         + |c_K - c_to|^2_Wtp + |cdot_K - v_to|^2_Wtv  (K = the take-off knot)  + reg |f|^2
    s.t. |f_x|, |f_y| <= mu f_z (pyramid),   0 <= f_z <= f_z,max,ki,

with f_z,max = 0 for the knots after take-off (the contact schedule) and, before it, the largest
normal force the leg can hold within its peak joint torques (:func:`leg_force_limits`). The knots
before take-off split the time to take-off evenly, so that one ends exactly at take-off. The
problem (144 forces, 192 pyramid rows, bounds) is allocated once; each solve rebuilds the small
condensed matrices for the current knots (numpy, no symbolic program), updates the bounds in
place and calls DAQP: about 2 ms median per solve here (bench jumping), run every 4 ms tick of
the launch only.
"""

# (No ``from __future__ import annotations``: yaml_load_typed reads MpcParams' field types.)
from dataclasses import dataclass

import numpy as np

try:
    import daqp
except ImportError:  # pragma: no cover - depends on the environment
    daqp = None

_DAQP_OK = (1, 2)


@dataclass
class MpcParams:
    """Horizon, weights and limits of the launch MPC (params/controllers/jumping.yaml ``mpc``)."""

    horizon: int = 12  # knots
    dt: float = 0.025  # [s] per knot
    mu: float = 0.6  # friction pyramid (ground 1.0; QP 0.7)
    w_pos: float = 100.0  # running CoM height error [1/m^2]
    w_pos_xy: float = 1000.0  # running CoM horizontal position error [1/m^2]
    w_vel: float = 1.0  # running CoM velocity error [s^2/m^2]
    w_L: float = 1.0  # angular momentum [1/(kg m^2/s)^2]
    w_takeoff_pos: float = 3000.0  # CoM position at take-off
    w_takeoff_vel: float = 1000.0  # CoM velocity at take-off
    reg: float = 1e-6  # force regularisation [1/N^2]
    torque_margin: float = 0.8  # share of the peak joint torques the force limits may use
    fz_cap: float = 1000.0  # [N] per contact point, whatever the leg geometry


@dataclass
class MpcSolution:
    """One solve: forces (N, n_points, 3) [N, W], predicted states (N+1, 9), status."""

    ok: bool
    forces: np.ndarray
    states: np.ndarray
    iterations: int
    solve_time: float = 0.0  # [s] wall time of the QP solve


def leg_force_limits(J_points: np.ndarray, leg_cols: np.ndarray, effort: np.ndarray,
                     margin: float, cap: float) -> float:
    """Largest normal (z) force [N] one sole point can take with the leg's joint torques within
    ``margin`` x ``effort`` (static, tau = J^T f), the point's share being half the leg's.

    Args:
        J_points: (3, nv) translational Jacobian of the point (W).
        leg_cols: velocity indices of that leg's joints; effort: their peak torques [Nm].
    """
    jz = np.abs(J_points[2, leg_cols])
    with np.errstate(divide="ignore"):
        lim = np.where(jz > 1e-6, margin * effort / np.maximum(jz, 1e-12), np.inf)
    return float(min(cap, 0.5 * lim.min()))


class CentroidalMpc:
    """The condensed launch QP (see the module docstring), built once.

    Args:
        params: horizon, weights and limits.
        mass: robot mass [kg]; gravity: g [m/s^2] (positive).
        n_points: sole contact points (both soles).
    """

    def __init__(self, params: MpcParams, mass: float, gravity: float, n_points: int):
        self.p = params
        self.m = float(mass)
        self.g = np.array([0.0, 0.0, -float(gravity)])
        N, P = params.horizon, n_points
        self.N, self.P = N, P
        self.n = 3 * P * N
        # Sum of the point forces of a knot: S (3 x 3P).
        self._S = np.tile(np.eye(3), (1, P))
        self._lower = np.tril(np.ones((N, N)), -1)  # [k, j] = 1 for j < k (knot k ends later)
        self._Mblk = np.zeros((3 * N, self.n))
        # Where the entries of skew(r) of every (knot j, point i) block of _Mblk go: rows
        # 3 j + a, columns 3 (P j + i) + b, for the six off-diagonal (a, b).
        blk = np.arange(N * P)
        rows0, cols0 = 3 * (blk // P), 3 * blk
        self._skew_at = {(a, b): (rows0 + a, cols0 + b)
                         for a, b in ((0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1))}
        # Pyramid rows: for each force (fx, fy, fz): +-fx - mu fz <= 0, +-fy - mu fz <= 0.
        mu = params.mu
        n_f = P * N
        self.A = np.zeros((4 * n_f, self.n))
        for i in range(n_f):
            c = 3 * i
            self.A[4 * i + 0, [c, c + 2]] = [1.0, -mu]
            self.A[4 * i + 1, [c, c + 2]] = [-1.0, -mu]
            self.A[4 * i + 2, [c + 1, c + 2]] = [1.0, -mu]
            self.A[4 * i + 3, [c + 1, c + 2]] = [-1.0, -mu]
        self.bu = np.zeros(self.n + 4 * n_f)
        self.bl = np.zeros(self.n + 4 * n_f)
        self.bl[self.n:] = -1e30
        self.last: MpcSolution | None = None

    def knots(self, t_to: float) -> tuple[np.ndarray, int]:
        """Knot durations h (N,) [s] and the take-off knot K (1..N; N+1 = beyond the horizon)
        for a take-off ``t_to`` [s] from now: the knots before take-off split it evenly (so a
        knot ends exactly at take-off), the others last ``dt``."""
        N, dt = self.N, self.p.dt
        h = np.full(N, dt)
        if t_to > N * dt - 1e-9:
            return h, N + 1
        K = int(max(1, np.ceil(max(t_to, 0.0) / dt - 1e-6)))
        h[:K] = max(t_to, 1e-3) / K
        return h, K

    def _condense(self, h: np.ndarray) -> None:
        """Bc, Bv (3N x 3PN) and the gravity terms for knot durations h: with s_j, e_j the
        start and end of knot j, v_k = v0 + sum_{j<k} h_j a_j and
        c_k = c0 + e_k v0 + sum_{j<k} h_j (e_k - s_j - h_j / 2) a_j, a_j = F_j / m + g."""
        e = np.cumsum(h)
        s0 = e - h
        low = self._lower + np.eye(self.N)  # knot k's end state includes knot k itself
        Cv = low * h[None, :]
        Cc = low * (h[None, :] * (e[:, None] - s0[None, :] - 0.5 * h[None, :]))
        self.Bv = np.kron(Cv / self.m, self._S)
        self.Bc = np.kron(Cc / self.m, self._S)
        self.gv = np.kron(Cv.sum(axis=1), self.g)
        self.gc = np.kron(Cc.sum(axis=1), self.g)
        self.t_end = e
        self.t_start = s0
        self._tri = np.kron(low * h[None, :], np.eye(3))

    def solve(self, c0: np.ndarray, v0: np.ndarray, L0: np.ndarray, t_to: float,
              c_ref: np.ndarray, v_ref: np.ndarray, c_to: np.ndarray, v_to: np.ndarray,
              points: np.ndarray, fz_max: np.ndarray) -> MpcSolution:
        """Forces of the horizon from the measured state.

        Args:
            c0, v0, L0: CoM position, velocity, centroidal angular momentum now (W).
            t_to: time to take-off [s] (forces are zero on the knots after it).
            c_ref, v_ref: (N, 3) running references at the knot ends (:meth:`knots`) (W).
            c_to, v_to: CoM position and velocity wanted at take-off (W).
            points: (P, 3) contact point positions p_WC [m] (held over the horizon).
            fz_max: (P,) normal-force limit per point [N] while in contact.
        """
        import time

        p, N, P = self.p, self.N, self.P
        h, K = self.knots(t_to)
        self._condense(h)
        wc = np.tile([p.w_pos_xy, p.w_pos_xy, p.w_pos], N)
        wv = np.full(3 * N, p.w_vel)
        if K <= N:
            wc[3 * (K - 1):3 * K] += p.w_takeoff_pos
            wv[3 * (K - 1):3 * K] += p.w_takeoff_vel
        H0 = (self.Bc.T * wc) @ self.Bc + (self.Bv.T * wv) @ self.Bv
        # Moment blocks with the arms from the nominal CoM path (references at knot starts).
        Mb = self._Mblk
        c_nom = np.vstack([c0[None, :], c_ref[:-1]])  # at the knot starts
        # skew(points[i] - c_nom[j]) into every block at once (the same values as block by
        # block: a subtraction and negations; the diagonal stays zero).
        rx, ry, rz = (np.asarray(points)[None, :, :] - c_nom[:, None, :]).reshape(-1, 3).T
        at = self._skew_at
        Mb[at[0, 1]], Mb[at[0, 2]] = -rz, ry
        Mb[at[1, 0]], Mb[at[1, 2]] = rz, -rx
        Mb[at[2, 0]], Mb[at[2, 1]] = -ry, rx
        BL = self._tri @ Mb
        H = H0 + p.w_L * (BL.T @ BL)
        H[np.diag_indices_from(H)] += p.reg
        # Affine parts.
        ac = np.tile(c0, N) + np.repeat(self.t_end, 3) * np.tile(v0, N) + self.gc
        av = np.tile(v0, N) + self.gv
        aL = np.tile(L0, N)
        cr = c_ref.reshape(-1).copy()
        vr = v_ref.reshape(-1).copy()
        if K <= N:
            # The take-off terms: blend of the running reference and the take-off target.
            r = slice(3 * (K - 1), 3 * K)
            w1 = wc[r] - p.w_takeoff_pos
            cr[r] = (w1 * cr[r] + p.w_takeoff_pos * c_to) / wc[r]
            w1 = p.w_vel
            vr[r] = (w1 * vr[r] + p.w_takeoff_vel * v_to) / wv[r]
        f = (self.Bc.T @ (wc * (ac - cr)) + self.Bv.T @ (wv * (av - vr))
             + p.w_L * (BL.T @ aL))
        # Bounds: fz in [0, fz_max] on knots that start before take-off; fx, fy by the pyramid.
        n = self.n
        bu, bl = self.bu, self.bl
        contact = np.arange(N) < K  # knots before take-off
        fzm = np.outer(contact, np.minimum(fz_max, p.fz_cap)).reshape(-1)
        bu[0:n:3] = p.mu * fzm
        bu[1:n:3] = p.mu * fzm
        bu[2:n:3] = fzm
        bl[:n] = -bu[:n]
        bl[2:n:3] = 0.0
        t0 = time.perf_counter()
        ok, iters = False, 0
        x = None
        if daqp is not None:
            x, _, flag, info = daqp.solve(H, f, self.A, bu, bl, np.zeros(len(bu), dtype=np.intc),
                                          iter_limit=2000)
            ok = flag in _DAQP_OK and np.all(np.isfinite(x))
            iters = int(info["iterations"])
        if not ok:  # fall back: the clipped unconstrained solution (never raises)
            x = np.clip(np.linalg.solve(H, -f), bl[:n], bu[:n])
        solve_time = time.perf_counter() - t0
        states = np.zeros((N + 1, 9))
        states[0] = np.r_[c0, v0, L0]
        states[1:, 0:3] = (ac + self.Bc @ x).reshape(N, 3)
        states[1:, 3:6] = (av + self.Bv @ x).reshape(N, 3)
        states[1:, 6:9] = (aL + BL @ x).reshape(N, 3)
        sol = MpcSolution(bool(ok), x.reshape(N, P, 3), states, iters, solve_time)
        self.last = sol
        return sol

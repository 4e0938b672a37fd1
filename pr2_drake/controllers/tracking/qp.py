"""Whole-body QP: task-space inverse dynamics with contact forces, solved by OSQP.

Decision variables x = [vdot (nv), f (3 per contact point, in W, scaled by 1/force_scale)].
The dynamics rows come first: base, legs, arms; or, without ``arm_limits``, arms, base, legs
(the arm rows are then a prefix of A that DAQP is not given).
Constraints (rows of one preallocated sparse matrix, coefficients updated every tick):

- floating-base rows of M vdot + h = J_c^T f (the base is not actuated);
- leg torques tau = M_l vdot + h_l - J_{c,l}^T f within +- the peak torque;
- arm rows: either the arms are position-controlled elsewhere, so their torques are known (the
  spring-damper of the posture command) and enter as equalities, or (``arm_effort`` given) the
  QP drives them too and their torques are bounded by their peak torques like the legs'
  (``arm_limits``; without it the arm rows leave the DAQP problem: the arm torques are whatever
  the solution needs, clamped afterwards);
- hand contact forces (``n_hands`` > 0): 3 more variables per hand (W, scaled like the foot
  forces) that enter the dynamics through the hand point's Jacobian, each within box bounds
  (zero while the hand holds nothing), with a regularisation towards a prior force;
- per contact point: friction pyramid |f_x|, |f_y| <= mu f_z and f_min <= f_z <= f_max
  (f_max = 0 for points not in contact);
- kinematic rows J_k vdot = a_k (e.g. stance soles do not accelerate), each row switched off
  by infinite bounds when not needed.

The cost is the weighted least-squares sum of the tracking objectives' errors, given as H = sum J^T W J and
g = -sum J^T W a over vdot, plus small regularisation. The problem is built once; each tick
updates P, q, A, l, u in place.

Solvers (``QpParams.solver``): "daqp" (default) is a dual active-set method for small dense QPs;
it solves this ~48-variable problem exactly in about 0.05 ms (OSQP needs 100-400 ADMM
iterations, 0.5-1.5 ms, because the force distribution is ill-conditioned). When DAQP is not
installed or reports no solution (infeasible, cycling, iteration limit), the tick falls back to
the OSQP workspace (fixed sparsity, coefficients updated in place, warm-started), then to the last
torques. "osqp" uses OSQP only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import osqp
import scipy.sparse as sp

try:  # optional fast path (see module docstring)
    import daqp
except ImportError:  # pragma: no cover - depends on the environment
    daqp = None

from pr2_drake.controllers.walking_params import QpParams

_INF = 1e30  # OSQP_INFTY (DAQP_INF is the same)
_DAQP_EQUALITY = 5  # DAQP constraint sense: active + immutable
_DAQP_OK = (1, 2)  # optimal, soft optimal


@dataclass
class QpResult:
    """Solution of one tick. ``ok`` is False when the solver failed (then tau is a fallback)."""

    ok: bool
    tau: np.ndarray  # leg torques [Nm], original leg order
    vdot: np.ndarray
    forces: np.ndarray  # contact forces [N], (n_points, 3) in W
    status: str
    iterations: int
    tau_arms: np.ndarray | None = None  # arm torques [Nm] (arms driven by the QP), else None
    hand_forces: np.ndarray | None = None  # (n_hands, 3) [N] in W, forces on the hands


def _csc_pattern(mask: np.ndarray):
    """CSC index arrays of a boolean mask, and the (row, col) of each stored entry in order."""
    cols, rows = np.nonzero(mask.T)
    indptr = np.concatenate([[0], np.cumsum(np.bincount(cols, minlength=mask.shape[1]))])
    return rows, cols, indptr


class WholeBodyQp:
    """The preallocated OSQP problem (see module docstring).

    Args:
        nv: number of generalized velocities.
        base_v: indices of the 6 floating-base velocities.
        leg_v: indices of the leg joint velocities (the actuated rows we output).
        effort: peak torque per leg joint [Nm].
        n_points: number of contact points (all feet).
        params: QP settings.
        arm_v: indices of the arm joint velocities.
        n_kin: number of kinematic rows (J_kin vdot = a_kin, switchable).
        box_v: velocity indices with acceleration bounds (joint limits).
        arm_effort: peak torque per arm joint [Nm]: the QP drives the arms (else their torques
            are given to :meth:`solve`).
        n_hands: hand contact points whose forces are variables (0: none).
        arm_limits: with ``arm_effort``: the arm torque limits are rows of the QP. False: DAQP
            solves without the arm rows (arms that never reach their peak torques, e.g. held
            to a pose only: a smaller problem), and the arm torques are clamped afterwards.
    """

    def __init__(self, nv: int, base_v: np.ndarray, leg_v: np.ndarray, effort: np.ndarray,
                 n_points: int, params: QpParams, arm_v: np.ndarray | None = None,
                 n_kin: int = 0, box_v: np.ndarray | None = None,
                 arm_effort: np.ndarray | None = None, n_hands: int = 0,
                 arm_limits: bool = True):
        self.p = params
        self.nv = nv
        self.nf_feet = 3 * n_points
        self.n_hands = n_hands
        self.nf = 3 * n_points + 3 * n_hands
        self.n = nv + self.nf
        self.arm_effort = None if arm_effort is None else np.asarray(arm_effort, dtype=float)
        self.base_v = np.asarray(base_v)
        self.leg_v = np.asarray(leg_v)
        self.arm_v = np.zeros(0, dtype=int) if arm_v is None else np.asarray(arm_v)
        self.effort = np.asarray(effort, dtype=float)
        self.n_points = n_points
        n_dyn = len(self.base_v) + len(self.leg_v) + len(self.arm_v)
        self.n_dyn = n_dyn
        self.n_kin = n_kin
        self.box_v = np.zeros(0, dtype=int) if box_v is None else np.asarray(box_v)
        self.m = n_dyn + 5 * n_points + n_kin + len(self.box_v) + 3 * n_hands
        s = params.force_scale
        self.scale = s

        # Constant part of A: friction pyramid and normal-force rows.
        self.A = np.zeros((self.m, self.n))
        mu = params.mu
        for k in range(n_points):
            r = n_dyn + 5 * k
            c = nv + 3 * k
            self.A[r + 0, [c, c + 2]] = [1.0, -mu]
            self.A[r + 1, [c, c + 2]] = [-1.0, -mu]
            self.A[r + 2, [c + 1, c + 2]] = [1.0, -mu]
            self.A[r + 3, [c + 1, c + 2]] = [-1.0, -mu]
            self.A[r + 4, c + 2] = 1.0
        a_mask = self.A != 0
        a_mask[:n_dyn, :] = True
        self.kin_rows = np.arange(n_dyn + 5 * n_points, n_dyn + 5 * n_points + n_kin)
        a_mask[self.kin_rows, :nv] = True
        nh = 3 * n_hands
        self.box_rows = np.arange(self.m - nh - len(self.box_v), self.m - nh)
        self.A[self.box_rows, self.box_v] = 1.0
        a_mask[self.box_rows, self.box_v] = True
        self.hand_rows = np.arange(self.m - nh, self.m)
        self.hand_cols = np.arange(nv + self.nf_feet, self.n)
        self.A[self.hand_rows, self.hand_cols] = 1.0
        a_mask[self.hand_rows, self.hand_cols] = True
        self._a_rows, self._a_cols, a_indptr = _csc_pattern(a_mask)

        p_mask = np.zeros((self.n, self.n), dtype=bool)
        p_mask[:nv, :nv] = np.triu(np.ones((nv, nv), dtype=bool))
        p_mask[np.arange(nv, self.n), np.arange(nv, self.n)] = True
        self._p_rows, self._p_cols, p_indptr = _csc_pattern(p_mask)

        self.P = np.zeros((self.n, self.n))
        # Force regularisation (forces in units of force_scale): spreads the load evenly.
        self.P[np.arange(nv, self.n), np.arange(nv, self.n)] = params.force_reg
        hand = np.arange(nv + self.nf_feet, self.n)
        self.P[hand, hand] = params.hand_force_reg
        self.l = np.full(self.m, -np.inf)
        self.u = np.full(self.m, np.inf)
        self.l[:n_dyn] = -1.0
        self.u[:n_dyn] = 1.0
        for k in range(n_points):  # pyramid rows: a_i . f <= 0
            self.u[n_dyn + 5 * k:n_dyn + 5 * k + 4] = 0.0
        self.q = np.zeros(self.n)
        self._p_indptr = p_indptr
        self._a_indptr = a_indptr
        self._setup()
        self._diag = np.arange(nv)
        # Friction/normal rows are always in A0 with value 1 until the first update.
        self._first = True
        self.last_tau = np.zeros(len(self.leg_v))
        self.failures = 0
        solver = getattr(params, "solver", "daqp")
        if solver not in ("daqp", "osqp"):
            raise ValueError(f"qp.solver must be 'daqp' or 'osqp', got {solver!r}")
        self.use_daqp = solver == "daqp" and daqp is not None
        # Per-tick index helpers (contiguous row blocks as slices).
        na, nb = len(self.arm_v), len(self.base_v)
        # The first row DAQP sees: the arm rows are a prefix it skips without arm_limits.
        self._row0 = na if (self.arm_effort is not None and not arm_limits) else 0
        if self._row0:
            order, self._arm_rows = [self.arm_v, self.base_v, self.leg_v], slice(0, na)
            self._leg_rows = slice(na + nb, n_dyn)
        else:
            order, self._arm_rows = [self.base_v, self.leg_v, self.arm_v], slice(n_dyn - na, n_dyn)
            self._leg_rows = slice(nb, n_dyn - na)
        self._dyn_v = np.concatenate(order).astype(int)
        self._fz_rows = n_dyn + 5 * np.arange(n_points) + 4
        self._kin_slice = slice(n_dyn + 5 * n_points, n_dyn + 5 * n_points + n_kin)
        self._box_slice = slice(self.m - nh - len(self.box_v), self.m - nh)
        self._hand_slice = slice(self.m - nh, self.m)
        self.last_tau_arms = np.zeros(len(self.arm_v))
        self._P_vdiag = self.P.reshape(-1)[:nv * self.n:self.n + 1]  # view: diag of the vdot block
        assert np.shares_memory(self._P_vdiag, self.P)
        self._init_tick_buffers()

    def _init_tick_buffers(self) -> None:
        """Per-tick buffers: the bounds given to the solver, the offsets of the dynamics rows'
        bounds from -h (0 base; -+ the peak torques; the applied arm torques), the DAQP sense
        by (l == u), and the contact columns per contact pattern."""
        self._l = np.empty(self.m)
        self._u = np.empty(self.m)
        self._dyn_lo = np.zeros(self.n_dyn)
        self._dyn_hi = np.zeros(self.n_dyn)
        legs, arms = self._leg_rows, self._arm_rows
        self._dyn_lo[legs] = -self.effort
        self._dyn_hi[legs] = self.effort
        if self.arm_effort is not None:
            self._dyn_lo[arms] = -self.arm_effort
            self._dyn_hi[arms] = self.arm_effort
        self._sense_of = np.array([0, _DAQP_EQUALITY], dtype=np.intc)
        self._contact_cache: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}

    def _setup(self) -> None:
        """(Re)create the OSQP workspace with the fixed sparsity pattern."""
        params = self.p
        P0 = sp.csc_matrix((np.ones(len(self._p_rows)), self._p_rows, self._p_indptr),
                           shape=(self.n, self.n))
        A0 = sp.csc_matrix((np.ones(len(self._a_rows)), self._a_rows, self._a_indptr),
                           shape=(self.m, self.n))
        self.solver = osqp.OSQP()
        settings = dict(verbose=False, warm_starting=True, polishing=params.polish,
                        max_iter=params.max_iter, eps_abs=params.eps_abs,
                        eps_rel=params.eps_rel, adaptive_rho=True, check_termination=10)
        if params.time_limit > 0:
            settings["time_limit"] = params.time_limit
        # Placeholder data (values are overwritten by every solve; only the pattern matters).
        self.solver.setup(P0, np.zeros(self.n), A0, -np.ones(self.m), np.ones(self.m),
                          **settings)
        # The wrapper's update()/solve() add ~0.1 ms of bookkeeping per tick (derivative cache,
        # info copies): talk to the extension object directly.
        self._ext = self.solver._solver
        self._first = True

    def solve(self, M: np.ndarray, h: np.ndarray, Jc: np.ndarray, H: np.ndarray,
              g: np.ndarray, fz_max: np.ndarray,
              tau_arms: np.ndarray | None = None,
              fz_min: np.ndarray | None = None, J_kin: np.ndarray | None = None,
              a_kin: np.ndarray | None = None,
              box: tuple[np.ndarray, np.ndarray] | None = None,
              J_hands: np.ndarray | None = None,
              hand_bounds: tuple[np.ndarray, np.ndarray] | None = None,
              hand_prior: np.ndarray | None = None) -> QpResult:
        """Solve one tick.

        Args:
            M, h: mass matrix and bias (C v - tau_g) of the plant.
            Jc: (3 n_points x nv) contact point Jacobians, translational, in W.
            H, g: cost over vdot (0.5 vdot^T H vdot + g^T vdot), from the objectives.
            fz_max: (n_points,) upper bound on each normal force [N]; 0 = not in contact.
            tau_arms: the arm joint torques applied by the arm controller [Nm].
            fz_min: (n_points,) lower bound on the normal force of points in contact [N]
                (default: params.fz_min).
            J_kin, a_kin: (n_kin x nv) and (n_kin,) kinematic rows J_kin vdot = a_kin; rows
                with a NaN in a_kin are inactive.
            box: (lower, upper) bounds on vdot[box_v] (e.g. from joint limits).
            J_hands: (3 n_hands x nv) translational Jacobians of the hand points, in W.
            hand_bounds: (lower, upper) (3 n_hands,) bounds on the hand forces [N, W]; zero
                for a hand that holds nothing (default: all zero).
            hand_prior: (3 n_hands,) force [N] the regularisation pulls the hand forces to.
        """
        p, nv = self.p, self.nv
        in_contact = fz_max > 0
        hd = self._set_dynamics(M, h, Jc, self._contact_columns(in_contact), tau_arms, J_hands,
                                hand_bounds, hand_prior)
        self._set_force_bounds(fz_max, fz_min, in_contact)
        self._set_kinematic_rows(J_kin, a_kin, box)
        P = self.P
        P[:nv, :nv] = H
        self._P_vdiag += p.vdot_reg
        self.q[:nv] = g
        l = np.maximum(self.l, -_INF, out=self._l)
        u = np.minimum(self.u, _INF, out=self._u)
        # One reduction per array: a NaN or inf anywhere makes the sum non-finite (the bounds
        # are clamped to +-1e30 above, so only NaN can remain there).
        if not (math.isfinite(P.sum() + self.A.sum() + self.q.sum())
                and not math.isnan(l.sum() + u.sum())):
            return self._fallback("non-finite problem data", 0)
        if self.use_daqp:
            result = self._solve_daqp(l, u, hd, in_contact)
            if result is not None:
                return result
            # No solution from the active-set method: let OSQP try (approximate, capped).
        return self._solve_osqp(l, u, h, hd, in_contact)

    def _contact_columns(self, in_contact: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per force variable: the contact flag (0/1), and minus the force scale where in
        contact (0 elsewhere); cached per contact pattern."""
        key = in_contact.tobytes()
        cols = self._contact_cache.get(key)
        if cols is None:
            flag = np.repeat(in_contact, 3)
            cols = self._contact_cache[key] = (flag, -(self.scale * flag))
        return cols

    def _set_dynamics(self, M, h, Jc, columns, tau_arms, J_hands, hand_bounds,
                      hand_prior) -> np.ndarray:
        """The floating-base, leg and arm rows of M vdot + h = Jc^T f (+ J_hands^T f_H) and
        their bounds (the legs' and QP-driven arms' peak torques, or the applied arm torques);
        the hand-force columns, bounds and prior (``columns``: :meth:`_contact_columns`).
        Returns h of those rows."""
        nv, s, nd = self.nv, self.scale, self.n_dyn
        A = self.A
        # Forces of points not in contact leave the dynamics rows (their columns are zeroed,
        # the sparsity pattern stays), so solver tolerance cannot create phantom support.
        # Dynamics rows (see __init__) of [M, -Jc^T] in one gather each; -(x s) = x (-s).
        dyn = self._dyn_v
        A[:nd, :nv] = M[dyn]
        np.multiply(Jc.T[dyn], columns[1], out=A[:nd, nv:nv + self.nf_feet])
        l, u = self.l, self.u
        if self.n_hands:
            hc = slice(nv + self.nf_feet, self.n)
            hr = self._hand_slice
            if J_hands is None or hand_bounds is None:
                A[:nd, hc] = 0.0
                l[hr] = 0.0
                u[hr] = 0.0
            else:
                A[:nd, hc] = J_hands.T[dyn] * (-s)
                l[hr] = hand_bounds[0] / s
                u[hr] = hand_bounds[1] / s
            prior = np.zeros(3 * self.n_hands) if hand_prior is None else hand_prior
            self.q[hc] = -(self.p.hand_force_reg / s) * prior
        # Bounds -h + offsets: (-h) - e = (-h) + (-e), and -h + 0 = -h.
        hd = h[dyn]
        lo, hi = self._dyn_lo, self._dyn_hi
        if self.arm_effort is None and len(self.arm_v):
            arms = 0.0 if tau_arms is None else tau_arms
            lo[self._arm_rows] = arms
            hi[self._arm_rows] = arms
        neg = -hd
        np.add(neg, lo, out=l[:nd])
        np.add(neg, hi, out=u[:nd])
        return hd

    def _set_force_bounds(self, fz_max, fz_min, in_contact) -> None:
        """Normal-force bounds of the sole contact points (zero off contact)."""
        s, zr = self.scale, self._fz_rows
        lo = self.p.fz_min if fz_min is None else np.minimum(fz_min, 0.5 * fz_max)
        self.l[zr] = np.where(in_contact, lo / s, 0.0)
        self.u[zr] = fz_max / s

    def _set_kinematic_rows(self, J_kin, a_kin, box) -> None:
        """The kinematic rows J_kin vdot = a_kin (NaN: inactive) and the box on vdot."""
        l, u = self.l, self.u
        if self.n_kin:
            kr = self._kin_slice
            if J_kin is None or a_kin is None:
                self.A[kr, :self.nv] = 0.0
                l[kr] = -np.inf
                u[kr] = np.inf
            else:
                self.A[kr, :self.nv] = J_kin
                active = np.isfinite(a_kin)
                l[kr] = np.where(active, a_kin, -np.inf)
                u[kr] = np.where(active, a_kin, np.inf)
        if len(self.box_v):
            br = self._box_slice
            if box is None:
                l[br] = -np.inf
                u[br] = np.inf
            else:
                l[br], u[br] = box

    def _solve_daqp(self, l, u, hd, in_contact) -> QpResult | None:
        """DAQP's solution, or None when it has none."""
        r0 = self._row0
        if r0:  # without the arm rows (contiguous views)
            l, u = l[r0:], u[r0:]
        sense = self._sense_of.take((l == u).view(np.uint8))
        # (DAQP copies its inputs: the constant parts of P and A stay intact.) Typically
        # 2-10 active-set iterations; the cap bounds a pathological tick.
        x, _, exitflag, info = daqp.solve(self.P, self.q, self.A[r0:], u, l, sense,
                                          iter_limit=1000)
        if exitflag in _DAQP_OK and math.isfinite(x.sum()):
            return self._result(x, hd, in_contact, "daqp", int(info["iterations"]))
        return None

    def _solve_osqp(self, l, u, h, hd, in_contact) -> QpResult:
        """OSQP's solution (warm-started; approximate, capped), or the fallback."""
        s, nv = self.scale, self.nv
        ext = self._ext
        Px = self.P[self._p_rows, self._p_cols]
        Ax = self.A[self._a_rows, self._a_cols]
        try:
            ext.update_data_vec(q=self.q, l=l, u=u)
            ext.update_data_mat(P_x=Px, P_i=None, A_x=Ax, A_i=None)
            if self._first:
                f0 = np.zeros(self.nf)
                f0[2:self.nf_feet:3] = np.where(in_contact,
                                    h[self.base_v][5] / max(1, in_contact.sum()) / s, 0.0)
                ext.warm_start(np.concatenate([np.zeros(nv), f0]), None)
                self._first = False
            ext.solve()
            info = ext.info
            status = str(info.status)
            status_val = info.status_val
            iterations = int(info.iter)
            x = np.array(ext.solution.x)
            ok = (status_val in (1, 2) or (status_val in (7, 8) and info.prim_res < 1e-1))
        except Exception as err:  # noqa: BLE001 - any solver error means: fall back
            self._setup()
            return self._fallback(f"solver error: {err}", 0)
        if ok and x is not None and np.all(np.isfinite(x)):
            return self._result(x, hd, in_contact, status, iterations)
        return self._fallback(status, iterations)

    def _result(self, x: np.ndarray, hd: np.ndarray, in_contact: np.ndarray, status: str,
                iterations: int) -> QpResult:
        """Leg torques tau = M_l vdot + h_l - J_{c,l}^T f of a solution x (clamped), from the
        leg rows of A (= [M_l, -J_{c,l}^T], with the columns of points not in contact zero);
        the arm torques likewise when the QP drives the arms."""
        nv = self.nv
        legs = self._leg_rows
        tau = np.dot(self.A[legs], x) + hd[legs]
        np.minimum(tau, self.effort, out=tau)
        np.maximum(tau, -self.effort, out=tau)
        tau_arms = None
        if self.arm_effort is not None:
            arms = self._arm_rows
            tau_arms = np.dot(self.A[arms], x) + hd[arms]
            np.minimum(tau_arms, self.arm_effort, out=tau_arms)
            np.maximum(tau_arms, -self.arm_effort, out=tau_arms)
            self.last_tau_arms = tau_arms
        vdot = x[:nv]
        nff = self.nf_feet
        f = x[nv:nv + nff] * self._contact_columns(in_contact)[0]
        hand = x[nv + nff:] * self.scale if self.n_hands else None
        self.last_tau = tau
        self.failures = 0
        return QpResult(True, tau, vdot, (f * self.scale).reshape(-1, 3), status, iterations,
                        tau_arms, None if hand is None else hand.reshape(-1, 3))

    def _fallback(self, status: str, iterations: int) -> QpResult:
        """The last torques, decayed: a failed tick never raises."""
        self.failures += 1
        self.last_tau = self.last_tau * self.p.fail_decay
        tau_arms = None
        if self.arm_effort is not None:
            self.last_tau_arms = self.last_tau_arms * self.p.fail_decay
            tau_arms = self.last_tau_arms.copy()
        self._first = True
        return QpResult(False, self.last_tau.copy(), np.zeros(self.nv),
                        np.zeros((self.n_points, 3)), status, iterations, tau_arms,
                        np.zeros((self.n_hands, 3)) if self.n_hands else None)

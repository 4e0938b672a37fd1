"""The jump planner: phases of one jump and their plans for the whole-body QP.

A jump request (:class:`JumpRequest`: take-off time, horizontal velocity, apex height) becomes
a timeline ending at the requested take-off time:

- CROUCH: the CoM goes down to ``crouch_height`` along a quintic (PD + feed-forward), over the
  middle of the soles (leaning along the launch's horizontal velocity, so that the launch
  force passes through the CoM: ``launch_cop_back``), then holds;
- LAUNCH: the centroidal MPC (:class:`pr2_drake.controllers.planning.centroidal_mpc.CentroidalMpc`)
  chooses the sole forces that reach the take-off velocity v_to at ``takeoff_height`` at the
  take-off time; the QP tracks the CoM acceleration of its first knot. v_to: vertical
  sqrt(2 g apex) (apex = CoM rise above take-off), horizontal as requested;
- FLIGHT: no contacts; each sole follows the CoM (ballistic) plus an offset that tucks by
  ``tuck_height`` and then reaches the landing posture (``landing_height`` below the CoM, the
  soles ``stance_width`` apart and ahead of the CoM by v/omega, the capture point) at the
  predicted landing time;
- LANDING: a sole counts as landed when a contact point is within ``touchdown_height`` of the
  ground; its normal-force bound ramps up; an impedance on the CoM towards ``absorb_height``
  over the soles absorbs the impact (the QP keeps the torques within their limits);
- RECOVERY: the CoM rises to the walking controller's standing height, then the walking
  planner takes over from the measured state (no jolt).

Frames: W world (z up), heading frame H (yaw of the pelvis at the request). Units: m, s, N.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np

from pr2_drake.controllers.frames import rot_z
from pr2_drake.controllers.planning.centroidal_mpc import CentroidalMpc, MpcSolution, leg_force_limits
from pr2_drake.controllers.jump_params import JumpParams
from pr2_drake.controllers.plan import JumpPlan
from pr2_drake.controllers.plan import SwingReference
from pr2_drake.controllers.planning.swing import _quintic
from pr2_drake.controllers.model import WholeBodyModel
from pr2_drake.ports import N_ARMS


class JumpPhase(enum.IntEnum):
    IDLE = 0  # walking / standing (the gait planner's plan)
    CROUCH = 1
    LAUNCH = 2
    FLIGHT = 3
    LANDING = 4
    RECOVERY = 5


@dataclass
class JumpRequest:
    """A checked jump request: take-off time [s] (simulation time), horizontal CoM velocity at
    take-off (vx, vy) [m/s] in the heading frame, apex [m] = CoM rise above take-off."""

    t_takeoff: float
    velocity: np.ndarray
    apex: float

    def vertical_speed(self, gravity: float) -> float:
        """Take-off vertical CoM speed [m/s] of a ballistic rise of ``apex``."""
        return math.sqrt(2.0 * gravity * self.apex)


def _blend(a: np.ndarray, b: np.ndarray, t: float, t0: float, T: float):
    """Quintic from a (t0) to b (t0 + T): value, rate, second rate."""
    tau = (t - t0) / T if T > 1e-9 else 1.0
    s, ds, dds = _quintic(tau)
    d = b - a
    if T <= 1e-9 or tau >= 1.0:
        return b.copy(), np.zeros(3), np.zeros(3)
    return a + s * d, ds / T * d, dds / (T * T) * d


class JumpPlanner:
    """Phases and plans of a jump (see the module docstring).

    Args:
        params: jump parameters (params/controllers/jumping.yaml).
        model: the controller's robot model (at the measured state each tick).
        stand_height: CoM height above the soles when standing [m] (walking parameters).
        fz_max: per contact point normal-force bound of the QP in contact [N].
    """

    def __init__(self, params: JumpParams, model: WholeBodyModel, stand_height: float,
                 fz_max: float):
        self.params = params
        self.model = model
        self.g = model.gravity
        self.stand_height = stand_height
        self.fz_max = fz_max
        self.mpc = CentroidalMpc(params.mpc, model.mass, model.gravity, 2 * model.n_points)
        self.plan = JumpPlan()
        n = model.n_points
        self._leg_cols = [model.v_legs[5 * s:5 * s + 5] for s in (0, 1)]
        self._leg_effort = [model.effort[N_ARMS + 5 * s:N_ARMS + 5 * s + 5] for s in (0, 1)]
        self._pts = np.zeros((2 * n, 3))
        self._fz = np.zeros(2 * n)
        self.reset()

    def reset(self) -> None:
        self.phase = JumpPhase.IDLE
        self.request: JumpRequest | None = None
        self.t_phase = 0.0
        self.mpc_solution: MpcSolution | None = None
        self.mpc_times: list[float] = []
        self.t_touchdown = [math.inf, math.inf]
        self.t_land = math.inf
        self.log: dict = {}

    # ---- timeline ------------------------------------------------------------------------------
    def launch_duration(self, req: JumpRequest) -> float:
        """Launch time [s]: constant acceleration from rest over the crouch-to-take-off rise."""
        p = self.params
        vz = max(req.vertical_speed(self.g), 0.3)
        return 2.0 * (p.takeoff_height - p.crouch_height) / vz

    def lead_time(self, req: JumpRequest) -> float:
        """Time from the start of the crouch to take-off [s]."""
        p = self.params
        return p.crouch_time + p.crouch_hold + self.launch_duration(req)

    @property
    def active(self) -> bool:
        return self.phase != JumpPhase.IDLE

    def start(self, t: float, req: JumpRequest, heading: float) -> None:
        """Begin the crouch now for a take-off at ``req.t_takeoff`` (the caller made sure it is
        at least :meth:`lead_time` away) from a standing robot."""
        m, p = self.model, self.params
        self.request = req
        self.heading = heading
        R = rot_z(heading)
        self.v_to_xy = (R[:2, :2] @ req.velocity).copy()
        soles = [m.sole_pose(s).translation() for s in (0, 1)]
        self.ground = float(0.5 * (soles[0][2] + soles[1][2]))
        mid = 0.5 * (soles[0] + soles[1])
        T_L = self.launch_duration(req)
        self.T_launch = T_L
        self.t_launch = req.t_takeoff - T_L
        self.t_crouch = t
        self.crouch_T = max(1e-3, self.t_launch - p.crouch_hold - t)
        com, comd, _, _ = m.com()
        self.c_start = com.copy()
        # A horizontal launch pushes along a line through the CoM (no pitching): the CoM
        # leans ahead of the centre of pressure by its height times a_xy / (g + a_z) (mean
        # launch accelerations), with the centre of pressure ``launch_cop_back`` behind the
        # soles' middle, against the motion.
        a_xy = self.v_to_xy / T_L
        ratio = a_xy / (self.g + req.vertical_speed(self.g) / T_L)
        speed = float(np.linalg.norm(self.v_to_xy))
        back = self.v_to_xy / speed * p.launch_cop_back if speed > 1e-9 else np.zeros(2)
        lean = p.crouch_height * ratio - back
        n_lean = float(np.linalg.norm(lean))
        if n_lean > p.launch_lean_max:  # the crouched CoM stays over the soles
            lean *= p.launch_lean_max / n_lean
        self.c_crouch = np.array([mid[0] + lean[0], mid[1] + lean[1],
                                  self.ground + p.crouch_height])
        self.phase = JumpPhase.CROUCH
        self.t_phase = t
        self.mpc_times = []
        self.t_touchdown = [math.inf, math.inf]
        self.log = dict(t_request_start=t, t_takeoff_planned=req.t_takeoff, ground=self.ground,
                        v_to=np.r_[self.v_to_xy, req.vertical_speed(self.g)])

    # ---- the tick ------------------------------------------------------------------------------
    def update(self, t: float) -> JumpPlan:
        """The plan of this tick (the model holds the measured state); may end the jump (then
        ``phase`` is IDLE and the caller hands back to the walking planner)."""
        m, p = self.model, self.params
        com, comd, _, _ = m.com()
        plan = self.plan
        req = self.request
        ph = self.phase
        if ph == JumpPhase.CROUCH and t >= self.t_launch - 1e-9:
            self._go(JumpPhase.LAUNCH, t)
            self.c_launch = com.copy()  # (the launch starts where the crouch ended)
            vz = req.vertical_speed(self.g)
            self.v_to = np.r_[self.v_to_xy, vz]
            self.c_to = self.c_launch + 0.5 * self.v_to * self.T_launch
            self.c_to[2] = self.ground + p.takeoff_height
            self.T_launch = max(1e-3, req.t_takeoff - t)
        if self.phase == JumpPhase.LAUNCH and t >= req.t_takeoff - 1e-9:
            self._go(JumpPhase.FLIGHT, t)
            self.log.update(t_takeoff=t, com_takeoff=com.copy(), comd_takeoff=comd.copy())
            self.r_to = [m.sole_pose(s).translation() - com for s in (0, 1)]
        if self.phase == JumpPhase.FLIGHT:
            self.t_land = t + self._time_to_landing(com, comd)
            landed = self._touchdowns(t)
            if any(landed):
                self._go(JumpPhase.LANDING, t)
                self.log.update(t_touchdown=t, com_touchdown=com.copy(),
                                comd_touchdown=comd.copy())
                self.p_land = [m.sole_pose(s).translation().copy() for s in (0, 1)]
        if self.phase == JumpPhase.LANDING:
            self._touchdowns(t)
            settled = (t - self.t_phase >= p.landing_min_time and
                       float(np.linalg.norm(comd)) < p.landing_settle_speed
                       and all(np.isfinite(self.t_touchdown)))
            if settled or t - self.t_phase >= 3.0 * p.landing_min_time + 0.5:
                self._go(JumpPhase.RECOVERY, t)
                self.c_rec0 = com.copy()
        if self.phase == JumpPhase.RECOVERY and t - self.t_phase >= p.recovery_time:
            self._go(JumpPhase.IDLE, t)
            self.log["t_end"] = t
            return plan
        self._fill(t, com, comd)
        return plan

    def _go(self, phase: JumpPhase, t: float) -> None:
        self.phase = phase
        self.t_phase = t

    def _time_to_landing(self, com: np.ndarray, comd: np.ndarray) -> float:
        """Ballistic time [s] until the CoM is ``landing_height`` above the ground."""
        h = com[2] - (self.ground + self.params.landing_height)
        vz = comd[2]
        disc = vz * vz + 2.0 * self.g * h
        return max(0.0, (vz + math.sqrt(max(disc, 0.0))) / self.g)

    def _touchdowns(self, t: float) -> list[bool]:
        """Sides whose sole has touched down (after half the predicted flight)."""
        m, p = self.model, self.params
        t0 = self.log.get("t_takeoff", t)
        halfway = t >= t0 + 0.5 * (self.t_land - t0) or self.phase == JumpPhase.LANDING
        out = []
        for s in (0, 1):
            if math.isfinite(self.t_touchdown[s]):
                out.append(True)
                continue
            low = float(m.contact_heights(s).min()) - self.ground < p.touchdown_height
            if halfway and (low or t > self.t_land + 0.1):
                self.t_touchdown[s] = t
            out.append(math.isfinite(self.t_touchdown[s]))
        return out

    # ---- plans ---------------------------------------------------------------------------------
    def _fill(self, t: float, com: np.ndarray, comd: np.ndarray) -> None:
        m, p, plan = self.model, self.params, self.plan
        g_W = np.array([0.0, 0.0, -self.g])
        ph = self.phase
        plan.pelvis_R = rot_z(self.heading)
        plan.com_frame_yaw = None
        plan.swing = None
        plan.ground_z = self.ground
        # The walking status port's gait phase stays STAND (0) during a jump; the jump's phase
        # is on the jump controller's ``jump_status`` port.
        plan.phase = 0
        plan.stance = -1
        plan.soles = [None, None]
        plan.pelvis_scale = 1.0
        L = m.plant.CalcSpatialMomentumInWorldAboutPoint(m.context, com).rotational()
        self.L = L
        plan.L_rate = -p.angular_momentum.kd * L
        plan.L_weight = 0.0 if ph == JumpPhase.FLIGHT else p.angular_momentum.weight
        for c in plan.contacts:
            c.active, c.fz_min, c.fz_max, c.hard = True, 2.0, self.fz_max, True
        w = p.com.weight
        if ph == JumpPhase.CROUCH:
            c_d, v_d, a_d = _blend(self.c_start, self.c_crouch, t, self.t_crouch, self.crouch_T)
            plan.com_acc = a_d + p.com.kp * (c_d - com) + p.com.kd * (v_d - comd)
            plan.com_weight = np.full(3, w)
        elif ph == JumpPhase.LAUNCH:
            plan.com_acc = self._launch_acc(t, com, comd)
            plan.com_weight = np.full(3, p.com_launch_weight)
            # The moment of the MPC's first-knot forces about the CoM: Ldot as planned.
            f0 = self.mpc_solution.forces[0]
            plan.L_rate = np.cross(self._pts - com, f0).sum(axis=0)
            plan.L_weight = p.launch_angular_momentum_weight
            plan.pelvis_scale = p.launch_pelvis_scale
        elif ph == JumpPhase.FLIGHT:
            plan.com_acc = g_W
            plan.com_weight = np.zeros(3)
            for s in (0, 1):
                plan.contacts[s].active = False
                plan.contacts[s].fz_max = 0.0
                plan.contacts[s].hard = False
                plan.soles[s] = self._flight_sole(s, t, com, comd)
        elif ph == JumpPhase.LANDING:
            mid = 0.5 * (self.p_land[0] + self.p_land[1])
            c_d = np.array([mid[0], mid[1], self.ground + p.absorb_height])
            L, Lxy = p.landing, p.landing_xy
            kp = np.array([Lxy.kp, Lxy.kp, L.kp])
            kd = np.array([Lxy.kd, Lxy.kd, L.kd])
            plan.com_acc = kp * (c_d - com) - kd * comd
            plan.com_weight = np.array([Lxy.weight, Lxy.weight, L.weight])
            for s in (0, 1):
                c = plan.contacts[s]
                if not math.isfinite(self.t_touchdown[s]):
                    c.active, c.fz_max, c.hard = False, 0.0, False
                    plan.soles[s] = self._reach_down(s)
                    continue
                ramp = (t - self.t_touchdown[s]) / max(p.load_ramp, 1e-6)
                c.fz_max = self.fz_max * float(np.clip(ramp, 0.1, 1.0))
                c.hard = ramp >= 1.0
        elif ph == JumpPhase.RECOVERY:
            soles = [m.sole_pose(s).translation() for s in (0, 1)]
            mid = 0.5 * (soles[0] + soles[1])
            c_end = np.array([mid[0], mid[1], self.ground + self.stand_height])
            c_d, v_d, a_d = _blend(self.c_rec0, c_end, t, self.t_phase, p.recovery_time)
            plan.com_acc = a_d + p.com.kp * (c_d - com) + p.com.kd * (v_d - comd)
            plan.com_weight = np.full(3, w)

    def _launch_acc(self, t: float, com: np.ndarray, comd: np.ndarray) -> np.ndarray:
        """Solve the MPC from the measured state; the CoM acceleration of its first knot."""
        m, mpc = self.model, self.mpc
        N = mpc.N
        T_L = self.T_launch
        a = self.v_to / T_L
        h, _ = mpc.knots(self.request.t_takeoff - t)
        taus = (t - self.t_launch) + np.cumsum(h)
        c_ref = np.zeros((N, 3))
        v_ref = np.zeros((N, 3))
        g_W = np.array([0.0, 0.0, -self.g])
        for k, tau in enumerate(taus):
            if tau <= T_L:
                tau = max(tau, 0.0)
                c_ref[k] = self.c_launch + 0.5 * a * tau * tau
                v_ref[k] = a * tau
            else:
                s = tau - T_L
                c_ref[k] = self.c_to + self.v_to * s + 0.5 * g_W * s * s
                v_ref[k] = self.v_to + g_W * s
        n = m.n_points
        for s in (0, 1):
            J, _ = m.contact_points(s)
            X = m.sole_pose(s)
            P = (X.rotation().matrix() @ m.p_SC).T + X.translation()
            for i in range(n):
                k = s * n + i
                self._pts[k] = P[i]
                self._fz[k] = leg_force_limits(J[3 * i:3 * i + 3], self._leg_cols[s],
                                               self._leg_effort[s], mpc.p.torque_margin,
                                               mpc.p.fz_cap)
        sol = mpc.solve(com, comd, self.L, self.request.t_takeoff - t, c_ref, v_ref, self.c_to,
                        self.v_to, self._pts, self._fz)
        self.mpc_solution = sol
        self.mpc_times.append(sol.solve_time)
        return sol.forces[0].sum(axis=0) / m.mass + g_W

    def _flight_sole(self, side: int, t: float, com: np.ndarray, comd: np.ndarray):
        """Sole reference in flight: the CoM plus an offset (tuck, then landing posture)."""
        p = self.params
        t0 = self.log["t_takeoff"]
        r0 = self.r_to[side]
        r_tuck = r0 + np.array([0.0, 0.0, p.tuck_height])
        R = rot_z(self.heading)
        omega = math.sqrt(self.g / p.landing_height)
        sign = 1.0 if side == 0 else -1.0
        r_land = R @ np.array([0.0, sign * 0.5 * p.stance_width, 0.0])
        r_land[:2] += comd[:2] / omega  # the capture point of the (ballistic) CoM
        r_land[2] = -p.landing_height
        t_ext = max(t0 + p.tuck_time, self.t_land - p.extend_time)
        if t < t0 + p.tuck_time:
            r, rd, rdd = _blend(r0, r_tuck, t, t0, p.tuck_time)
        else:
            r, rd, rdd = _blend(r_tuck, r_land, t, t_ext, max(self.t_land - t_ext, 1e-3))
        g_W = np.array([0.0, 0.0, -self.g])
        return SwingReference(side, com + r, comd + rd, g_W + rdd, rot_z(self.heading),
                              np.zeros(3))

    def _reach_down(self, side: int) -> SwingReference:
        """A sole not yet landed while the other has: straight down to the ground."""
        p = self.p_land[side].copy()
        p[2] = self.ground - 0.01
        return SwingReference(side, p, np.array([0.0, 0.0, -0.3]), np.zeros(3),
                              rot_z(self.heading), np.zeros(3))

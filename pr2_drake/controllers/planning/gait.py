"""The walking planner: gait state machine, footsteps, CoM/DCM control and swing -> a plan.

``GaitPlanner.update(t, command, model)`` runs once per control tick and fills a
:class:`pr2_drake.controllers.plan.WholeBodyPlan`: which soles are in contact, the CoM
acceleration (a feedback law of the measured CoM), the CoM height, the pelvis orientation and
the swing-sole reference. It knows nothing about the QP or the objectives that track the plan.

KUAVO's legs have no ankle roll and its soles touch the ground along a line (heel and toe
spheres, see models/kuavo/params.yaml): in single support the ZMP is on the sole's centre line,
so sideways the robot is a linear inverted pendulum steered only by where it puts its feet.
The design follows from that:

- Footsteps come from a footstep planner (:class:`pr2_drake.controllers.planning.footsteps.
  FootstepPlanner`, passed in; by default from the velocity command), then move with the
  divergent component of motion (DCM, capture point) xi = c + cdot / omega: the swing sole goes
  where the DCM will be at the next ZMP switch, minus the periodic offset the next planned steps
  need. Where and when it lands are chosen together (:mod:`step_adjust`): a step that cannot
  reach far enough lands sooner, and after a push towards the stance leg the swing sole lands
  close beside it (never crossing) so that the next step can catch the DCM.
- Double support moves the DCM to where the next step needs it (DCM tracking with the ZMP
  inside the support region), and lasts longer while that still helps.
- Single support keeps the ZMP on the stance sole; along the sole an ankle term tracks the DCM.
- Standing holds the CoM over the middle of the soles (PD); stopping uses pydrake's
  ``ZmpPlanner`` (LIPM + ZMP preview) to bring the CoM there after the last step.
- Swing heights and landing pitch come from a terrain model (:class:`FlatTerrain`,
  :class:`RoughTerrain`, :class:`SlopeTerrain`, passed in).

Gait phases: STAND, START (weight shift before the first step), SINGLE, DOUBLE, STOP (settle
after the last step, then STAND). Frames: W world (z up), soles S (``l_sole``, ``r_sole``),
heading frame H (yaw only). Gravity comes from the model's plant.
"""

from __future__ import annotations

import enum
import math

import numpy as np

from pr2_drake.controllers.frames import rot2, rot_y, rot_z, wrap, yaw_of
from pr2_drake.controllers.planning.com_bias import ComBiasEstimator
from pr2_drake.controllers.planning.com_plan import ComPlanner, zmp_point
from pr2_drake.controllers.planning.liftoff import LiftoffRule, shift_duration
from pr2_drake.controllers.planning.speed_correction import SpeedCorrection
from pr2_drake.controllers.planning.footsteps import (
    FootstepPlanner,
    VelocityFootstepPlanner,
    clamp_to_stance,
    square_stance,
)
from pr2_drake.controllers.planning.terrain import FlatTerrain
from pr2_drake.controllers.plan import SwingReference, WholeBodyPlan
from pr2_drake.controllers.planning.step_adjust import choose_step, periodic_dcm_offset
from pr2_drake.controllers.planning.swing import SwingTrajectory
from pr2_drake.controllers.walking_params import WalkingParams
from pr2_drake.controllers.model import WholeBodyModel


class Phase(enum.IntEnum):
    STAND = 0
    START = 1
    SINGLE = 2
    DOUBLE = 3
    STOP = 4


class GaitPlanner:
    """Gait state machine and walking references (see the module docstring).

    Args:
        params: walking parameters (gait timing, limits, gains of the standing CoM law).
        model: the controller's robot model (updated to the measured state before each tick).
        footsteps: footstep planner (default: from the velocity command).
        terrain: terrain model for swing heights and landing pitch (default: flat).
    """

    def __init__(self, params: WalkingParams, model: WholeBodyModel,
                 footsteps: FootstepPlanner | None = None, terrain: FlatTerrain | None = None):
        self.params = params
        self.model = model
        self.gravity = model.gravity
        self.footsteps = footsteps or VelocityFootstepPlanner(params.gait,
                                                              params.limits.start_threshold)
        self.terrain = terrain or FlatTerrain()
        self.com_planner = ComPlanner(params.gait, self.gravity)
        self.swing_z_error = 0.0  # [m] swing sole height above its desired height (last tick)
        self.plan = WholeBodyPlan()
        self.speed_correction = SpeedCorrection(params.gait)
        self.liftoff = LiftoffRule(params.gait)
        self.com_bias = ComBiasEstimator(params.gait)
        self.reset()

    # ---- state -------------------------------------------------------------------------------
    def reset(self) -> None:
        """Forget the gait state: the next tick starts standing from the measured pose."""
        self.phase = Phase.STAND
        self.t_phase = 0.0
        self.phase_duration = 0.0
        self.stance = -1  # stance side in SINGLE / new stance in DOUBLE / first stance in START
        self.footholds: list[np.ndarray | None] = [None, None]
        self.swing: SwingTrajectory | None = None
        self.swing_plan: np.ndarray | None = None  # planned target before DCM adjustment
        self._step_over = False  # the swing is a high one the footstep planner asked for
        self.heading: float | None = None
        self.t_last: float | None = None
        self.t_touchdown = -np.inf
        self.command = np.zeros(3)
        self.z_target: float | None = None
        self.speed_correction.reset(-np.inf, np.zeros(2))
        self.com_bias.reset()
        self.com_offset = None
        self._pelvis_yaw: float | None = None
        self._pelvis_R = None

    def clip_command(self, command: np.ndarray) -> np.ndarray:
        """Clip a checked command (vx, vy, yaw_rate) to the configured limits."""
        return np.array(self._clip(*command.tolist()))

    def _clip(self, vx: float, vy: float, wz: float) -> list[float]:
        """:meth:`clip_command` on three floats."""
        lim = self.params.limits
        return [min(max(vx, lim.vx_min), lim.vx_max),
                min(max(vy, -lim.vy_max), lim.vy_max),
                min(max(wz, -lim.yaw_rate_max), lim.yaw_rate_max)]

    # ---- the tick ----------------------------------------------------------------------------
    def update(self, t: float, command: np.ndarray, com, comd,
               com_offset: np.ndarray | None = None) -> WholeBodyPlan:
        """One tick at time t [s] for a checked velocity command (vx, vy, yaw_rate) in the
        heading frame [m/s, m/s, rad/s] and the measured CoM p_WCcm, v_WCcm (the model holds
        the measured state). ``com_offset`` (xy, W) [m] shifts the standing CoM target (e.g.
        leaning against a force at a hand). Returns the plan (the same object every tick)."""
        self.com_offset = com_offset
        p = self.params
        m = self.model
        if self.t_last is not None and t < self.t_last - 1e-9:
            self.reset()  # the simulation restarted
        dt = 0.0 if self.t_last is None else t - self.t_last
        self.t_last = t
        # The command used is rate-limited (acceleration limits), except that stopping the
        # walking (all zero) is immediate.
        lim = p.limits
        # (Scalar math: three numbers per tick are cheaper than numpy calls.)
        tc = self._clip(*command.tolist())
        old = self.command.tolist()
        if tc[0] != 0.0 or tc[1] != 0.0 or tc[2] != 0.0:
            rates = (lim.accel_max * dt, lim.accel_max * dt, lim.yaw_accel_max * dt)
            cmd = [c + min(max(x - c, -r), r) for x, c, r in zip(tc, old, rates)]
        else:
            cmd = tc
        self.command = np.array(cmd)
        self.speed_correction.observe_command(t, tc, cmd)

        R_WB = m.base_rotation()
        pelvis_yaw = yaw_of(R_WB)
        com = self.com_bias.shifted(com, pelvis_yaw)  # the real CoM, as far as it is known
        if self.heading is None:
            self.heading = pelvis_yaw
        # Integrate the yaw-rate command, but stop while the heading leads the pelvis by more
        # than heading_lead_max (no wind-up when the body cannot follow).
        new_heading = self.heading + cmd[2] * dt
        lead_new = abs(wrap(new_heading - pelvis_yaw))
        if lead_new <= p.limits.heading_lead_max or lead_new < abs(wrap(self.heading - pelvis_yaw)):
            self.heading = new_heading
        if self.footholds[0] is None:
            self.footholds = [self._sole_pose4(0), self._sole_pose4(1)]
        self.footsteps.observe(self.footholds)

        self._step_state_machine(t, dt, com, comd)
        return self._fill_plan(t, dt, com, comd)

    def _step_state_machine(self, t: float, dt: float, com, comd) -> None:
        g = self.params.gait
        m = self.model
        if self.phase == Phase.STAND or self.phase == Phase.STOP:
            if self._moving():
                self.footholds = [self._sole_pose4(0), self._sole_pose4(1)]
                self.footsteps.observe(self.footholds)
                self._start_walking(t, com, comd)
            elif self.phase == Phase.STOP and t - self.t_phase >= self.phase_duration:
                self.phase = Phase.STAND
                self.t_phase = t
        elif self.phase in (Phase.START, Phase.DOUBLE):
            if self.phase == Phase.DOUBLE and g.stance_slip_replan > 0.0:
                self._stance_moved(t, com, comd)
            # Lift off when the DCM is where the next step needs it (or after a time-out).
            elapsed = t - self.t_phase
            omega = math.sqrt(self.gravity / g.com_height)
            d = com[:2] + comd[:2] / omega - self.start_dcm[2]
            self.liftoff.update(math.sqrt(d.dot(d)), dt)
            if (elapsed >= min(self.phase_duration, g.min_double_support) - 1e-9
                    and self.liftoff.running_away()):
                self._lift_off(t, com, comd)  # the DCM runs away: step now
            elif (elapsed >= self.phase_duration - 1e-9
                  and self.liftoff.done(elapsed, self.phase_duration)):
                self._lift_off(t, com, comd)
        if self.phase == Phase.SINGLE:
            swing_side = 1 - self.stance
            self.swing.advance(t)
            progress = self.swing.progress
            # Swing sole height above the stance sole, or above its target on known terrain.
            z_ref = (self.swing.target[2] if self.terrain.known_heights
                     else self.footholds[self.stance][2])
            heights = m.contact_heights(swing_side) - z_ref
            blocked = (g.blocked_touchdown_error > 0 and progress >= g.early_touchdown_phase
                       and self.swing_z_error > g.blocked_touchdown_error
                       and (heights.min() + z_ref - self.swing.target[2]
                            < g.early_touchdown_max_height))
            if ((progress >= g.touchdown_min_phase and heights.min() < g.touchdown_height)
                    or blocked or t >= self.swing.landing_time + g.late_touchdown):
                self._touchdown(t, com, comd)
            elif progress < g.dcm_freeze_phase and self.footsteps.adjustable:
                self._adjust_swing_target(t, com, comd)

    def _fill_plan(self, t: float, dt: float, com, comd) -> WholeBodyPlan:
        """References and contacts of this tick into ``self.plan``."""
        p = self.params
        g = p.gait
        plan = self.plan
        # CoM.
        ground = self._ground_z()
        if self.phase == Phase.STAND:
            # (Scalar math per component, in the order the 2-vector expressions had.)
            (ax, ay), (bx, by) = (zmp_point(f, g).tolist() for f in self.footholds)
            tx, ty = 0.5 * (ax + bx), 0.5 * (ay + by)
            if self.com_offset is not None:
                lx, ly = self._clip_lean(self.com_offset).tolist()
                tx, ty = tx + lx, ty + ly
            kp, kd = p.com_xy.kp, p.com_xy.kd
            a_xy = np.array([kp * (tx - float(com[0])) - kd * float(comd[0]),
                             kp * (ty - float(com[1])) - kd * float(comd[1])])
        elif self.phase in (Phase.START, Phase.DOUBLE):
            a_xy = self._shift_comdd(t, com, comd)
        elif self.phase == Phase.SINGLE:
            a_xy = self._single_comdd(t, dt, com, comd)
        else:
            a_xy = self.com_planner.comdd(t, com[:2], comd[:2])
        # CoM height: standing height at rest, the (lower) LIPM height when walking; the target
        # moves at a bounded rate, starting from the measured height.
        z_ref = ground
        if g.com_height_over_stance and self.phase == Phase.SINGLE:
            z_ref = float(self.footholds[self.stance][2])  # over the stance sole (stairs)
        if g.com_height_step_down:
            z_ref = min(z_ref, self._next_foothold_z())  # step-down: lower the CoM first
        z_goal = z_ref + (g.stand_com_height if self.phase == Phase.STAND else g.com_height)
        if g.com_reach > 0.0:
            z_goal = min(z_goal, self._reach_cap(com, g.com_reach))
        if self.z_target is None:
            self.z_target = float(com[2])
        dz = g.height_rate * dt
        self.z_target += min(max(z_goal - self.z_target, -dz), dz)
        plan.com_acc_xy = a_xy
        plan.com_z = self.z_target
        # On a line foot the lateral CoM acceleration is set by gravity: in single support the
        # CoM objective is expressed in the stance sole's frame (small lateral weight).
        plan.com_frame_yaw = (self.footholds[self.stance][3] if self.phase == Phase.SINGLE
                              else None)
        # Pelvis orientation (level, yaw along the heading).
        if self.heading != self._pelvis_yaw:  # (the same matrix while the heading holds)
            self._pelvis_yaw = self.heading
            self._pelvis_R = rot_z(self.heading)
        plan.pelvis_R = self._pelvis_R
        # Contacts.
        fmax = p.qp.fz_max_factor * self.model.mass * self.gravity
        for side in (0, 1):
            c = plan.contacts[side]
            c.active = not (self.phase == Phase.SINGLE and side == 1 - self.stance)
            c.fz_min = p.qp.fz_min
            if not c.active:
                c.fz_max = 0.0
                c.hard = False
                continue
            bound = fmax
            if self.phase == Phase.DOUBLE and side == self.stance:
                ramp = (t - self.t_touchdown) / max(p.qp.load_ramp, 1e-6)
                bound = fmax * min(max(ramp, 0.1), 1.0)
            c.fz_max = bound
            if self.phase == Phase.SINGLE:
                c.fz_min = p.qp.fz_min_single
            c.hard = bool(p.qp.hard_contacts and bound >= fmax)
        plan.swing = self._swing_reference(t) if self.phase == Phase.SINGLE else None
        plan.phase = int(self.phase)
        plan.stance = self.stance if self.phase == Phase.SINGLE else -1
        plan.ground_z = ground
        return plan

    def _swing_reference(self, t: float) -> SwingReference:
        """The swing sole's desired motion now (and the blocked-descent measure)."""
        side = 1 - self.stance
        X, V, _, _ = self.model.sole_spatial(side)
        p_d, v_d, a_d, yaw_d, yawd_d = self.swing.evaluate(t)
        pos = X.translation()
        pitch_d, pitchd_d = self.swing.pitch()
        R_d = rot_z(yaw_d)
        if pitch_d != 0.0:  # landing pitched on known terrain
            R_d = np.dot(R_d, rot_y(pitch_d))
        w_d = np.array([-math.sin(yaw_d) * pitchd_d, math.cos(yaw_d) * pitchd_d, yawd_d])
        # Blocked descent (early contact): above the curve and no longer moving down.
        self.swing_z_error = (float(pos[2] - p_d[2])
                              if v_d[2] <= 0.0 and V[5] > 0.5 * min(v_d[2], -0.1) else 0.0)
        return SwingReference(side, p_d, v_d, a_d, R_d, w_d)

    # ---- helpers -----------------------------------------------------------------------------
    def _clip_lean(self, offset: np.ndarray) -> np.ndarray:
        """A standing CoM offset (xy, W) [m] clipped, in the heading frame, to the soles' contact
        points less ``gait.lean_margin``: forward and back to the rearmost heel and foremost toe
        point (a split stance leans further), sideways to the soles' lateral distance. A CoM leaned further would be behind the heel (or outside a
        sole) when the force it leans against stops, and could not be brought back."""
        g = self.params.gait
        R = rot2(self.heading)
        d = R.T @ offset
        a, b = self.footholds
        ab = R.T @ (a[:2] - b[:2])  # left sole from the right one, heading frame
        half_x = max(float(np.max(self.model.p_SC[0])) + 0.5 * abs(float(ab[0]))
                     - g.lean_margin, 0.0)
        half_y = max(0.5 * abs(float(ab[1])) - g.lean_margin, 0.0)
        return R @ np.array([min(max(d[0], -half_x), half_x), min(max(d[1], -half_y), half_y)])

    def _sole_pose4(self, side: int) -> np.ndarray:
        X = self.model.sole_pose(side)
        p = X.translation()
        return np.array([p[0], p[1], p[2], yaw_of(X.rotation().matrix())])

    def _moving(self) -> bool:
        return self.footsteps.keep_walking(self.command, self.footholds)

    def _reach_cap(self, com, reach: float) -> float:
        """Highest CoM height [m] within ``reach`` of every supporting sole, counting the
        CoM's offset from it along the heading (``com_reach``)."""
        c, s = np.cos(self.heading), np.sin(self.heading)
        cap = np.inf
        for side in (0, 1):
            f = self.footholds[side]
            if f is None or (self.phase == Phase.SINGLE and side != self.stance):
                continue
            dx = min(abs(c * (com[0] - f[0]) + s * (com[1] - f[1])), 0.9 * reach)
            cap = min(cap, float(f[2]) + float(np.sqrt(reach * reach - dx * dx)))
        return cap

    def _next_foothold_z(self) -> float:
        """Height [m] of where the swing sole lands next: the swing target in single support,
        the planned next foothold in the double support before it (inf: none)."""
        if self.phase == Phase.SINGLE and self.swing is not None:
            return float(self.swing.target[2])
        if self.phase in (Phase.START, Phase.DOUBLE) and self.swing_plan is not None:
            return float(self.swing_plan[2])
        return np.inf

    def _ground_z(self) -> float:
        zs = [f[2] for f in self.footholds if f is not None]
        return float(sum(zs) / len(zs)) if zs else 0.0

    # ---- gait events -------------------------------------------------------------------------
    def _start_walking(self, t: float, com, comd) -> None:
        """From both soles down: move the DCM over the first stance sole, then step."""
        c = self.command
        first_swing = self.footsteps.first_swing_side(c, self.footholds)
        stance = 1 - first_swing
        g = self.params.gait
        self.stance = stance
        self.speed_correction.reset(t, com)
        self.swing_plan = self.footsteps.next_steps(self.footholds[stance], stance,
                                                    self.heading, c, 1)[0]
        self._begin_shift(t, com, comd, Phase.START, g.start_shift)

    def _begin_shift(self, t: float, com, comd, phase: Phase, duration: float) -> None:
        """Start a double-support phase that moves the DCM to where the next step needs it.

        At lift-off the DCM must be such that, with the ZMP on the stance sole, it reaches the
        planned swing target plus the periodic offset b1 at the next ZMP switch.
        """
        g = self.params.gait
        omega = math.sqrt(self.gravity / g.com_height)
        p_st = zmp_point(self.footholds[self.stance], g)
        p_new = zmp_point(self.swing_plan, g)
        b1 = self._planned_dcm_offset()
        decay = np.exp(-omega * (g.swing_time + 0.5 * g.double_support))
        xi_end = p_st + (p_new + b1 - p_st) * decay
        self.start_dcm = (t, com[:2] + comd[:2] / omega, xi_end)
        self.liftoff.reset()
        self.phase = phase
        self.t_phase = t
        self.phase_duration = duration

    def _plan_shift(self, t: float, com, comd) -> None:
        """Plan the next step from the new stance sole; begin the shift (:func:`shift_duration`)."""
        g = self.params.gait
        self.swing_plan = self.footsteps.next_steps(self.footholds[self.stance], self.stance,
                                                    self.heading, self._plan_command(), 1)[0]
        self._begin_shift(t, com, comd, Phase.DOUBLE, g.double_support)
        if g.shift_time_factor > 0.0:
            omega = math.sqrt(self.gravity / g.com_height)
            _, xi0, xi1 = self.start_dcm
            z = zmp_point(self.footholds[1 - self.stance], g)
            self.phase_duration = shift_duration(xi0, xi1, z[:2], omega, g)

    def _stance_moved(self, t: float, com, comd) -> None:
        """Double support: a new stance sole that slid more than ``stance_slip_replan`` [m] since
        touchdown (off a stone) is taken where it is now and the shift's target planned again
        (same start), lasting ``double_support`` at least after the slide."""
        now, was = self._sole_pose4(self.stance), self.footholds[self.stance]
        if math.hypot(now[0] - was[0], now[1] - was[1]) > self.params.gait.stance_slip_replan:
            self.footholds[self.stance] = now
            self.footsteps.observe(self.footholds)
            t0, xi0, _ = self.start_dcm
            t_phase, duration = self.t_phase, self.phase_duration
            self._plan_shift(t, com, comd)
            self.start_dcm = (t0, xi0, self.start_dcm[2])
            self.t_phase = t_phase
            self.phase_duration = max(duration, t - t_phase + self.params.gait.double_support)

    def _shift_comdd(self, t: float, com, comd) -> np.ndarray:
        """CoM acceleration (xy) of the weight shift: DCM tracking with a bounded ZMP."""
        g = self.params.gait
        omega = math.sqrt(self.gravity / g.com_height)
        t0, xi0, xi1 = self.start_dcm
        T = max(self.phase_duration, 1e-3)
        tau = (t - t0) / T
        tc = min(max(tau, 0.0), 1.0)
        sd = tc**3 * (10 - 15 * tc + 6 * tc * tc)
        dsd = 30 * tc * tc * (1 - tc) ** 2 / T
        # (Scalar math per component, in the order the 2-vector expressions had.)
        k = g.dcm_track_gain
        com_xy = (float(com[0]), float(com[1]))
        zmp = []
        for s0, s1, c, cd in zip(xi0.tolist(), xi1.tolist(), com_xy, comd[:2].tolist()):
            xi = c + cd / omega
            zmp.append(xi - ((s1 - s0) * dsd - k * (xi - (s0 + (s1 - s0) * sd))) / omega)
        # Keep the ZMP inside the double-support region (heading frame box around the soles).
        R = rot2(self.heading)
        RT = R.T
        a, b = (np.dot(RT, zmp_point(f, g)) for f in self.footholds)
        z_H = np.dot(RT, np.array(zmp))
        half = 0.5 * self.model.foot_length - 0.02
        z_H[0] = min(max(z_H[0], min(a[0], b[0]) - half), max(a[0], b[0]) + half)
        z_H[1] = min(max(z_H[1], min(a[1], b[1])), max(a[1], b[1]))
        w2 = omega**2
        zx, zy = np.dot(R, z_H).tolist()
        return np.array([w2 * (com_xy[0] - zx), w2 * (com_xy[1] - zy)])

    def _single_comdd(self, t: float, dt: float, com, comd) -> np.ndarray:
        """CoM acceleration (xy) in single support: LIPM about a ZMP on the stance sole.

        The ZMP sits at the sole centre plus an ankle correction along the sole (the only
        direction a line foot can move it) that tracks the DCM reference of this step,
        xi_ref(t) = p + (xi_liftoff - p) exp(omega (t - t_liftoff)).
        """
        g = self.params.gait
        omega = math.sqrt(self.gravity / g.com_height)
        foot = self.footholds[self.stance]
        # (Scalar math per component, in the order the 2-vector expressions had.)
        px, py = zmp_point(foot, g).tolist()
        cx, cy = float(com[0]), float(com[1])
        growth = np.exp(omega * (t - self.t_phase))
        sx, sy = self.start_dcm[2].tolist()
        xr, yr = px + (sx - px) * growth, py + (sy - py) * growth
        ca, sa = math.cos(foot[3]), math.sin(foot[3])
        xi_err = np.array([cx + float(comd[0]) / omega - xr, cy + float(comd[1]) / omega - yr])
        if self.com_bias.enabled:
            self.com_bias.observe(xi_err, yaw_of(self.model.base_rotation()), dt)
        dx = (1.0 + g.ankle_dcm_gain / omega) * float(np.dot(np.array([ca, sa]), xi_err))
        lim = g.ankle_zmp_range
        d = min(max(dx, -lim), lim)
        w2 = omega * omega
        return np.array([w2 * (cx - (px + ca * d)), w2 * (cy - (py + sa * d))])

    def _lift_off(self, t: float, com, comd) -> None:
        g = self.params.gait
        swing_side = 1 - self.stance
        self.footholds[self.stance] = self._sole_pose4(self.stance)
        start = self._sole_pose4(swing_side)
        target = clamp_to_stance(self.swing_plan, self.footholds[self.stance], self.stance, g)
        self.swing = SwingTrajectory(t, g.single_support, start, target, g.swing_height,
                                     g.swing_land_fraction, g.swing_lift_fraction,
                                     g.late_descent_speed, g.late_descent_max)
        self.swing.pitch_start = self._sole_pitch(swing_side)
        self.swing_z_error = 0.0
        self._terrain_target()
        self._step_over = False
        self._step_over_clearance()
        self.dcm_offset = self._planned_dcm_offset()
        self._t_retarget = t
        self.phase = Phase.SINGLE
        self.t_phase = t
        self.phase_duration = g.single_support

    def _touchdown(self, t: float, com, comd) -> None:
        g = self.params.gait
        landed = 1 - self.stance
        self.footholds[landed] = self._sole_pose4(landed)
        old = self.footholds[self.stance]
        new = self.footholds[landed]
        self.swing = None
        self.t_touchdown = t
        self.stance = landed
        if not self._moving() and square_stance(new, old, landed, g):
            mid = 0.5 * (zmp_point(new, g) + zmp_point(old, g))
            times = np.array([t, t + 0.5 * g.stop_settle, t + g.stop_settle + 1.0])
            pts = np.array([zmp_point(old, g), mid, mid]).T
            self.com_planner.plan(times, pts, com[:2], comd[:2], g.com_height)
            self.phase = Phase.STOP
            self.t_phase = t
            self.phase_duration = g.stop_settle
            return
        self.speed_correction.touchdown(t, com, self.command, self.heading)
        self._plan_shift(t, com, comd)

    def _plan_command(self) -> np.ndarray:
        """The command the footstep planner uses: the command plus the speed correction."""
        c = self.command.copy()
        if self._moving():
            c[:2] += self.speed_correction.value
        return c

    def _adjust_swing_target(self, t: float, com, comd) -> None:
        """Capture-point (DCM) stepping: choose where and when the swing sole lands so that, at
        the next ZMP switch, the DCM has the offset from the new sole that the planned steps
        need (:func:`pr2_drake.controllers.planning.step_adjust.choose_step`).

        For the planned next two steps L1, L2 of period T, that periodic offset is
        b = (L1 exp(omega T) + L2) / (exp(2 omega T) - 1) (``self.dcm_offset``).
        """
        g = self.params.gait
        omega = math.sqrt(self.gravity / g.com_height)
        stance = self.footholds[self.stance]
        p_st = zmp_point(stance, g)
        xi = com[:2] + comd[:2] / omega
        plan = self.swing_plan
        sw = self.swing
        t_now_land = sw.landing_time
        # Landing-time window; when it is empty (the swing is nearly over) only the current
        # landing time remains.
        planned = sw.t0 + g.swing_time
        earliest = max(t + g.min_remaining_swing, sw.t0 + g.min_swing_time)
        latest = planned + g.max_swing_extension
        # The ZMP reference offset of the landing sole (zmp_point) moves with its target; the
        # target's yaw stays as set at lift-off.
        plan_zmp = zmp_point(plan, g)
        choice = choose_step(t, xi, p_st, stance, self.stance, plan_zmp, self.dcm_offset,
                             self.heading, earliest, planned, latest, t_now_land, g, omega)
        if abs(choice.landing_time - t_now_land) > 1e-6:
            sw.retime(t, choice.landing_time)
        wish_xy = choice.target_xy - (plan_zmp - plan[:2])
        caught = self.footsteps.catch_step(wish_xy, plan, stance, sw.progress)
        if caught is not None:  # the plan's level cannot take the DCM: land on the next one
            self.swing_plan = plan = caught
            self.dcm_offset = self._planned_dcm_offset()
        target_xy = self.footsteps.constrain(wish_xy, plan)
        # Move the swing target at a bounded speed so the swing curve stays smooth.
        step = target_xy - self.swing.target[:2]
        max_step = g.retarget_speed * max(t - self._t_retarget, 0.0)
        n = math.sqrt(step.dot(step))  # (np.linalg.norm's own sum)
        if n > max_step:
            step *= max_step / n
        self.swing.target[:2] += step
        self._t_retarget = t
        self._terrain_target()
        if self._step_over:  # a high swing stays high (no jump of the reference mid-swing)
            self._step_over_clearance()

    def _sole_pitch(self, side: int) -> float:
        """Pitch [rad] of a sole about its y axis (negative = toe up)."""
        R = self.model.sole_pose(side).rotation().matrix()
        return float(np.arctan2(-R[2, 0], np.hypot(R[0, 0], R[1, 0])))

    def _terrain_target(self) -> None:
        """Swing target height and landing pitch from the terrain model and the stance sole."""
        if not self.terrain.known_heights:
            return
        stance = self.footholds[self.stance]
        slope = -np.tan(self._sole_pitch(self.stance))
        z, pitch = self.terrain.foothold(stance, slope, self.swing.target)
        self.swing.target[2] = z
        self.swing.pitch_target = pitch
        self.swing.plan_over_terrain(self.terrain, self.params.gait)

    def _step_over_clearance(self) -> None:
        """A high swing when the footstep planner asks for one (stepping over an obstacle,
        :meth:`FootstepPlanner.swing_clearance`): the higher of its and the terrain's height."""
        clear = self.footsteps.swing_clearance(self.swing.start, self.swing.target)
        if clear is None:
            return
        self._step_over = True
        if self.swing.clear_z is not None:
            clear = max(clear, self.swing.clear_z)
        self.swing.clear_z = float(clear)
        g = self.params.gait
        self.swing.clear_fractions = (g.swing_clear_lift, g.swing_clear_lower)

    def _planned_dcm_offset(self) -> np.ndarray:
        """Periodic DCM offset b (xy, W) at the switch onto the planned swing target."""
        g = self.params.gait
        return periodic_dcm_offset(self.footsteps, self.swing_plan, 1 - self.stance,
                                   self.heading, self._plan_command(), g,
                                   math.sqrt(self.gravity / g.com_height))

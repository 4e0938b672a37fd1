"""The whole-body controller: a short composition of planner, objectives and QP.

One control tick (:meth:`WholeBodyController.update`):

1. the robot model takes the measured state (:class:`WholeBodyModel`), and the CoM state the
   planner sees is filtered against sensor noise when ``com_filter`` is on
   (:class:`pr2_drake.controllers.com_filter.ComStateFilter`, predicted with the CoM
   acceleration of the previous tick's QP solution);
2. the gait planner (:class:`GaitPlanner`, with a footstep planner and a terrain model passed
   in) turns the velocity command into a plan (:class:`WholeBodyPlan`): active contacts and
   references; the caller adds hand targets and which hand holds something;
3. each tracking objective (:mod:`pr2_drake.controllers.tracking.objectives`: CoM, pelvis, sole contacts, swing
   sole, hands, posture) adds its rows to the cost;
4. the whole-body QP (:class:`WholeBodyQp`, DAQP, built once) over all 24 velocity DoFs, the
   sole contact forces and, for a hand that holds something, the hand's contact force, returns
   the leg torques and, when it drives the arms (``arms="effort"``), the arm torques.

Arms: ``arms="position"`` (default; the arms are held by another block, e.g.
:class:`pr2_drake.controllers.posture.ArmPosture`, and the QP takes their torques as given),
``arms="effort"`` (the QP drives the arms: posture and hand objectives, torque limits, and hand
contact forces as variables while a hand is attached) or ``arms="balance"`` (the QP drives the
arms with the posture objective only: no hand targets, no hand-force variables, and the arm
torques, far from their peaks, are clamped after the QP rather than bounded in it; for agents
that walk and never reach).

Robot facts (mass, gravity, peak torques, joint ranges) come from the model's plant.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from pr2_drake.controllers.com_filter import ComStateFilter
from pr2_drake.controllers.planning.terrain import FlatTerrain
from pr2_drake.controllers.planning.footsteps import FootstepPlanner
from pr2_drake.controllers.planning.gait import GaitPlanner, Phase
from pr2_drake.controllers.tracking.hand_force import HandForceEstimator
from pr2_drake.controllers.plan import WholeBodyPlan
from pr2_drake.controllers.tracking.objectives import (
    ComObjective,
    HandPositionObjective,
    HandUprightObjective,
    PelvisOrientationObjective,
    PostureObjective,
    SoleContactObjective,
    SwingSoleObjective,
    ObjectiveCost,
)
from pr2_drake.controllers.walking_params import WalkingParams
from pr2_drake.controllers.model import WholeBodyModel
from pr2_drake.controllers.tracking.qp import WholeBodyQp
from pr2_drake.ports import N_ARMS
from pr2_drake.robot.params import ARM_JOINTS, LEG_JOINTS

COMMAND_PORT = "velocity_command"
HAND_TARGETS_PORT = "hand_targets"
ARM_MODES = ("position", "effort", "balance")

# Layout of the status vector (also the status output port).
STATUS_FIELDS = ("qp_ok", "qp_failures", "qp_iterations", "phase", "stance_side", "falling")


def check_command(command, port: str = COMMAND_PORT) -> np.ndarray:
    """A velocity command (vx, vy, yaw_rate) as a float array, or ValueError naming the port."""
    if type(command) is np.ndarray and command.shape == (3,) and command.dtype == np.float64:
        x, y, z = command.tolist()  # the common case (a port's value): no conversions
        if math.isfinite(x) and math.isfinite(y) and math.isfinite(z):
            return command
    try:
        cmd = np.asarray(command, dtype=float).reshape(-1)
    except (TypeError, ValueError) as err:
        raise ValueError(f"{port}: expected 3 numbers (vx, vy, yaw_rate), got {command!r}") from err
    if cmd.shape != (3,):
        raise ValueError(f"{port}: expected 3 values (vx, vy, yaw_rate), got shape {cmd.shape}")
    if not np.all(np.isfinite(cmd)):
        raise ValueError(f"{port}: command contains NaN or inf: {cmd}")
    return cmd


def check_hand_targets(targets, port: str = HAND_TARGETS_PORT) -> list[np.ndarray | None]:
    """Hand targets as [left, right], each None, a finite p_WH (3) [m], or 6 values: p_WH and
    an axis u_H of the hand frame to keep vertical (a held object's "up"; returned unit
    length); ValueError naming the port on a wrong length, shape, NaN, inf or a zero axis.

    Accepts a sequence of two entries, or a mapping with keys "left_hand" / "right_hand".
    """
    if targets is None:
        return [None, None]
    if isinstance(targets, dict):
        unknown = set(targets) - {"left_hand", "right_hand"}
        if unknown:
            raise ValueError(f"{port}: unknown hands {sorted(unknown)}; use left_hand, "
                             "right_hand")
        targets = [targets.get("left_hand"), targets.get("right_hand")]
    try:
        entries = list(targets)
    except TypeError as err:
        raise ValueError(f"{port}: expected [left, right] targets, got {targets!r}") from err
    if len(entries) != 2:
        raise ValueError(f"{port}: expected 2 entries (left, right), got {len(entries)}")
    out: list[np.ndarray | None] = []
    for name, p in zip(("left", "right"), entries):
        if p is None:
            out.append(None)
            continue
        try:
            a = np.asarray(p, dtype=float).reshape(-1)
        except (TypeError, ValueError) as err:
            raise ValueError(f"{port}: {name} target is not 3 numbers: {p!r}") from err
        if a.shape not in ((3,), (6,)):
            raise ValueError(f"{port}: {name} target needs 3 values (x, y, z) or 6 (x, y, z "
                             f"and an up axis in the hand frame), got {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{port}: {name} target contains NaN or inf: {a}")
        if a.size == 6:
            n = float(np.linalg.norm(a[3:]))
            if n < 1e-9:
                raise ValueError(f"{port}: {name} target's up axis is zero: {a[3:]}")
            a = np.r_[a[:3], a[3:] / n]
        out.append(a)
    return out


@dataclass
class TickInfo:
    """What one tick did (for the status port and the benchmark)."""

    qp_ok: bool = True
    qp_failures: int = 0
    qp_iterations: int = 0
    phase: Phase = Phase.STAND
    stance_side: int = -1  # -1 both
    falling: bool = False

    def vector(self) -> np.ndarray:
        return np.array([float(self.qp_ok), self.qp_failures, self.qp_iterations,
                         int(self.phase), self.stance_side, float(self.falling)])


class WholeBodyController:
    """Planner + objectives + QP (see the module docstring).

    Args:
        params: walking parameters (None: params/controllers/walking.yaml).
        footsteps: footstep planner (None: from the velocity command).
        terrain: terrain model of the footholds (None: flat).
        arms: "position", "effort" or "balance" (see the module docstring).
    """

    def __init__(self, params: WalkingParams | None = None,
                 footsteps: FootstepPlanner | None = None, terrain: FlatTerrain | None = None,
                 arms: str = "position"):
        if arms not in ARM_MODES:
            raise ValueError(f"arms must be one of {ARM_MODES}, got {arms!r}")
        self.params = params or WalkingParams.load()
        p = self.params
        self.model = m = WholeBodyModel()
        self.arms_driven = arms != "position"  # the QP outputs arm torques
        self.hands = arms == "effort"  # ... and tracks hand targets and held objects' forces
        self.planner = GaitPlanner(p, m, footsteps, terrain)
        self.com_filter = ComStateFilter(p.com_filter)
        # Objectives, in the order their rows are summed.
        self.contacts = SoleContactObjective(p.qp, m)
        self.objectives = [ComObjective(p.com_xy, p.com_z, p.com_lateral_single_weight),
                      PelvisOrientationObjective(p.pelvis, m),
                      self.contacts,
                      SwingSoleObjective(p.swing_pos, p.swing_rot)]
        arm_gains = p.arms.posture if self.arms_driven else p.posture_arms
        n_arms, n_legs = len(m.v_arms), len(m.v_legs)
        self.posture = PostureObjective(
            m, m.q_nominal[m.maps.q_joints],
            np.r_[np.full(n_arms, arm_gains.kp), np.full(n_legs, p.posture_legs.kp)],
            np.r_[np.full(n_arms, arm_gains.kd), np.full(n_legs, p.posture_legs.kd)],
            np.r_[np.full(n_arms, arm_gains.weight), np.full(n_legs, p.posture_legs.weight)])
        if self.hands:
            self.objectives += [HandPositionObjective(0, p.arms.hand), HandPositionObjective(1, p.arms.hand),
                           HandUprightObjective(0, p.arms.hand_upright,
                                           p.arms.hand_upright_max_error),
                           HandUprightObjective(1, p.arms.hand_upright,
                                           p.arms.hand_upright_max_error)]
        self.objectives.append(self.posture)
        self.cost = ObjectiveCost(m.nv)
        # The QP: leg (and arm) torque limits and joint ranges from the plant.
        self.effort = m.effort[N_ARMS:]
        self.arm_effort = m.effort[:N_ARMS]
        # Joint-range rows for the joints the QP drives (legs; arms too in effort mode), in
        # the original joint order; knees stay bent (knee_max).
        margin = p.qp.joint_limit_margin
        lower = m.q_lower + margin
        upper = m.q_upper - margin
        knee = [i for i, name in enumerate(ARM_JOINTS + LEG_JOINTS) if name.endswith("knee")]
        upper[knee] = np.minimum(upper[knee], p.qp.knee_max)
        sel = slice(0, None) if self.arms_driven else slice(N_ARMS, None)
        self.q_box_min, self.q_box_max = lower[sel], upper[sel]
        self._q_box = np.array([self.q_box_min, self.q_box_max])  # (2, n): both bounds at once
        self.q_box_idx = m.maps.q_joints[sel]
        self.box_v = m.maps.v_joints[sel]
        self.qp = WholeBodyQp(m.nv, m.maps.v_base, m.v_legs, self.effort, 2 * m.n_points, p.qp,
                              arm_v=m.v_arms, n_kin=2 * self.contacts.n_kin_foot,
                              box_v=self.box_v,
                              arm_effort=self.arm_effort if self.arms_driven else None,
                              n_hands=2 if self.hands else 0,
                              arm_limits=arms != "balance")
        self.q_arms_hold = m.q_nominal[m.maps.q_joints[:N_ARMS]]
        self.hand_force = HandForceEstimator(m)
        self._fz_max = np.zeros(2 * m.n_points)
        self._fz_min = np.zeros(2 * m.n_points)
        self._hand_J = np.zeros((6, m.nv))
        self._hand_lo = np.zeros(6)
        self._hand_hi = np.zeros(6)
        self.timing = np.zeros(3)  # [s] accumulated: planner, objectives, QP (when ``timed``)
        self.timed = False
        self.debug = False
        self.debug_info: dict = {}
        self.reset()

    # ---- state -------------------------------------------------------------------------------
    def reset(self) -> None:
        """Forget the gait state: the next tick starts standing from the measured pose."""
        self.planner.reset()
        self.com_filter.reset()
        self.info = TickInfo()
        self.qp.last_tau = np.zeros(len(self.effort))
        self.qp.last_tau_arms = np.zeros(N_ARMS)
        self.qp.failures = 0
        self.qp._first = True
        self.tau_arms = np.zeros(N_ARMS)
        self.last_result = None
        self.hand_force.reset()

    # The gait state, read through the planner (for tests, plots and agents).
    @property
    def phase(self) -> Phase:
        return self.planner.phase

    @property
    def t_last(self) -> float | None:
        return self.planner.t_last

    @property
    def terrain(self) -> FlatTerrain:
        return self.planner.terrain

    def clip_command(self, command) -> np.ndarray:
        """Check (ValueError on NaN/inf/shape) and clip the command to the configured limits."""
        return self.planner.clip_command(check_command(command))

    def clip_hand_target(self, side: int, p_WH: np.ndarray) -> np.ndarray:
        """A hand target moved into the workspace: within ``arms.reach_max`` of the shoulder
        (the arm's first joint) and at least ``arms.z_min`` above the mean sole height."""
        a = self.params.arms
        m = self.model
        p_WS = m.shoulder_position(side)
        d = p_WH - p_WS
        n = float(np.sqrt(d @ d))
        out = p_WH if n <= a.reach_max else p_WS + d * (a.reach_max / n)
        z_min = self.planner.plan.ground_z + a.z_min
        if out[2] < z_min:
            out = np.array([out[0], out[1], z_min])
        return out

    def _lean(self, f_hands: np.ndarray) -> np.ndarray:
        """Standing CoM offset (xy, W) [m] that keeps the ZMP in place under the hand forces:
        m g dc = -sum f_xy (z_H - z_ground) (moments about the ground, quasi-static)."""
        m = self.model
        z_g = self.planner.plan.ground_z
        out = np.zeros(2)
        for side in (0, 1):
            f = f_hands[side]
            if f[0] != 0.0 or f[1] != 0.0:
                out -= f[:2] * (m.hand_point(side)[0][2] - z_g)
        return out / (m.mass * m.gravity)

    # ---- the tick ----------------------------------------------------------------------------
    def update(self, t: float, q: np.ndarray, v: np.ndarray, command,
               tau_arms: np.ndarray | None = None, hand_targets=None,
               attached: tuple[bool, bool] = (False, False)) -> np.ndarray:
        """One control tick at time t [s]: plant state (q, v) in, leg torques [Nm] out (the arm
        torques, when the QP drives the arms, in ``self.tau_arms``).

        Args:
            command: (vx, vy, yaw_rate) in the heading frame [m/s, m/s, rad/s]; clipped to the
                limits, ValueError on NaN/inf.
            tau_arms: the arm torques [Nm] being applied (e.g. the testbed's measured efforts).
                arms="position": None = assume the arm posture block's spring-damper.
                arms="effort": they give the estimate of a held hand's force
                (:class:`HandForceEstimator`); None = the QP's own last arm torques.
            hand_targets: [left, right] p_WH [m] or None each (arms="effort"); see
                :func:`check_hand_targets`; targets outside the workspace are clipped
                (:meth:`clip_hand_target`).
            attached: per hand, whether it holds something (pick_state): its contact force
                becomes a QP variable within ``qp.hand_force_max``.
        """
        timed = self.timed
        if timed:
            t0 = time.perf_counter()
        cmd = check_command(command)
        targets = check_hand_targets(hand_targets)
        m = self.model
        m.update(q, v)
        com, comd, J_com, jdv_com = m.com()
        com, comd = self.com_filter.update(t, com, comd)
        lean = None
        if self.hands:
            attached = (bool(attached[0]), bool(attached[1]))
            applied = self.tau_arms if tau_arms is None else tau_arms
            f_hands = self.hand_force.update(t, applied, attached)
            if attached[0] or attached[1]:
                lean = self._lean(f_hands)
        plan = self.planner.update(t, cmd, com, comd, lean)
        if self.hands:
            for side in (0, 1):
                h = plan.hands[side]
                tgt = targets[side]
                h.p = None if tgt is None else self.clip_hand_target(side, tgt[:3])
                h.up = None if tgt is None or tgt.size == 3 else tgt[3:]
                h.attached = attached[side]
                h.force_prior = self.hand_force.f[side]
        if timed:
            self.timing[0] += time.perf_counter() - t0
        tau = self.track(plan, self.objectives, q, v, tau_arms)
        if self.com_filter.enabled:
            res = self.last_result
            self.com_filter.set_acceleration(J_com @ res.vdot + jdv_com if res.ok else None)
        return tau

    def track(self, plan: WholeBodyPlan, objectives, q: np.ndarray, v: np.ndarray,
              tau_arms: np.ndarray | None = None,
              joint_limit_horizon: float | None = None) -> np.ndarray:
        """Track a plan with a objective list: the objectives' rows, then the whole-body QP (torque
        limits, friction, the plan's contact-force bounds, joint-limit braking within
        ``joint_limit_horizon`` [s], default ``qp.joint_limit_horizon``). The model must hold
        the measured (q, v) (:meth:`update` does this; another planner, e.g. a jump's, calls
        ``model.update`` then this with its own plan and objectives). ``tau_arms`` as in
        :meth:`update`. Returns the leg torques [Nm]; fills ``info`` and ``last_result``."""
        timed = self.timed
        if timed:
            t1 = time.perf_counter()
        p = self.params
        m = self.model
        cost = self.cost
        cost.clear()
        cost.record = self.debug
        for objective in objectives:
            objective.add_to(cost, m, plan)
        # Arm torques: measured, or the posture block's spring-damper (position mode).
        if not self.arms_driven and (tau_arms is None or not np.isfinite(tau_arms).all()):
            q_arms = q[m.maps.q_joints[:len(m.v_arms)]]
            tau_arms = np.clip(p.arm_stiffness * (self.q_arms_hold - q_arms)
                               - p.arm_damping * v[m.v_arms], -self.arm_effort, self.arm_effort)
        # Joint limits: accelerations that stop each joint within its range in horizon h.
        # (Both bounds in one (2, n) array: the same operations per element, half the calls.)
        hz = p.qp.joint_limit_horizon if joint_limit_horizon is None else joint_limit_horizon
        box = self._q_box - q[self.q_box_idx]
        box -= v[self.box_v] * hz
        box *= 2.0
        box /= hz * hz
        a_lo, a_hi = box[0], box[1]
        bad = a_lo > a_hi
        if bad.any():
            mid = 0.5 * (a_lo + a_hi)
            box[:] = np.where(bad, mid, box)
        np.maximum(box, -2000.0, out=box)
        np.minimum(box, 2000.0, out=box)
        n = m.n_points
        c0, c1 = plan.contacts
        fz_max, fz_min = self._fz_max, self._fz_min
        fz_max[:n], fz_max[n:] = c0.fz_max, c1.fz_max
        fz_min[:n], fz_min[n:] = c0.fz_min, c1.fz_min
        hand_args = {}
        if self.hands:
            fmax = p.qp.hand_force_max
            for side in (0, 1):
                r = slice(3 * side, 3 * side + 3)
                h = plan.hands[side]
                if h.attached:
                    self._hand_J[r] = m.hand_point(side)[2]
                    self._hand_lo[r] = h.force_prior - fmax
                    self._hand_hi[r] = h.force_prior + fmax
                else:
                    self._hand_J[r] = 0.0
                    self._hand_lo[r] = 0.0
                    self._hand_hi[r] = 0.0
            hand_args = dict(J_hands=self._hand_J, hand_bounds=(self._hand_lo, self._hand_hi),
                             hand_prior=np.concatenate((plan.hands[0].force_prior,
                                                        plan.hands[1].force_prior)))
        if timed:
            t2 = time.perf_counter()
        res = self.qp.solve(m.mass_matrix(), m.bias(), self.contacts.J_all, cost.H, cost.g,
                            fz_max, tau_arms, fz_min, self.contacts.J_kin, self.contacts.a_kin,
                            (a_lo, a_hi), **hand_args)
        if self.arms_driven:
            self.tau_arms = res.tau_arms
        if self.debug:
            self.debug_info = dict(costs=[float(np.sum(w * (J @ res.vdot - a) ** 2))
                                          for J, a, w in cost.rows], rows=list(cost.rows))
        g = p.gait
        com = m.com()[0]
        falling = bool(com[2] - plan.ground_z < 0.5 * g.com_height)
        self.info = TickInfo(res.ok, self.qp.failures, res.iterations, Phase(plan.phase),
                             plan.stance, falling)
        self.last_result = res
        if timed:
            t3 = time.perf_counter()
            self.timing[1:] += (t2 - t1, t3 - t2)
        return res.tau

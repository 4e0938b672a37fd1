"""Parameters of the walking controller, loaded from params/controllers/walking.yaml.

Units: metres, seconds, radians, newtons; gains as stiffness [1/s^2] and damping [1/s] of the
task-space acceleration laws ``a_d = kp (x_d - x) + kd (v_d - v) + a_ff``.

(No ``from __future__ import annotations`` here: ``yaml_load_typed`` reads the field types.)
"""

import math
from dataclasses import dataclass, field
from typing import ClassVar

from pr2_drake.params import Params


@dataclass
class GaitParams:
    """Gait timing [s] and footstep limits [m, rad]."""

    single_support: float = 0.35
    double_support: float = 0.10
    start_shift: float = 0.40  # weight shift from standing to the first stance foot
    stop_settle: float = 0.60  # final double support before standing
    step_width: float = 0.22  # nominal lateral distance between the soles
    min_step_width: float = 0.15  # feet never get closer than this (lateral, heading frame)
    # Standing lean against a force at a held hand: the CoM stays this far inside the soles'
    # contact points (heading frame), so that it is still over the feet when the force stops.
    lean_margin: float = 0.02
    max_step_forward: float = 0.25
    max_step_backward: float = 0.12
    max_step_lateral: float = 0.10  # extra width per step beyond step_width
    max_step_yaw: float = 0.30
    swing_height: float = 0.06
    swing_land_fraction: float = 0.9  # the swing lands at this fraction of single support
    # Over an edge (the terrain model's swing_clearance) the swing sole rises to the clearance
    # height during this first fraction of the swing phase, moves, and lowers onto the target
    # during this last fraction (lift, move, lower; the horizontal motion overlaps 40 %).
    # The CoM height target is com_height above the mean foothold height, or, when this is
    # set, above the stance sole in single support (stairs: the stance leg on the upper tread
    # is not left crouched while the other sole swings up from the lower one).
    com_height_over_stance: bool = False
    # Step-downs (stairs): when set, the CoM height target is com_height above the lower of
    # the stance sole and the swing target (single support) or the next planned foothold
    # (double support before it), so that the CoM descends before the swing sole has to reach
    # the lower tread (the swing knee does not straighten). Level steps are unchanged.
    com_height_step_down: bool = False
    # [m] > 0 (stairs): knee-limit-aware CoM height. The CoM height target stays within this
    # distance of every supporting sole, counting the CoM's offset from the sole along the
    # heading: z <= z_sole + sqrt(com_reach^2 - dx^2). A rear sole still on the lower tread
    # after a step-up then keeps the CoM low until it lifts (its knee stays bent). 0 = off.
    com_reach: float = 0.0
    swing_clear_lift: float = 0.3
    swing_clear_lower: float = 0.3
    # Step-downs over an edge (stairs, :class:`PatchTerrain`): the horizontal motion starts at
    # this fraction of the swing phase (not after 60 % of the lift: nothing ahead is higher,
    # and a longer window means a slower sole that the leg tracks), and the sole lowers only
    # once its planned heel is swing_down_heel_margin [m] past the last higher ground.
    swing_down_move_start: float = 0.1
    swing_down_heel_margin: float = 0.04
    swing_lift_fraction: float = 0.0  # horizontal swing motion starts/ends this much of the
    # swing phase after lift-off / before landing (vertical lift and landing)
    touchdown_height: float = 0.004  # sole lower than this above the stance sole (above its
    # target when the core has a terrain model) = contact
    touchdown_min_phase: float = 0.9  # swing progress (1 = planned landing) before contact counts
    late_touchdown: float = 0.15  # declare contact this long after the planned landing
    late_descent_speed: float = 0.5  # [m/s] the sole reference keeps descending after the
    late_descent_max: float = 0.05  # [m] planned landing, to this far below the target
    # Early contact (rough or sloped ground): after this swing progress, a descending swing
    # sole held more than blocked_touchdown_error above its desired height has landed
    # (0 = off).
    early_touchdown_phase: float = 0.6
    blocked_touchdown_error: float = 0.0
    early_touchdown_max_height: float = 0.04  # [m] ... and is at most this above its target
    com_height: float = 0.50  # CoM height above the stance soles (LIPM height) when walking
    stand_com_height: float = 0.555  # CoM height when standing
    height_rate: float = 0.1  # [m/s] how fast the CoM height target moves between the two
    zmp_offset_x: float = 0.0  # ZMP reference ahead of the sole centre
    # Foot placement from the capture-point (DCM) error, per axis of the heading frame
    # (1 = the DCM lands at the planned offset from the new sole; see step_adjust.py).
    dcm_gain: list[float] = field(default_factory=lambda: [1.0, 1.0])
    recovery_min_step_width: float = 0.08  # [m] step adjustment may go this narrow
    recovery_step_backward: float = 0.0  # [m] > 0: ... and this far behind the stance sole
    #                                      (0: max_step_backward + 0.05)
    # Step adjustment cost (step_adjust.choose_step): unreachable part of the ideal step along
    # the stance sole, outwards (DCM outside the new sole) and inwards [1/m^2], landing time
    # off the plan [1/s^2], and a fixed cost of changing the landing time.
    step_cost_x: float = 1000.0
    step_cost_outward: float = 10000.0
    step_cost_inward: float = 300.0
    step_cost_timing: float = 100.0
    retime_penalty: float = 0.05
    timing_grid: float = 0.01  # [s] landing times searched on this grid
    max_swing_extension: float = 0.05  # [s] a swing may land this much later than planned
    dcm_track_gain: float = 10.0  # [1/s] DCM tracking in double support
    liftoff_dcm_tolerance: float = 0.02  # [m] DCM error allowed at lift-off
    max_shift_extension: float = 0.3  # [s] double support may last this much longer
    ankle_dcm_gain: float = 3.0  # [1/s] single support: DCM feedback through the CoP
    ankle_zmp_range: float = 0.04  # [m] ... within this distance of the sole centre
    speed_gain: float = 0.3  # per step: integral correction of the planned speed
    speed_correction_max: float = 0.15  # [m/s]
    speed_hold_change: float = 0.03  # [m/s] a linear command change that holds it
    speed_hold_decay: float = 0.5  # ... and shrinks it by this factor per step
    speed_window_steps: int = 1  # the speed compared is the mean over this many steps (2: stride)
    speed_error_max: float = 0.0  # [m/s] > 0: a window off the command by more is not integrated
    com_bias_rate: float = 0.0  # [1/s] CoM offset estimate from the single-support DCM error
    com_bias_error_max: float = 0.01  # [m] ... each tick's error clipped to this
    com_bias_max: float = 0.03  # [m] ... the estimate within this, per axis (com_bias.py)
    com_bias_axes: str = "y"  # ... on these axes of the pelvis' yaw frame ("xy", "y")
    min_swing_time: float = 0.18  # [s] step timing: a swing may be shortened to this
    min_remaining_swing: float = 0.08  # [s] ... but never lands sooner than this from now
    min_double_support: float = 0.04  # [s] double support ends this early if the DCM ...
    runaway_dcm_error: float = 0.05  # [m] ... is this far from its target and moving away
    runaway_dcm_growth: float = 0.004  # [m] moving away: this much over its smallest error
    dcm_error_filter: float = 0.012  # [s] low-pass of the DCM error in these rules (noise)
    shift_time_factor: float = 0.0  # > 0: double support lasts this x the DCM's least shift
    #                                 time (liftoff.py shift_duration); 0: double_support
    stance_slip_replan: float = 0.0  # [m] > 0: a new stance sole that slides this far in double
    #                                  support is re-read and the shift's target planned again
    retarget_speed: float = 3.0  # [m/s] fastest motion of the swing target
    dcm_freeze_phase: float = 0.8  # the swing target stops moving after this swing progress
    zmp_qy: float = 1.0  # ZmpPlanner weights: ZMP error and CoM acceleration
    zmp_r: float = 0.001

    @property
    def swing_time(self) -> float:
        """Planned time from lift-off to landing [s]."""
        return self.single_support * self.swing_land_fraction

    @property
    def step_period(self) -> float:
        """Planned time from one touchdown to the next [s]."""
        return self.swing_time + self.double_support


@dataclass
class CommandLimits:
    """Velocity command limits: out-of-range commands are clipped to these [m/s, rad/s]."""

    vx_max: float = 0.45
    vx_min: float = -0.25
    vy_max: float = 0.2
    yaw_rate_max: float = 0.6
    accel_max: float = 0.5  # [m/s^2] the command used ramps at most this fast (x, y)
    yaw_accel_max: float = 1.0  # [rad/s^2]
    start_threshold: float = 0.01  # |command| above this starts walking (m/s or rad/s)
    heading_lead_max: float = 0.3  # desired heading never leads the pelvis by more [rad]


@dataclass
class ObjectiveGains:
    """Stiffness kp [1/s^2], damping kd [1/s] and QP weight of one objective."""

    kp: float = 100.0
    kd: float = 20.0
    weight: float = 1.0


@dataclass
class QpParams:
    """Whole-body QP settings."""

    mu: float = 0.7  # friction pyramid coefficient (ground model: 1.0)
    fz_min: float = 2.0  # [N] per contact point in contact
    fz_min_single: float = 15.0  # [N] per stance point in single support (keeps the CoP off
    # the heel/toe edge, so the line foot keeps some yaw friction)
    fz_max_factor: float = 1.2  # per point, times the robot weight
    load_ramp: float = 0.03  # [s] ramp of a landing foot's normal-force bound
    hard_contacts: bool = True  # fully loaded stance soles: hard no-acceleration rows
    contact_weight: float = 1000.0  # soft no-acceleration cost (soles loading/unloading)
    contact_kd: float = 20.0
    vdot_reg: float = 1e-4
    force_reg: float = 1.0  # on forces in units of force_scale
    force_scale: float = 100.0
    max_iter: int = 400
    time_limit: float = 0.0  # [s] OSQP wall-time cap; 0 = none (a cap breaks determinism)
    eps_abs: float = 1e-3  # absolute: relative tolerances scale with the big dynamics rows
    eps_rel: float = 1e-6
    joint_limit_margin: float = 0.03  # [rad] leg joints stop this far inside their range
    knee_max: float = -0.15  # [rad] the knee never straightens beyond this (singularity)
    joint_limit_horizon: float = 0.08  # [s] braking horizon of the joint-limit rows
    polish: bool = True  # OSQP solution polishing (accurate active set)
    fail_decay: float = 0.9  # last torques scaled by this after each failed solve
    hand_force_reg: float = 1000.0  # regularisation of a held hand's contact force (units
    # of force_scale) towards its estimate: the QP leans on a held object only as needed
    hand_force_max: float = 20.0  # [N] band about the estimate, per component (W)
    solver: str = "daqp"  # "daqp" (dense active set, exact, ~0.05 ms; OSQP as its fallback)
    # or "osqp" (the settings above from max_iter to polish apply to OSQP only)


@dataclass
class ComFilterParams:
    """The CoM state the gait planner sees (pr2_drake/controllers/com_filter.py): time
    constants [s] of the corrections towards the measured position and velocity (0 = that one
    unfiltered; both 0 = off), and the longest gap between ticks [s] it predicts across."""

    position_time: float = 0.0
    velocity_time: float = 0.0
    max_gap: float = 0.05


@dataclass
class ArmParams:
    """The arms when the whole-body QP drives them (``arms_command`` in effort mode)."""

    posture: ObjectiveGains = field(default_factory=lambda: ObjectiveGains(100.0, 20.0, 0.1))
    hand: ObjectiveGains = field(default_factory=lambda: ObjectiveGains(150.0, 25.0, 100.0))
    # A hand target's "up" axis (a held object's vertical) kept vertical [1/s^2, 1/s, weight].
    hand_upright: ObjectiveGains = field(default_factory=lambda: ObjectiveGains(100.0, 20.0, 200.0))
    # ... its error (sine of the tilt) saturated at this, so a far tilt is turned gently.
    hand_upright_max_error: float = 0.2
    # Hand targets farther than this from the shoulder are pulled back onto this sphere [m].
    reach_max: float = 0.42
    # ... and below this height above the ground under the robot (mean sole height) [m].
    z_min: float = 0.25


@dataclass
class WalkingParams(Params):
    """All walking-controller parameters (see params/controllers/walking.yaml)."""

    FILE: ClassVar[str] = "params/controllers/walking.yaml"
    control_period: float = 0.004  # [s] QP rate; torques are held in between
    gait: GaitParams = field(default_factory=GaitParams)
    limits: CommandLimits = field(default_factory=CommandLimits)
    qp: QpParams = field(default_factory=QpParams)
    com_xy: ObjectiveGains = field(default_factory=lambda: ObjectiveGains(30.0, 10.0, 500.0))
    com_lateral_single_weight: float = 500.0  # CoM objective weight sideways in single support
    com_z: ObjectiveGains = field(default_factory=lambda: ObjectiveGains(100.0, 20.0, 100.0))
    pelvis: ObjectiveGains = field(default_factory=lambda: ObjectiveGains(100.0, 20.0, 30.0))
    swing_pos: ObjectiveGains = field(default_factory=lambda: ObjectiveGains(400.0, 40.0, 1000.0))
    swing_rot: ObjectiveGains = field(default_factory=lambda: ObjectiveGains(200.0, 30.0, 50.0))
    posture_legs: ObjectiveGains = field(default_factory=lambda: ObjectiveGains(20.0, 2.0, 0.05))
    posture_arms: ObjectiveGains = field(default_factory=lambda: ObjectiveGains(100.0, 20.0, 0.0))
    # Arms (position mode, posture block): stiffness [Nm/rad] and damping [Nm s/rad].
    arm_stiffness: float = 60.0
    arm_damping: float = 3.0
    arms: ArmParams = field(default_factory=lambda: ArmParams())
    com_filter: ComFilterParams = field(default_factory=ComFilterParams)

    def check(self) -> None:
        """Raise ValueError on inconsistent values."""
        g = self.gait
        if self.control_period <= 0:
            raise ValueError(f"control_period must be > 0, got {self.control_period}")
        if g.single_support <= 0 or g.double_support <= 0:
            raise ValueError("gait single_support and double_support must be > 0")
        if len(g.dcm_gain) != 2 or not all(0.0 <= k < math.inf for k in g.dcm_gain):
            raise ValueError(f"gait.dcm_gain needs 2 finite values >= 0 (x, y), got "
                             f"{g.dcm_gain}")
        if not 0.0 < g.recovery_min_step_width <= g.min_step_width:
            raise ValueError("gait.recovery_min_step_width must be in (0, min_step_width]")
        if not 0.0 <= g.recovery_step_backward < 0.5:
            raise ValueError("gait.recovery_step_backward must be in [0, 0.5) m (0: "
                             f"max_step_backward + 0.05), got {g.recovery_step_backward}")
        if not (0.0 <= g.swing_down_move_start < 1.0 - 0.6 * g.swing_clear_lower
                and 0.0 <= g.swing_down_heel_margin < 0.2):
            raise ValueError("gait.swing_down_move_start must be in [0, 1 - 0.6 swing_clear_lower) "
                             "and swing_down_heel_margin in [0, 0.2) m, got "
                             f"{g.swing_down_move_start}, {g.swing_down_heel_margin}")
        if g.min_step_width > g.step_width:
            raise ValueError("gait.min_step_width must not exceed gait.step_width")
        if not (0.0 <= g.shift_time_factor < math.inf and 0.0 <= g.stance_slip_replan < math.inf):
            raise ValueError("gait.shift_time_factor and stance_slip_replan must be finite and "
                             f">= 0 (0: off), got {g.shift_time_factor}, {g.stance_slip_replan}")
        if not (isinstance(g.speed_window_steps, int) and 1 <= g.speed_window_steps <= 4
                and 0.0 <= g.speed_error_max < math.inf):
            raise ValueError("gait.speed_window_steps must be an integer in 1..4 and "
                             "speed_error_max finite and >= 0 (0: no limit), got "
                             f"{g.speed_window_steps}, {g.speed_error_max}")
        if g.com_bias_axes not in ("x", "y", "xy"):
            raise ValueError(f"gait.com_bias_axes must be 'x', 'y' or 'xy', got "
                             f"{g.com_bias_axes!r}")
        f = self.com_filter
        if not (0.0 <= f.position_time < math.inf and 0.0 <= f.velocity_time < math.inf
                and 0.0 < f.max_gap < math.inf):
            raise ValueError("com_filter.position_time and velocity_time must be >= 0 and "
                             f"max_gap > 0, got {f}")
        if min(g.com_bias_rate, g.com_bias_error_max, g.com_bias_max) < 0:
            raise ValueError("gait.com_bias_rate, com_bias_error_max and com_bias_max must be "
                             ">= 0")

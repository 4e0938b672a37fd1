"""The plan: what the planners hand to the tracking objectives for one control tick.

A plan says which contacts are active and what each objective should track: CoM acceleration and
height, pelvis orientation, the swing sole, each hand, the joint posture. Planners
(:class:`pr2_drake.controllers.planning.gait.GaitPlanner`, an agent's hand targets) fill it; objectives
(:mod:`pr2_drake.controllers.tracking.objectives`) read it. Frames: W world (z up); S a sole frame; H a hand
sphere centre (``l_arm_sphere`` / ``r_arm_sphere``). Units: m, s, rad, N.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

HANDS = ("left_hand", "right_hand")  # index 0, 1 (as in pick_state)


@dataclass
class SoleContact:
    """One sole's contact this tick: its normal-force bounds per contact point [N] and whether
    its points are held by hard rows (loaded stance) or a soft cost (loading/unloading)."""

    active: bool = True
    fz_min: float = 2.0
    fz_max: float = 0.0
    hard: bool = True


@dataclass
class SwingReference:
    """Desired swing-sole motion: p_WS, v_WS, a_WS (3 each, W) and R_WS_d, w_WS_d (W)."""

    side: int
    p: np.ndarray
    v: np.ndarray
    a: np.ndarray
    R: np.ndarray
    w: np.ndarray


@dataclass
class HandReference:
    """A hand's desired position p_WH [m] (None: no hand objective), an axis of the hand frame to
    keep upright (``up``, e.g. a held object's vertical: None leaves the orientation free), and
    whether it is attached
    (``pick_state``): then its contact force is a QP variable within ``force_max`` [N] per
    axis of W (centred on ``force_prior`` [N], the force expected at the hand)."""

    p: np.ndarray | None = None
    up: np.ndarray | None = None  # unit axis in H to keep along +z of W (None: free)
    attached: bool = False
    force_prior: np.ndarray = field(default_factory=lambda: np.zeros(3))


@dataclass
class WholeBodyPlan:
    """Everything the objectives track in one tick (see the module docstring).

    Attributes:
        contacts: per sole (0 left, 1 right).
        com_acc_xy: desired CoM acceleration in x, y [m/s^2] (W), already a feedback law.
        com_z: desired CoM height [m] (W).
        com_frame_yaw: when set, the CoM task's rows are expressed in this yaw frame and the
            lateral row gets the single-support weight (line foot).
        pelvis_R: desired pelvis orientation R_WB.
        swing: swing-sole reference, or None in double support.
        hands: per hand (0 left, 1 right).
        phase, stance: gait phase (int) and stance side (-1 both) for the status port.
        ground_z: mean height of the footholds [m] (fall detection).
    """

    contacts: list[SoleContact] = field(default_factory=lambda: [SoleContact(), SoleContact()])
    com_acc_xy: np.ndarray = field(default_factory=lambda: np.zeros(2))
    com_z: float = 0.0
    com_frame_yaw: float | None = None
    pelvis_R: np.ndarray = field(default_factory=lambda: np.eye(3))
    swing: SwingReference | None = None
    hands: list[HandReference] = field(default_factory=lambda: [HandReference(),
                                                                HandReference()])
    phase: int = 0
    stance: int = -1
    ground_z: float = 0.0


@dataclass
class JumpPlan(WholeBodyPlan):
    """A plan with a CoM acceleration in 3-D and per-sole references.

    Attributes:
        com_acc: desired CoM acceleration a_WCcm [m/s^2] (W), already a feedback law.
        com_weight: QP weight of its x, y, z rows (0: no CoM objective, e.g. in flight).
        soles: per sole (0 left, 1 right) a reference, or None (in contact or free).
        pelvis_scale: factor on the pelvis orientation weight (the launch lets the torso pitch
            so that the angular momentum stays small: with both soles fixed the two conflict).
        L_rate: desired rate of the centroidal angular momentum [N m] (W), already a feedback
            law; L_weight: its QP weight (0: none, e.g. in flight, where it is conserved).
    """

    com_acc: np.ndarray = field(default_factory=lambda: np.zeros(3))
    com_weight: np.ndarray = field(default_factory=lambda: np.zeros(3))
    L_rate: np.ndarray = field(default_factory=lambda: np.zeros(3))
    L_weight: float = 0.0
    pelvis_scale: float = 1.0  # times the pelvis orientation task's weight
    soles: list[SwingReference | None] = field(default_factory=lambda: [None, None])

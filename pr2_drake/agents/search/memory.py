"""What the task-6 search sequencer knows: its parameters, its stages and its memory.

(No ``from __future__ import annotations``: ``yaml_load_typed`` reads the field types.)
"""

import enum
from dataclasses import dataclass, field
from typing import Any, ClassVar, List, Optional

import numpy as np

from pr2_drake.agents.sequencer import SequencerMemory
from pr2_drake.params import Params

HANDS = ("left_hand", "right_hand")


@dataclass
class SearchAgentParams(Params):
    """See params/agents/search.yaml (m, s, deg where named)."""

    FILE: ClassVar[str] = "params/agents/search.yaml"
    period: float = 0.02
    look_distance: float = 0.55
    look_yaws_deg: List[float] = field(default_factory=lambda: [0.0, 30.0, -30.0])
    look_settle: float = 0.6
    look_frames: int = 2
    look_sides: int = 2
    search_margin: float = 0.25
    pick_standoff: float = 0.12
    pick_reach: float = 0.58
    stage_distance: float = 0.40
    place_standoff: float = 0.15
    hand_lateral: float = 0.10
    approach_radius: float = 0.12
    approach_gain: float = 1.0
    approach_yaw_gain: float = 1.5
    approach_speed: float = 0.10
    position_tolerance: float = 0.04
    approach_timeout: float = 8.0
    approach_accept: float = 0.12
    yaw_tolerance_deg: float = 5.0
    settle_time: float = 0.8
    pre_height: float = 0.08
    grasp_height: float = 0.05
    grasp_offset: float = 0.12
    grasp_margin: float = 0.04
    grasp_elevations_deg: List[float] = field(default_factory=lambda: [55.0, 70.0, 85.0])
    grasp_azimuths_deg: List[float] = field(
        default_factory=lambda: [0.0, 45.0, -45.0, 90.0, -90.0, 135.0, -135.0, 180.0])
    hand_clearance: float = 0.05
    reach: float = 0.44
    lift_forward: float = 0.05
    edge_clearance: float = 0.07
    reach_time: float = 1.5
    pick_timeout: float = 1.2
    pick_tries: int = 4
    carry: List[float] = field(default_factory=lambda: [0.22, 0.14, 0.30])
    place_inset: float = 0.17
    place_reach: float = 0.12
    place_clearance: float = -0.001
    place_tolerance: float = 0.008
    place_settle_time: float = 1.5
    place_gain: float = 3.0
    place_lower_max: float = 0.04
    place_pull_max: float = 0.06
    release_hold: float = 0.6
    back_speed: float = 0.10
    back_time: float = 2.0
    approach_stall_time: float = 3.0
    approach_progress: float = 0.03
    approach_yaw_weight: float = 0.3
    reach_accept: float = 0.55
    place_margin: float = 0.12
    place_turn_deg: float = 40.0
    approach_retries: int = 2
    walk_stall_time: float = 8.0
    walk_progress: float = 0.05
    walk_arrive: float = 0.6
    weak_obstacle: int = 2
    weak_floor_ratio: float = 4.0
    verify_frames: int = 3
    verify_height: float = 0.05
    place_retries: int = 1
    scan_rate: float = 0.4
    scan_turn_deg: float = 330.0
    scan_capture_every: int = 2
    scan_detect_every: int = 2
    walk_capture_every: int = 4
    color_margin: float = 0.25
    color_lead: float = 0.35
    height_tolerance: float = 0.03
    searched_margin: float = 0.15
    explore_max: int = 4
    explore_distance: float = 1.0
    blocked_distance: float = 0.6


class Stage(enum.IntEnum):
    NAVIGATE = 0
    LOOK = 1
    APPROACH = 2
    SETTLE = 3
    REACH = 4
    PICK = 5
    LIFT = 6
    CARRY = 7
    APPROACH_TABLE = 8
    SETTLE_TABLE = 9
    PLACE = 10
    RELEASE = 11
    RETRACT = 12
    BACK = 13
    DONE = 14
    FAILED = 15
    SCAN = 16
    VERIFY = 17


@dataclass
class SearchMemory(SequencerMemory):
    """What :class:`pr2_drake.agents.search.sequencer.ObjectSearchSequencer` remembers between
    its updates (abstract state in its Context), besides :class:`SequencerMemory`.

    Attributes:
        map: the map of what the camera has seen (:class:`~.mapping.HeightMap`); frames: how
            many frames it holds; frame_time: the last one's render time [s]; poses: (time,
            X_WC) of the last updates at which a frame was rendered; capture: whether the next
            camera sample renders; capture_color: whether it renders colour too (a frame the
            detector may see: scanning, ``color_lead`` before a look's detection, and walking
            the last ``color_margin`` to a scan's spot; else depth only).
        surfaces: the tops to search by name (from the map); place: the one searched now;
            searched: centres of the tops searched in vain; hints: where the target was seen
            while scanning (W, m); explored: frontiers walked to.
        scan_yaw, scan_turned: the heading at the last update of a scan and how far it has
            turned [rad] (None: no scan under way). path_version: the map version the path
            was last checked against.
        side: outward normal (x, y) of the table side the robot stands at.
        path: the waypoints being walked (W, m); goal: the pose goal (x, y, yaw).
        look_k, look_tries, t_still: the heading looked along, frames taken there, since
            when the robot stands still [s] (-1: it does not); look_sides: outward normals
            (x, y) of the sides of ``place`` looked from already.
        p_WO: the detected target's centre (W, m); others: other objects seen with it.
        pick_goal: the pose to pick from; nav_then: the stage after NAVIGATE.
        hand: the hand that picks (0 left, 1 right); hand_path, hand_t0: its waypoints and
            their start time [s]; pick_tries: tries so far.
        sides_tried: the table sides (outward normals) a pick missed from; retry_side: the
            side to walk round to after stepping back from a missed pick (None: none).
        r_pick, o_pick: hand and object at the pick in the base's heading frame (m);
        hand_over_top: the hand centre above the pick table's top (m); place_lower: how far
            [m] a place has moved the hand's target below its drop point (the hand stopped
            above it); place_pull: how far [m] it has then drawn the target back towards
            the base (the target was beyond the arm's reach); up_H: the held object's
            vertical in the hand frame (None: not kept vertical).
        best_err, t_best: the least distance [m] to the stage's goal seen since the stage
            began (by a walk or an approach: the progress watch of :mod:`.recovery`) and when
            it last shrank by the stage's step [s]; approach_tries: walks made again to a pick
            or place pose after an approach stalled; lenient: the path was planned past the
            map's weak obstacles (no path otherwise); place_tries: objects picked up again
            after a place the check after it (VERIFY) did not see on the coffee table.
        failure: why the sequence FAILED ("" while it has not); log: what happened when.
    """

    stage: int = Stage.SCAN
    map: Any = None
    frames: int = 0
    frame_time: float = -1.0
    poses: list = field(default_factory=list)
    capture: bool = False
    capture_color: bool = True
    surfaces: dict = field(default_factory=dict)
    searched: list = field(default_factory=list)
    hints: list = field(default_factory=list)
    explored: int = 0
    scan_yaw: Optional[float] = None
    scan_turned: float = 0.0
    path_version: int = -1
    place: Optional[str] = None
    side: np.ndarray = field(default_factory=lambda: np.array([0.0, 1.0]))
    path: Optional[list] = None
    goal: Optional[np.ndarray] = None
    look_k: int = 0
    look_tries: int = 0
    look_sides: list = field(default_factory=list)
    t_still: float = -1.0
    p_WO: Optional[np.ndarray] = None
    others: list = field(default_factory=list)
    pick_goal: Optional[np.ndarray] = None
    nav_then: int = Stage.LOOK
    hand: int = 1
    hand_path: list = field(default_factory=list)
    hand_t0: float = 0.0
    pick_tries: int = 0
    sides_tried: list = field(default_factory=list)
    retry_side: Optional[np.ndarray] = None
    r_pick: np.ndarray = field(default_factory=lambda: np.zeros(3))
    o_pick: np.ndarray = field(default_factory=lambda: np.zeros(3))
    hand_over_top: float = 0.0
    place_lower: float = 0.0
    place_pull: float = 0.0
    up_H: Optional[np.ndarray] = None
    best_err: float = float("inf")
    t_best: float = 0.0
    approach_tries: int = 0
    lenient: bool = False
    place_tries: int = 0
    failure: str = ""
    log: list = field(default_factory=list)

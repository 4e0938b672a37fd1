"""Task 6 reference agent: read the sentence, find the object with the head camera, carry it to
the coffee table.

:class:`ObjectSearchAgent` is a Diagram of a sequencer (:class:`ObjectSearchSequencer`) and the
walking controller with the arms in the whole-body QP (``WalkingController(arms="effort")``,
its QP at 125 Hz: params/controllers/walking_search.yaml, task 6's row), built like
:class:`pr2_drake.agents.valve.ValveAgent`. The sequencer is made of the search parts, each
replaceable on its own (constructor arguments of :class:`ObjectSearchSequencer`):

- ``parser`` (:class:`~.instruction.InstructionParser`, anything with ``parse(sentence)``):
  the ``instruction`` prior -> target object, source furniture/room, destination;
- ``detector`` (:class:`~.perception.ObjectDetector`, anything with ``find(rgb, depth, X_WC,
  target)``): the head camera frame (``rgbd`` input) -> the target's position in W;
- ``grid`` (:class:`~.navigation.OccupancyGrid` of the public scene description) and
  :func:`~.navigation.plan_path` / :func:`~.navigation.follow_velocity`: walking between rooms.

Stages (``stage`` output):

1. NAVIGATE to a look pose ``look_distance`` before the next likely place (the source
   furniture; else the furniture of the source room; else the object's home table in the
   public scene description; then the other tables, nearest first), facing its top, on the
   side of the table with the most free floor;
2. LOOK: stand still, take a frame, run the detector; try the headings ``look_yaws_deg``
   (the camera is fixed on the base: the body turns); nothing found -> next place;
3. APPROACH: small steps onto a pick pose ``pick_standoff`` from the table edge, in line with
   the object (the hand's shoulder nearer it), facing the table; an object more than
   ``pick_reach`` from the hand's shoulder there is picked from the side (of the four)
   nearest it where there is floor (NAVIGATE round the table first); SETTLE until the gait
   stands;
4. REACH: the nearer hand rises in front of the body, moves over the grasp point
   (``pre_height`` above it) and down onto it: ``grasp_offset`` from the object's centre
   towards the shoulder, at least ``grasp_height`` above the centre (inside the 0.20 m pick
   distance, as near the shoulder as that allows), or, when another object seen with it would
   be nearly as near that point (``pick`` latches the nearest), higher over it or from
   another side (``grasp_margin``); PICK: ``pick`` until ``pick_state`` reports
   it attached (timeout: closer to the centre and try again, ``pick_tries`` in all);
5. LIFT to the carry pose, NAVIGATE (holding it) to the coffee table, APPROACH the place
   pose from which, the arm as at the pick, the object is over the table's centre line
   ``place_inset`` inside its near edge (the base at least ``place_standoff`` from the edge),
   SETTLE;
6. PLACE: the hand goes back to where it held the object at the pick (relative to the base,
   so that the arm is as it was), as high over this top as it was over that one plus
   ``place_clearance``; RELEASE; the hand goes up; step BACK; DONE. While placing, the hand
   targets carry the object's vertical in the hand frame (6-value targets): the whole-body QP
   keeps it vertical, so round objects are set down upright.

FAILED (standing, the reason in ``error`` and the step log in ``log``): not found on any
table, pick failed ``pick_tries`` times, no path, or the object fell from the hand.

A sentence that cannot be read (unknown object, no destination) ends the episode at its first
update with the parser's message (termination ``agent_error``, the message in the report), not
with a crash at build time. Only the public observation (``body_state``, ``joint_state``,
``pick_state``, ``rgbd``), the priors (``instruction``, ``object_models``,
``coffee_table_center``, ``coffee_table_size``) and the task's public scene description
(tasks/6_object_search.yaml: walls, furniture, camera) are used; no simulator ground truth.
Parameters: params/agents/search.yaml. Positions in m, world frame W.

(No ``from __future__ import annotations``: ``yaml_load_typed`` reads the field types.)
"""

import enum
import math
from dataclasses import dataclass, field
from typing import Any, ClassVar, List, Optional

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Diagram, DiagramBuilder

from pr2_drake.agents.search.instruction import Instruction, InstructionError
from pr2_drake.agents.search.navigation import (
    NavigationParams,
    NoPathError,
    OccupancyGrid,
    follow_velocity,
    plan_path,
)
from pr2_drake.agents.sequencer import TaskSequencer
from pr2_drake.agents.walk_to_goal import yaw_from_quaternion
from pr2_drake.camera import RgbdFrame
from pr2_drake.grasp import PickState
from pr2_drake.lifetime import weak_calc
from pr2_drake.params import Params
from pr2_drake.ports import BODY_STATE_SIZE, JOINT_STATE_SIZE, P_WB, QUAT_WB

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
    place_clearance: float = -0.001
    release_hold: float = 0.6
    back_speed: float = 0.10
    back_time: float = 2.0



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


@dataclass(frozen=True)
class Table:
    """A table top from the public scene description: centre (x, y), size (x, y), top height."""

    name: str
    center: np.ndarray
    size: np.ndarray
    height: float

    def side_frame(self, normal: np.ndarray):
        """(half depth along ``normal``, unit tangent, half length along the tangent)."""
        n = np.asarray(normal, float)
        t = np.array([-n[1], n[0]])
        return (float(abs(n) @ self.size) / 2, t, float(abs(t) @ self.size) / 2)

    def contains(self, p, margin: float = 0.0) -> bool:
        return bool(np.all(np.abs(np.asarray(p)[:2] - self.center) <= self.size / 2 + margin))


def tables_from_scene(scene: dict) -> dict[str, Table]:
    """Every furniture top of the task YAML's ``scene`` block."""
    return {k: Table(k, np.asarray(f["center"], float), np.asarray(f["size"], float),
                     float(f["height"])) for k, f in scene["furniture"].items()}


def best_side(grid: OccupancyGrid, table: Table, standoff: float, radius: float) -> np.ndarray:
    """Outward unit normal (x, y) of the table side to stand at: the long sides first, the one
    with the most free floor in front (ray on the grid inflated by ``radius``)."""
    g = grid.inflated(radius)
    best, best_key = None, None
    for n in (np.array([1.0, 0.0]), np.array([-1.0, 0.0]), np.array([0.0, 1.0]),
              np.array([0.0, -1.0])):
        half, _, half_len = table.side_frame(n)
        free = 0.0
        for d in np.arange(standoff, 2.0, 0.05):
            if not g.free(table.center + n * (half + d)):
                break
            free = d
        key = (free >= standoff + 0.2, half_len >= half, free)
        if best_key is None or key > best_key:
            best, best_key = n, key
    return best


def search_order(instr: Instruction, vocab_home: dict[str, str], furniture_room: dict[str, str],
                 tables: dict[str, Table], destination: str, p0) -> list[str]:
    """Furniture keys to search, most likely first (the destination is never searched)."""
    order: list[str] = []
    if instr.source_furniture:
        order.append(instr.source_furniture)
    if instr.source_room:
        order += [f for f, r in furniture_room.items() if r == instr.source_room]
    home = vocab_home.get(instr.target)
    if home:
        order.append(home)
    rest = sorted(tables, key=lambda k: float(np.linalg.norm(tables[k].center - p0[:2])))
    order += rest
    out: list[str] = []
    for k in order:
        if k in tables and k not in out and k != destination:
            out.append(k)
    return out


def _smooth(s: float) -> float:
    s = min(max(s, 0.0), 1.0)
    return s * s * (3.0 - 2.0 * s)


def _wrap(a: float) -> float:
    return math.atan2(math.sin(a), math.cos(a))


class ObjectSearchSequencer(TaskSequencer):
    """Stages of the search and transport (see the module docstring).

    Inputs: ``body_state``, ``joint_state``, ``pick_state``, ``rgbd`` (RgbdFrame),
    ``walker_status``. Outputs: ``velocity_command`` (3), ``hand_targets`` ([left, right]),
    ``pick`` (str), ``release`` (bool), ``stage`` (1), ``camera_capture`` (bool: True in
    LOOK, the only stage that uses frames).

    Args:
        instruction: the parsed sentence, or None with ``error`` the parser's message.
        scene: the task YAML's public ``scene`` block (walls, furniture, objects' homes).
        detector: ``find(rgb, depth, X_WC, target) -> Detection | None``.
        object_height: the target's height [m] (its model): the hand clears its top when it
            comes from above.
        coffee_table: (x, y, top z) and size (x, y) of the destination, from the priors.
    """

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    def __init__(self, instruction: Optional[Instruction], scene: dict, detector,
                 object_height: float, params: SearchAgentParams | None = None,
                 nav: NavigationParams | None = None, camera_kinematics=None,
                 error: str = "", frame_shape=(480, 640)):
        super().__init__()
        from pr2_drake.controllers.model import WholeBodyModel

        self.p = params or SearchAgentParams()
        self.nav = nav or NavigationParams()
        self.instruction = instruction
        self.error = error
        self.detector = detector
        self.kin = camera_kinematics
        self.object_height = float(object_height)
        self.tables = tables_from_scene(scene)
        self.home = {k: v["table"] for k, v in scene["objects"].items()}
        self.room_of = {k: v["room"] for k, v in scene["furniture"].items()}
        self.grid = OccupancyGrid.from_scene(scene, self.nav.resolution)
        self.model = WholeBodyModel()  # forward kinematics of the observed state
        self.model.update(self.model.q_nominal, np.zeros(self.model.nv))
        # The shoulders in the base frame (the nominal pose has the base at the origin).
        self.p_BS = [self.model.shoulder_position(side).copy() for side in (0, 1)]
        self._bs = self.DeclareVectorInputPort("body_state", BODY_STATE_SIZE)
        self._js = self.DeclareVectorInputPort("joint_state", JOINT_STATE_SIZE)
        self._pick_state = self.DeclareAbstractInputPort("pick_state",
                                                         AbstractValue.Make(PickState()))
        h, w = frame_shape
        blank = RgbdFrame(np.zeros((h, w, 3), np.uint8), np.zeros((h, w), np.float32))
        self._rgbd = self.DeclareAbstractInputPort("rgbd", AbstractValue.Make(blank))
        self._status = self.DeclareVectorInputPort("walker_status", 6)
        self.DeclareDiscreteState(1)
        after_update = self.declare_command_outputs(grasp=True)
        self.DeclareAbstractOutputPort("camera_capture", lambda: AbstractValue.Make(False),
                                       weak_calc(self._calc_capture),
                                       prerequisites_of_calc=after_update)
        self.DeclarePeriodicUnrestrictedUpdateEvent(self.p.period, 0.0, self._update)
        self.reset()

    # ---- memory ------------------------------------------------------------------------------
    def reset(self) -> None:
        self.stage = Stage.NAVIGATE
        self.t_stage = 0.0
        self.t_last = -1.0
        self.cmd = np.zeros(3)
        self.targets: list = [None, None]
        self.pick = ""
        self.release = False
        self.places: Optional[list[str]] = None  # furniture still to search
        self.place: Optional[str] = None
        self.side = np.array([0.0, 1.0])  # outward normal of the side we stand at
        self.path = None
        self.goal: Optional[np.ndarray] = None  # (x, y, yaw) of the current pose goal
        self.look_k = 0  # index into look_yaws_deg
        self.look_tries = 0
        self.t_still = -1.0
        self.p_WO: Optional[np.ndarray] = None  # detected target centre
        self.others: list[np.ndarray] = []  # other objects seen with it (centres, W)
        self.pick_goal: Optional[np.ndarray] = None  # (x, y, yaw) to pick from
        self.nav_then = Stage.LOOK  # what follows NAVIGATE
        self.hand = 1
        self.hand_path: list = []
        self.hand_t0 = 0.0
        self.pick_tries = 0
        self.r_pick = np.zeros(3)  # hand at the pick, heading frame of the base [m]
        self.o_pick = np.zeros(3)  # detected object at the pick, heading frame [m]
        self.hand_over_top = 0.0  # hand centre above the pick table's top at the pick [m]
        self.up_H: Optional[np.ndarray] = None  # held object's vertical in the hand frame
        self.log: list[str] = []

    def _go(self, stage: Stage, t: float) -> None:
        self.log.append(f"{t:7.2f} {self.stage.name} -> {stage.name}")
        self.stage = stage
        self.t_stage = t

    # ---- geometry ----------------------------------------------------------------------------
    def _look_pose(self, name: str) -> np.ndarray:
        tab = self.tables[name]
        n = best_side(self.grid, tab, self.p.look_distance, self.nav.robot_radius)
        half, _, _ = tab.side_frame(n)
        xy = tab.center + n * (half + self.p.look_distance)
        return np.array([xy[0], xy[1], math.atan2(-n[1], -n[0])])

    def _pose_at(self, tab: Table, n: np.ndarray, along: float, standoff: float) -> np.ndarray:
        half, t, half_len = tab.side_frame(n)
        along = float(np.clip(along, -half_len - 0.1, half_len + 0.1))
        xy = tab.center + n * (half + standoff) + t * along
        return np.array([xy[0], xy[1], math.atan2(-n[1], -n[0])])

    def _heading_frame(self, yaw: float, err_W) -> tuple[float, float]:
        cy, sy = math.cos(yaw), math.sin(yaw)
        return cy * err_W[0] + sy * err_W[1], -sy * err_W[0] + cy * err_W[1]

    @staticmethod
    def _in_heading(p_WB, yaw: float, p_W) -> np.ndarray:
        """p_W relative to the base in its heading frame (x ahead, y left, z up) [m]."""
        d = np.asarray(p_W, float) - np.asarray(p_WB, float)
        c, s = math.cos(yaw), math.sin(yaw)
        return np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1], d[2]])

    def _place_pose(self, tab: Table) -> np.ndarray:
        """(x, y, yaw) facing ``tab`` across ``self.side`` from which, the arm as at the pick,
        the object is over the top's centre line ``place_inset`` inside its near edge (deeper
        if that would bring the base nearer than ``place_standoff`` to the edge)."""
        _, tan, _ = tab.side_frame(self.side)
        left = np.array([self.side[1], -self.side[0]])  # the robot's left facing -n
        ox, oy = float(self.o_pick[0]), float(self.o_pick[1])
        standoff = max(ox - self.p.place_inset, self.p.place_standoff)
        return self._pose_at(tab, self.side, -oy * float(left @ tan), standoff)

    def _drop_point(self, p_WB, yaw: float, tab: Table) -> np.ndarray:
        """p_WH to release at: where the hand held the object at the pick relative to the base
        (heading frame), as high over ``tab``'s top as it was over the pick table's plus
        ``place_clearance`` (so the object's bottom is that far above the top) [m]."""
        c, s = math.cos(yaw), math.sin(yaw)
        rx, ry = float(self.r_pick[0]), float(self.r_pick[1])
        return np.array([p_WB[0] + c * rx - s * ry, p_WB[1] + s * rx + c * ry,
                         tab.height + self.hand_over_top + self.p.place_clearance])

    def _carry_point(self, p_WB, yaw: float) -> np.ndarray:
        x, y, z = self.p.carry
        y = y if self.hand == 0 else -y
        c, s = math.cos(yaw), math.sin(yaw)
        return np.array([p_WB[0] + c * x - s * y, p_WB[1] + s * x + c * y, p_WB[2] + z])

    def _plan(self, p_WB, goal: np.ndarray) -> bool:
        try:
            self.path = plan_path(self.grid, p_WB[:2], goal[:2], self.nav.robot_radius)
        except NoPathError as e:
            self.log.append(f"no path: {e}")
            self.path = None
            return False
        self.goal = goal
        return True

    def _steps(self, p_WB, yaw: float) -> bool:
        """Proportional small steps onto ``self.goal``; True when there."""
        p = self.p
        ex, ey = self._heading_frame(yaw, self.goal[:2] - p_WB[:2])
        e_yaw = _wrap(self.goal[2] - yaw)
        if math.hypot(ex, ey) < p.position_tolerance and abs(e_yaw) < math.radians(
                p.yaw_tolerance_deg):
            self.cmd = np.zeros(3)
            return True
        s = p.approach_speed
        self.cmd = np.array([min(max(p.approach_gain * ex, -s), s),
                             min(max(p.approach_gain * ey, -s), s),
                             min(max(p.approach_yaw_gain * e_yaw, -0.4), 0.4)])
        return False

    def _close_enough(self, p_WB, yaw: float, t: float) -> bool:
        """After ``approach_timeout`` of small steps (the table edge may stop the body short
        of the goal), within ``approach_accept`` [m] and twice the yaw tolerance is enough."""
        p = self.p
        return bool(t - self.t_stage > p.approach_timeout
                    and np.linalg.norm(self.goal[:2] - p_WB[:2]) < p.approach_accept
                    and abs(_wrap(self.goal[2] - yaw)) < 2 * math.radians(p.yaw_tolerance_deg))

    def _walk(self, p_WB, yaw: float) -> bool:
        """Follow ``self.path`` to ``self.goal``; True within ``approach_radius`` of its end."""
        if np.linalg.norm(self.goal[:2] - p_WB[:2]) < self.p.approach_radius:
            return True
        self.cmd = follow_velocity(self.path, p_WB, yaw, None, self.nav)
        return False

    def _next_place(self, p_WB, t: float) -> None:
        if self.places is None:
            self.places = search_order(self.instruction, self.home, self.room_of, self.tables,
                                       self.instruction.destination, p_WB)
        while self.places:
            self.place = self.places.pop(0)
            goal = self._look_pose(self.place)
            if self._plan(p_WB, goal):
                self.look_k = 0
                self.nav_then = Stage.LOOK
                self._go(Stage.NAVIGATE, t)
                return
        self._go(Stage.FAILED, t)
        self.error = f"target {self.instruction.target!r} not found on any table"

    def _grasp_point(self, offset: float) -> np.ndarray:
        """``offset`` [m] from the object's centre (inside the pick distance): towards the
        hand's shoulder, not below the centre plus ``grasp_height``; but when another object
        seen would be less than ``grasp_margin`` farther from that point than the target (the
        pick latches the nearest object), the first of the other directions (turned about the
        target, then higher over it) that keeps that margin and stays within ``reach`` of the
        shoulder, else the one with the widest margin."""
        p = self.p
        o = self.p_WO
        s = self.model.shoulder_position(self.hand)
        d = s - o
        flat = float(np.hypot(d[0], d[1]))
        u0 = d[:2] / max(flat, 1e-6)
        el0 = math.atan2(max(float(d[2]), p.grasp_height), flat)
        best, best_key = None, None
        for el in [el0] + [math.radians(e) for e in p.grasp_elevations_deg]:
            # Over the target only when the hand clears its top.
            if el < el0 or (el > el0 and offset * math.sin(el) < 0.5 * self.object_height
                            + p.hand_clearance):
                continue
            for az in p.grasp_azimuths_deg:
                c, sn = math.cos(math.radians(az)), math.sin(math.radians(az))
                u = np.array([c * u0[0] - sn * u0[1], sn * u0[0] + c * u0[1]])
                g = o + offset * np.array([math.cos(el) * u[0], math.cos(el) * u[1],
                                           math.sin(el)])
                margin = min((float(np.linalg.norm(g - q)) for q in self.others),
                             default=np.inf) - offset
                if margin >= p.grasp_margin and np.linalg.norm(g - s) <= p.reach:
                    return g
                key = (np.linalg.norm(g - s) <= p.reach, margin)
                if best_key is None or key > best_key:
                    best, best_key = g, key
        return best

    def _out_from_under(self, p_WH, heading, tab: Table):
        """Where the hand goes first when it hangs below ``tab``'s top within
        ``edge_clearance`` of its footprint: straight back along ``heading`` (unit, x-y) at its
        height until it is that far outside (at most 0.2 m back); None when it hangs clear."""
        margin = self.p.edge_clearance
        if p_WH[2] >= tab.height or not tab.contains(p_WH, margin):
            return None
        back = np.array(p_WH, float)
        for _ in range(10):
            back[:2] -= 0.02 * heading
            if not tab.contains(back, margin):
                break
        return back

    def _start_hand_path(self, points: list, t: float) -> None:
        start = self.model.hand_point(self.hand)[0].copy()
        self.hand_path = [start] + [np.asarray(x, float) for x in points]
        self.hand_t0 = t

    def _follow_hand(self, t: float, hold: float = 0.3) -> bool:
        T = self.p.reach_time
        k = (t - self.hand_t0) / T
        seg = min(int(k), len(self.hand_path) - 2)
        a, b = self.hand_path[seg], self.hand_path[seg + 1]
        self.targets[self.hand] = a + (b - a) * _smooth(k - seg)
        return k >= len(self.hand_path) - 1 + hold / T

    # ---- the sequencer -----------------------------------------------------------------------
    def _update(self, context, state) -> None:
        t = context.get_time()
        if t < self.t_last - 1e-9:
            self.reset()
        self.t_last = t
        if self.instruction is None:
            raise InstructionError(f"ObjectSearchAgent cannot read the instruction: "
                                   f"{self.error}")
        p = self.p
        bs = self._bs.Eval(context)
        js = self._js.Eval(context)
        self.model.update(*self.model.state_from_ports(js, bs))
        p_WB = bs[P_WB]
        yaw = yaw_from_quaternion(bs[QUAT_WB])
        pick = self._pick_state.Eval(context)
        standing = int(self._status.Eval(context)[3]) == 0
        self.pick = ""
        self.release = False
        if self.places is None:
            self._next_place(p_WB, t)
        st = self.stage
        if st == Stage.NAVIGATE:
            if self._walk(p_WB, yaw):
                if self.nav_then == Stage.APPROACH:
                    self.goal = self.pick_goal
                    self._go(Stage.APPROACH, t)
                else:
                    self._go(Stage.LOOK, t)
                    self.t_still = -1.0
                    self.look_tries = 0
        if self.stage == Stage.LOOK:
            self._look(context, p_WB, yaw, standing, t)
        if self.stage == Stage.APPROACH:
            if self._steps(p_WB, yaw) or self._close_enough(p_WB, yaw, t):
                self.cmd = np.zeros(3)
                self._go(Stage.SETTLE, t)
        if self.stage == Stage.SETTLE:
            self.cmd = np.zeros(3)
            if not standing:
                self.t_stage = t
            elif t - self.t_stage >= p.settle_time:
                grasp = self._grasp_point(p.grasp_offset)
                # Up in front of the body first (the hand hangs below the table top).
                c, s_ = math.cos(yaw), math.sin(yaw)
                p_WH = self.model.hand_point(self.hand)[0]
                up = np.array([p_WB[0] + p.lift_forward * c, p_WB[1] + p.lift_forward * s_,
                               grasp[2] + p.pre_height])
                up[:2] += (p_WH[:2] - p_WB[:2]) - ((p_WH[:2] - p_WB[:2]) @ [c, s_]) * np.array(
                    [c, s_])  # keep the hand's sideways offset
                path = [up, grasp + [0.0, 0.0, p.pre_height], grasp]
                back = self._out_from_under(p_WH, np.array([c, s_]), self.tables[self.place])
                if back is not None:  # the body stopped short: the hand hangs under the top
                    path.insert(0, back)
                    if (up[:2] - p_WB[:2]) @ [c, s_] > (back[:2] - p_WB[:2]) @ [c, s_]:
                        up[:2] = back[:2]
                self._start_hand_path(path, t)
                self.pick_tries = 0
                self._go(Stage.REACH, t)
        if self.stage == Stage.REACH:
            if self._follow_hand(t):
                self._go(Stage.PICK, t)
        if self.stage == Stage.PICK:
            if pick.attached:
                p_WH = self.model.hand_point(self.hand)[0]
                # Where the hand holds it, in the base's heading frame (x ahead, y left, z up):
                # placing with the arm as it was here keeps the object's tilt small, and the
                # hand's height over the table it stood on sets the place height (the detected
                # height is a few cm off).
                self.r_pick = self._in_heading(p_WB, yaw, p_WH)
                self.o_pick = self._in_heading(p_WB, yaw, self.p_WO)
                self.hand_over_top = float(p_WH[2] - self.tables[self.place].height)
                # The object's vertical in the hand frame: the QP keeps it vertical while it
                # is set down (it stood upright; round objects roll off when set down tilted).
                # Not while walking: against the carry pose, the arm's 4 joints cannot.
                self.up_H = self.model.hand_rotation(self.hand)[0].T @ np.array([0.0, 0.0, 1.0])
                self._start_hand_path([p_WH + [0.0, 0.0, 0.10],
                                       self._carry_point(p_WB, yaw)], t)
                self._go(Stage.LIFT, t)
            elif t - self.t_stage > p.pick_timeout:
                self.pick_tries += 1
                if self.pick_tries >= p.pick_tries:
                    self.error = "pick failed"
                    self._go(Stage.FAILED, t)
                else:
                    self.targets[self.hand] = self._grasp_point(
                        max(p.grasp_offset - 0.03 * self.pick_tries, 0.03))
                    p_WH = self.model.hand_point(self.hand)[0]
                    self.log.append(f"{t:7.2f} pick try {self.pick_tries}: hand "
                                    f"{np.linalg.norm(p_WH - self.p_WO):.3f} from the object")
                    self.t_stage = t
            else:
                self.pick = HANDS[self.hand]
        if self.stage == Stage.LIFT:
            if self._follow_hand(t):
                tab = self.tables[self.instruction.destination]
                n = best_side(self.grid, tab, p.look_distance, self.nav.robot_radius)
                goal = self._pose_at(tab, n, 0.0, p.look_distance)
                self.side = n
                if self._plan(p_WB, goal):
                    self._go(Stage.CARRY, t)
                else:
                    self.error = "no path to the destination"
                    self._go(Stage.FAILED, t)
        if self.stage in (Stage.LIFT, Stage.CARRY, Stage.APPROACH_TABLE, Stage.SETTLE_TABLE,
                          Stage.PLACE) and not pick.attached:
            self.error = "the object fell from the hand"
            self.log.append(f"{t:7.2f} {self.error}")
            self.targets = [None, None]
            self.up_H = None
            self._go(Stage.FAILED, t)
        if self.stage == Stage.CARRY:
            self.targets[self.hand] = self._carry_point(p_WB, yaw)
            if self._walk(p_WB, yaw):
                self.goal = self._place_pose(self.tables[self.instruction.destination])
                self._go(Stage.APPROACH_TABLE, t)
        if self.stage == Stage.APPROACH_TABLE:
            self.targets[self.hand] = self._carry_point(p_WB, yaw)
            if self._steps(p_WB, yaw) or self._close_enough(p_WB, yaw, t):
                self.cmd = np.zeros(3)
                self._go(Stage.SETTLE_TABLE, t)
        if self.stage == Stage.SETTLE_TABLE:
            self.cmd = np.zeros(3)
            self.targets[self.hand] = self._carry_point(p_WB, yaw)
            if not standing:
                self.t_stage = t
            elif t - self.t_stage >= p.settle_time:
                drop = self._drop_point(p_WB, yaw, self.tables[self.instruction.destination])
                self._start_hand_path([drop + [0.0, 0.0, 0.08], drop], t)
                self._go(Stage.PLACE, t)
        if self.stage == Stage.PLACE:
            if self._follow_hand(t):
                self._go(Stage.RELEASE, t)
        if self.stage == Stage.RELEASE:
            self.release = True
            if pick.attached:
                self.t_stage = t
            elif t - self.t_stage >= p.release_hold:
                self.up_H = None
                p_WH = self.model.hand_point(self.hand)[0]
                self._start_hand_path([p_WH + [0.0, 0.0, 0.10]], t)
                self._go(Stage.RETRACT, t)
        if self.stage == Stage.RETRACT:
            if self._follow_hand(t):
                self.targets[self.hand] = None
                self._go(Stage.BACK, t)
        if self.stage == Stage.BACK:
            self.cmd = np.array([-p.back_speed, 0.0, 0.0])
            if t - self.t_stage >= p.back_time:
                self._go(Stage.DONE, t)
        if self.stage in (Stage.DONE, Stage.FAILED):
            self.cmd = np.zeros(3)
        state.get_mutable_discrete_state().get_mutable_vector(0).SetAtIndex(0, float(self.stage))

    def _look(self, context, p_WB, yaw: float, standing: bool, t: float) -> None:
        p = self.p
        base_yaw = self.goal[2]
        want = base_yaw + math.radians(p.look_yaws_deg[self.look_k])
        e_yaw = _wrap(want - yaw)
        if abs(e_yaw) > math.radians(p.yaw_tolerance_deg):
            self.cmd = np.array([0.0, 0.0, min(max(p.approach_yaw_gain * e_yaw, -0.4), 0.4)])
            self.t_still = -1.0
            return
        self.cmd = np.zeros(3)
        if not standing:
            self.t_still = -1.0
            return
        if self.t_still < 0:
            self.t_still = t
        if t - self.t_still < p.look_settle + 0.15 * self.look_tries:
            return
        det = self._detect(context)
        self.look_tries += 1
        tab = self.tables[self.place]
        if det is not None and tab.contains(det, p.search_margin) and abs(
                det[2] - tab.height) < 0.35:
            self.p_WO = det
            self.log.append(f"{t:7.2f} found {self.instruction.target} at "
                            f"{np.round(det, 3).tolist()} on {self.place} "
                            f"({len(self.others)} other objects seen)")
            self._start_approach(p_WB, t)
            return
        if self.look_tries >= p.look_frames:
            self.look_tries = 0
            self.look_k += 1
            if self.look_k >= len(p.look_yaws_deg):
                self._next_place(p_WB, t)

    def _detect(self, context) -> Optional[np.ndarray]:
        """The target's centre p_WO in this frame, or None; ``self.others`` gets the other
        objects' centres when the detector lists every object (``detect``)."""
        frame = self._rgbd.Eval(context)
        if frame.depth.size == 0:
            return None
        X_WC = self.kin.camera_pose(self._bs.Eval(context), self._js.Eval(context))
        target = self.instruction.target
        if hasattr(self.detector, "detect"):
            found = self.detector.detect(frame.color, frame.depth, X_WC)
            hit = next((d for d in found if d.label == target), None)
            if hit is not None:
                self.others = [np.asarray(d.p_WO, float) for d in found if d is not hit]
        else:
            hit = self.detector.find(frame.color, frame.depth, X_WC, target)
        return None if hit is None else np.asarray(hit.p_WO, float)

    def _start_approach(self, p_WB, t: float) -> None:
        tab = self.tables[self.place]
        look = best_side(self.grid, tab, self.p.look_distance, self.nav.robot_radius)
        # Stand at the side nearest the object (when there is room), else the look side.
        n = self._pick_side(tab, float(p_WB[2]))
        if not np.allclose(n, look):
            self.hand, stage = self._pick_pose(tab, n, self.p.stage_distance)
            if self._plan(p_WB, stage):
                self.hand, self.pick_goal = self._pick_pose(tab, n, self.p.pick_standoff)
                self.side = n  # walk round the table first
                self.nav_then = Stage.APPROACH
                self._go(Stage.NAVIGATE, t)
                return
        self.hand, self.pick_goal = self._pick_pose(tab, look, self.p.pick_standoff)
        self.side = look
        self.goal = self.pick_goal
        self._go(Stage.APPROACH, t)

    def _pick_pose(self, tab: Table, n: np.ndarray, standoff: float):
        """(hand, (x, y, yaw)): the hand on the object's side and the pose ``standoff`` from
        the edge across ``n``, facing the table, in line with the object but for
        ``hand_lateral`` (the hand's shoulder nearer it)."""
        _, tan, _ = tab.side_frame(n)
        along = float((self.p_WO[:2] - tab.center) @ tan)
        left = np.array([n[1], -n[0]])  # the robot's left when it faces -n
        hand = 0 if along * float(left @ tan) > 0 else 1
        sign = 1.0 if hand == 0 else -1.0
        along -= sign * self.p.hand_lateral * float(left @ tan)
        return hand, self._pose_at(tab, n, along, standoff)

    def _pick_side(self, tab: Table, z_base: float) -> np.ndarray:
        """The look side, or, when the object is beyond reach from its pick pose (farther
        than ``pick_reach`` from the hand's shoulder there; the base at height ``z_base``),
        the side (of the four) whose edge is nearest the object, where there is floor to
        stand on in front of the object."""
        look = best_side(self.grid, tab, self.p.look_distance, self.nav.robot_radius)
        d = self.p_WO[:2] - tab.center

        def depth(n: np.ndarray) -> float:
            return tab.side_frame(n)[0] - float(d @ n)

        if self._shoulder_to_object(tab, look, z_base) <= self.p.pick_reach:
            return look
        g = self.grid.inflated(self.nav.robot_radius)
        best, best_depth = look, depth(look) - 0.05  # walking round must gain something
        for n in (-look, np.array([-look[1], look[0]]), np.array([look[1], -look[0]])):
            half, tan, half_len = tab.side_frame(n)
            along = float(np.clip(d @ tan, -half_len, half_len))
            if depth(n) < best_depth and g.free(
                    tab.center + n * (half + self.p.stage_distance) + tan * along):
                best, best_depth = n, depth(n)
        return best

    def _shoulder_to_object(self, tab: Table, n: np.ndarray, z_base: float) -> float:
        """Distance [m] from the picking hand's shoulder, at the pick pose across ``n``, to
        the object (the shoulder's place in the base frame from the robot model)."""
        hand, (x, y, yaw) = self._pick_pose(tab, n, self.p.pick_standoff)
        r = self.p_BS[hand]
        c, s = math.cos(yaw), math.sin(yaw)
        p_WS = np.array([x + c * r[0] - s * r[1], y + s * r[0] + c * r[1], z_base + r[2]])
        return float(np.linalg.norm(p_WS - self.p_WO))

    # ---- outputs -----------------------------------------------------------------------------
    def _calc_targets(self, context, output) -> None:
        targets = [None if x is None else np.array(x) for x in self.targets]
        side = self.hand
        if (self.up_H is not None and targets[side] is not None
                and self.stage in (Stage.PLACE, Stage.RELEASE)):
            targets[side] = np.r_[targets[side], self.up_H]  # set down upright
        output.set_value(targets)

    def _calc_capture(self, context, output) -> None:
        # Frames are used only in LOOK (``_detect``, after ``look_settle`` there): the camera
        # renders from the first sample in LOOK on, and not at all otherwise.
        output.set_value(bool(self.stage == Stage.LOOK))


class ObjectSearchAgent(Diagram):
    """Task 6 reference agent (see the module docstring).

    Input ports: ``joint_state``, ``body_state``, ``pick_state``, ``rgbd``. Output ports:
    ``legs_command``, ``arms_command`` (effort, from the whole-body QP), ``pick``,
    ``release``, ``velocity_command``, ``stage`` and ``camera_capture`` (the camera renders
    only while the sequencer looks).

    Args:
        priors: the task's priors (``instruction``, ``object_models``, ``coffee_table_*``).
        params: sequencer YAML (default params/agents/search.yaml).
        parser: replaces the rule-based :class:`InstructionParser` (``parse(sentence)``).
        detector: replaces the :class:`ObjectDetector` (``find(rgb, depth, X_WC, target)``).
        walking_params: overrides of params/controllers/walking.yaml for the walking
            controller (task 6's row: params/controllers/walking_search.yaml, the QP at
            125 Hz).
    """

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    def __init__(self, priors: dict[str, Any], params: str | None = None, parser=None,
                 detector=None, walking_params: str | None = None):
        super().__init__()
        from pr2_drake.agents.search.instruction import InstructionParser
        from pr2_drake.agents.search.perception import (
            CameraIntrinsics,
            HeadCameraKinematics,
            ObjectDetector,
            object_models_from_priors,
        )
        from pr2_drake.controllers.walking import WalkingController
        from pr2_drake.controllers.walking_params import WalkingParams
        from pr2_drake.tasks import get_task

        if "object_models" not in priors:
            raise ValueError(f"ObjectSearchAgent needs the task-6 priors (object_models, "
                             f"instruction); got {sorted(priors)}")
        spec = get_task(6).spec
        scene = spec.scene
        parser = parser or InstructionParser.from_task()
        instruction, error = None, ""
        try:
            instruction = parser.parse(priors.get("instruction", ""))
        except InstructionError as e:
            error = str(e)
        cam = spec.camera
        K = CameraIntrinsics.from_fov(int(cam["width"]), int(cam["height"]),
                                      float(cam["fov_y_deg"]))
        models = object_models_from_priors(priors)
        detector = detector or ObjectDetector(models, K)
        height = models[instruction.target].height if (
            instruction and instruction.target in models) else 0.1
        seq = ObjectSearchSequencer(instruction, scene, detector, height,
                                    SearchAgentParams.load(params),
                                    NavigationParams.load(), HeadCameraKinematics(), error,
                                    (K.height, K.width))
        builder = DiagramBuilder()
        builder.AddNamedSystem("sequencer", seq)
        wparams = WalkingParams.load(overrides=[walking_params] if walking_params else [])
        walker = builder.AddNamedSystem("walker", WalkingController(wparams, arms="effort"))
        js = builder.ExportInput(walker.GetInputPort("joint_state"), "joint_state")
        bs = builder.ExportInput(walker.GetInputPort("body_state"), "body_state")
        ps = builder.ExportInput(walker.GetInputPort("pick_state"), "pick_state")
        builder.ConnectInput(js, seq.GetInputPort("joint_state"))
        builder.ConnectInput(bs, seq.GetInputPort("body_state"))
        builder.ConnectInput(ps, seq.GetInputPort("pick_state"))
        builder.ExportInput(seq.GetInputPort("rgbd"), "rgbd")
        builder.Connect(walker.GetOutputPort("status"), seq.GetInputPort("walker_status"))
        builder.Connect(seq.GetOutputPort("velocity_command"),
                        walker.GetInputPort("velocity_command"))
        builder.Connect(seq.GetOutputPort("hand_targets"), walker.GetInputPort("hand_targets"))
        builder.ExportOutput(walker.GetOutputPort("legs_command"), "legs_command")
        builder.ExportOutput(walker.GetOutputPort("arms_command"), "arms_command")
        builder.ExportOutput(seq.GetOutputPort("pick"), "pick")
        builder.ExportOutput(seq.GetOutputPort("release"), "release")
        builder.ExportOutput(seq.GetOutputPort("velocity_command"), "velocity_command")
        builder.ExportOutput(seq.GetOutputPort("stage"), "stage")
        builder.ExportOutput(seq.GetOutputPort("camera_capture"), "camera_capture")
        builder.BuildInto(self)

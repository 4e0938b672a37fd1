"""The stages of the task-6 search sequencer: what each does in one update, and the moves and
poses they share (:class:`SearchStages`, a part of
:class:`pr2_drake.agents.search.sequencer.ObjectSearchSequencer`).

Each stage handler takes the memory (:class:`SearchMemory`, a copy to change), what the update
read (:class:`pr2_drake.agents.sequencer.Now`) and the context (for the camera frame). The
sequencer runs them in :data:`ORDER`; a stage may hand over to a later one in the same update.
Positions in m, world frame W.
"""

from __future__ import annotations

import math
from typing import Optional

import numpy as np

from pr2_drake.agents.search.memory import HANDS, SearchMemory, Stage
from pr2_drake.agents.search.navigation import NoPathError, follow_velocity, plan_path
from pr2_drake.agents.search.tables import (
    ON_TOP_HEIGHT,
    Table,
    heading_frame,
    in_heading,
    out_from_under,
    pose_at,
    sides_by_preference,
)
from pr2_drake.agents.sequencer import Now, along_path

#: [s] the wait before a frame grows by this with each frame taken at one heading.
LOOK_TRY_WAIT = 0.15

#: The stages' handlers in the order an update runs them ("check_held" is not a stage: while
#: the object should be in the hand, it checks it is).
ORDER = (
    ((Stage.SCAN,), "_scan"), ((Stage.NAVIGATE,), "_navigate"), ((Stage.LOOK,), "_look"), ((Stage.APPROACH,), "_approach"),
    ((Stage.SETTLE,), "_settle"), ((Stage.REACH,), "_reach"), ((Stage.PICK,), "_pick"),
    ((Stage.LIFT,), "_lift"),
    ((Stage.LIFT, Stage.CARRY, Stage.APPROACH_TABLE, Stage.SETTLE_TABLE, Stage.PLACE),
     "_check_held"),
    ((Stage.CARRY,), "_carry"), ((Stage.APPROACH_TABLE,), "_approach_table"),
    ((Stage.SETTLE_TABLE,), "_settle_table"), ((Stage.PLACE,), "_place"),
    ((Stage.RELEASE,), "_release"), ((Stage.RETRACT,), "_retract"), ((Stage.BACK,), "_back"),
    ((Stage.VERIFY,), "_verify"),
    ((Stage.DONE, Stage.FAILED), "_stand"),
)


def _wrap(a: float) -> float:
    return math.atan2(math.sin(a), math.cos(a))


class SearchStages:
    """The stage handlers and their moves (see the module docstring). Uses the sequencer's
    ``p`` (SearchAgentParams), ``nav``, ``grid``, ``tables``, ``model``, ``p_BS``,
    ``object_height``, ``instruction`` and ``_detect``."""

    __slots__ = ()

    # ---- the stages --------------------------------------------------------------------------
    def _navigate(self, m: SearchMemory, now: Now, context) -> None:
        if self._walk(m, now.p_WB, now.yaw, now.t):
            if m.nav_then == Stage.APPROACH:
                m.goal = m.pick_goal
                self._go(m, Stage.APPROACH, now.t)
            elif m.nav_then == Stage.SCAN:
                m.cmd = np.zeros(3)
                self._go(m, Stage.SCAN, now.t)
            else:
                self._go(m, Stage.LOOK, now.t)
                m.t_still = -1.0
                m.look_tries = 0
    def _frame_wait(self, m: SearchMemory) -> float:
        """How long [s] the gait must have stood still before the next frame is taken:
        ``look_settle``, plus ``LOOK_TRY_WAIT`` per frame already taken here."""
        return self.p.look_settle + LOOK_TRY_WAIT * m.look_tries

    def _still_frame(self, m: SearchMemory, now: Now, context):
        """Stand still and, once the gait has stood for :meth:`_frame_wait`, take a frame:
        (True, the target's detection or None); (False, None) while waiting."""
        m.cmd = np.zeros(3)
        if not now.standing:
            m.t_still = -1.0
            return False, None
        if m.t_still < 0:
            m.t_still = now.t
        if now.t - m.t_still < self._frame_wait(m):
            return False, None
        det = self._detect(m, context)
        m.look_tries += 1
        return True, det

    def _look(self, m: SearchMemory, now: Now, context) -> None:
        """Turn to the next heading, stand still, take frames until the target is found on
        this table (then APPROACH), or go on to the next place."""
        p, p_WB, yaw, t = self.p, now.p_WB, now.yaw, now.t
        base_yaw = m.goal[2]
        want = base_yaw + math.radians(p.look_yaws_deg[m.look_k])
        e_yaw = _wrap(want - yaw)
        if abs(e_yaw) > math.radians(p.yaw_tolerance_deg):
            m.cmd = np.array([0.0, 0.0, min(max(p.approach_yaw_gain * e_yaw, -0.4), 0.4)])
            m.t_still = -1.0
            return
        taken, det = self._still_frame(m, now, context)
        if not taken:
            return
        tab = m.surfaces[m.place]
        if det is not None and tab.contains(det, p.search_margin) and abs(
                det[2] - tab.height) < ON_TOP_HEIGHT:
            m.p_WO = det
            self._refresh_place(m)
            m.log.append(f"{t:7.2f} found {self.instruction.target} at "
                            f"{np.round(det, 3).tolist()} on {m.place} "
                            f"({len(m.others)} other objects seen)")
            self._start_approach(m, p_WB, t)
            return
        if m.look_tries >= p.look_frames:
            m.look_tries = 0
            m.look_k += 1
            if m.look_k >= len(p.look_yaws_deg) and not self._look_again(m, p_WB, t):
                self._searched(m)
                self._next_place(m, p_WB, t)

    def _approach(self, m: SearchMemory, now: Now, context) -> None:
        if self._steps(m, now.p_WB, now.yaw) or self._close_enough(m, now.p_WB, now.yaw, now.t):
            m.cmd = np.zeros(3)
            self._go(m, Stage.SETTLE, now.t)
        elif self._approach_stalled(m, now):
            self._recover_pick_approach(m, now)

    def _settle(self, m: SearchMemory, now: Now, context) -> None:
        """Stand still, then the hand's path to the grasp point: up in front of the body,
        over the grasp point, onto it (first back out from under the top if it hangs there)."""
        p, p_WB, t = self.p, now.p_WB, now.t
        m.cmd = np.zeros(3)
        if not now.standing:
            m.t_stage = t
            return
        if t - m.t_stage < p.settle_time:
            return
        grasp = self._grasp_point(m, p.grasp_offset)
        # Up in front of the body first (the hand hangs below the table top).
        c, s_ = math.cos(now.yaw), math.sin(now.yaw)
        p_WH = self.model.hand_point(m.hand)[0]
        up = np.array([p_WB[0] + p.lift_forward * c, p_WB[1] + p.lift_forward * s_,
                       grasp[2] + p.pre_height])
        up[:2] += (p_WH[:2] - p_WB[:2]) - ((p_WH[:2] - p_WB[:2]) @ [c, s_]) * np.array(
            [c, s_])  # keep the hand's sideways offset
        path = [up, grasp + [0.0, 0.0, p.pre_height], grasp]
        back = out_from_under(p_WH, np.array([c, s_]), m.surfaces[m.place], p.edge_clearance)
        if back is not None:  # the body stopped short: the hand hangs under the top
            path.insert(0, back)
            if (up[:2] - p_WB[:2]) @ [c, s_] > (back[:2] - p_WB[:2]) @ [c, s_]:
                up[:2] = back[:2]
        self._start_hand_path(m, path, t)
        m.pick_tries = 0
        self._go(m, Stage.REACH, t)

    def _reach(self, m: SearchMemory, now: Now, context) -> None:
        if self._follow_hand(m, now.t):
            self._go(m, Stage.PICK, now.t)

    def _pick(self, m: SearchMemory, now: Now, context) -> None:
        """``pick`` until attached (then remember how the hand held it, and LIFT; another
        object than the target: let go and pick from another side); after ``pick_timeout``,
        try again nearer the object's centre, ``pick_tries`` in all."""
        p, p_WB, yaw, t = self.p, now.p_WB, now.yaw, now.t
        if now.pick.attached and now.pick.object != self.instruction.target:
            # The grasp latches the object nearest the hand: one beside the target was.
            m.log.append(f"{t:7.2f} the hand holds {now.pick.object}, not "
                         f"{self.instruction.target}: let go")
            self._pick_missed(m, p_WB, t, let_go=True)
        elif now.pick.attached:
            p_WH = self.model.hand_point(m.hand)[0]
            # Where the hand holds it, in the base's heading frame (x ahead, y left, z up):
            # placing with the arm as it was here keeps the object's tilt small, and the
            # hand's height over the table it stood on sets the place height (the detected
            # height is a few cm off).
            m.r_pick = in_heading(p_WB, yaw, p_WH)
            m.o_pick = in_heading(p_WB, yaw, m.p_WO)
            m.hand_over_top = float(p_WH[2] - m.surfaces[m.place].height)
            # The object's vertical in the hand frame: the QP keeps it vertical while it
            # is set down (it stood upright; round objects roll off when set down tilted).
            # Not while walking: against the carry pose, the arm's 4 joints cannot.
            m.up_H = self.model.hand_rotation(m.hand)[0].T @ np.array([0.0, 0.0, 1.0])
            self._start_hand_path(m, [p_WH + [0.0, 0.0, 0.10],
                                      self._carry_point(m, p_WB, yaw)], t)
            self._go(m, Stage.LIFT, t)
        elif t - m.t_stage > p.pick_timeout:
            m.pick_tries += 1
            if m.pick_tries >= p.pick_tries:
                self._pick_missed(m, p_WB, t)
            else:
                m.targets[m.hand] = self._grasp_point(
                    m, max(p.grasp_offset - 0.03 * m.pick_tries, 0.03))
                p_WH = self.model.hand_point(m.hand)[0]
                m.log.append(f"{t:7.2f} pick try {m.pick_tries}: hand "
                             f"{np.linalg.norm(p_WH - m.p_WO):.3f} from the object")
                m.t_stage = t
        else:
            m.pick = HANDS[m.hand]

    def _lift(self, m: SearchMemory, now: Now, context) -> None:
        if self._follow_hand(m, now.t):
            m.approach_tries = 0
            if self._plan_destination(m, now.p_WB, now.t):
                self._go(m, Stage.CARRY, now.t)
            else:
                m.failure = "no path to the destination"
                self._go(m, Stage.FAILED, now.t)

    def _check_held(self, m: SearchMemory, now: Now, context) -> None:
        """From the lift to the place: the object must stay in the hand, else FAILED."""
        if not now.pick.attached:
            m.failure = "the object fell from the hand"
            m.log.append(f"{now.t:7.2f} {m.failure}")
            m.targets = [None, None]
            m.up_H = None
            self._go(m, Stage.FAILED, now.t)

    def _carry(self, m: SearchMemory, now: Now, context) -> None:
        m.targets[m.hand] = self._carry_point(m, now.p_WB, now.yaw)
        if self._walk(m, now.p_WB, now.yaw, now.t):
            m.goal = self._place_pose(m, self.destination)
            self._go(m, Stage.APPROACH_TABLE, now.t)

    def _approach_table(self, m: SearchMemory, now: Now, context) -> None:
        m.targets[m.hand] = self._carry_point(m, now.p_WB, now.yaw)
        if self._steps(m, now.p_WB, now.yaw) or self._close_enough(m, now.p_WB, now.yaw, now.t):
            m.cmd = np.zeros(3)
            self._go(m, Stage.SETTLE_TABLE, now.t)
        elif self._approach_stalled(m, now):
            self._recover_place_approach(m, now)

    def _settle_table(self, m: SearchMemory, now: Now, context) -> None:
        m.cmd = np.zeros(3)
        m.targets[m.hand] = self._carry_point(m, now.p_WB, now.yaw)
        if not now.standing:
            m.t_stage = now.t
        elif now.t - m.t_stage >= self.p.settle_time:
            drop = self._place_drop(m, now)
            m.place_lower = m.place_pull = 0.0
            self._start_hand_path(m, [drop + [0.0, 0.0, 0.08], drop], now.t)
            self._go(m, Stage.PLACE, now.t)

    def _place(self, m: SearchMemory, now: Now, context) -> None:
        if self._follow_hand(m, now.t) and self._hand_down(m, now):
            self._go(m, Stage.RELEASE, now.t)

    def _release(self, m: SearchMemory, now: Now, context) -> None:
        m.release = True
        if now.pick.attached:
            m.t_stage = now.t
        elif now.t - m.t_stage >= self.p.release_hold:
            m.up_H = None
            p_WH = self.model.hand_point(m.hand)[0]
            self._start_hand_path(m, [p_WH + [0.0, 0.0, 0.10]], now.t)
            self._go(m, Stage.RETRACT, now.t)

    def _retract(self, m: SearchMemory, now: Now, context) -> None:
        if self._follow_hand(m, now.t):
            m.targets[m.hand] = None
            self._go(m, Stage.BACK, now.t)

    def _back(self, m: SearchMemory, now: Now, context) -> None:
        m.cmd = np.array([-self.p.back_speed, 0.0, 0.0])
        if now.t - m.t_stage >= self.p.back_time:
            n, m.retry_side = m.retry_side, None
            if n is None:  # placed: is it on the table? (.recovery)
                m.t_still, m.look_tries = -1.0, 0
                self._go(m, Stage.VERIFY if self.p.verify_frames > 0 else Stage.DONE, now.t)
            elif not self._walk_round(m, m.surfaces[m.place], n, now.p_WB, now.t):
                m.failure = "pick failed"
                self._go(m, Stage.FAILED, now.t)

    def _pick_missed(self, m: SearchMemory, p_WB, t: float, let_go: bool = False) -> None:
        """After ``pick_tries`` misses (or, ``let_go``, a pick of another object: RELEASE it
        first): hand up, step back and walk round to the next side of the top (nearest the
        object, with floor in front on the map, not tried yet); FAILED when there is none."""
        m.sides_tried.append(np.array(m.side, float))
        m.approach_tries = 0
        n = self._next_pick_side(m, m.surfaces[m.place])
        m.log.append(f"{t:7.2f} pick missed from side {np.round(m.side, 2).tolist()}; "
                     f"next side {None if n is None else np.round(n, 2).tolist()}")
        if n is None:
            m.failure = "pick failed"
            self._go(m, Stage.FAILED, t)
            return
        m.retry_side = n
        if let_go:  # RELEASE lifts the hand once the object is let go, then RETRACT
            self._go(m, Stage.RELEASE, t)
            return
        self._start_hand_path(m, [self.model.hand_point(m.hand)[0] + [0.0, 0.0, 0.10]], t)
        self._go(m, Stage.RETRACT, t)

    @staticmethod
    def _stand(m: SearchMemory, now: Now, context) -> None:
        m.cmd = np.zeros(3)


    # ---- moves and poses ---------------------------------------------------------------------
    def _go(self, m: SearchMemory, stage: Stage, t: float) -> None:
        m.log.append(f"{t:7.2f} {m.stage.name} -> {stage.name}")
        m.stage = stage
        m.t_stage = t
        m.best_err, m.t_best = math.inf, t  # the progress watch starts again

    def _look_side(self, m: SearchMemory, tab: Table) -> np.ndarray:
        """Outward normal (x, y) of the side of ``tab`` to look from: the best
        (:func:`~.tables.sides_by_preference`) not looked from yet (``m.look_sides``)."""
        sides = sides_by_preference(self._grid(m), tab, self.p.look_distance,
                                    self.nav.robot_radius)
        return next((n for n in sides if not any(np.allclose(n, u) for u in m.look_sides)),
                    sides[0])

    def _look_pose(self, m: SearchMemory, name: str) -> np.ndarray:
        """The pose ``look_distance`` out from top ``name``'s look side (:meth:`_look_side`),
        facing it."""
        tab = m.surfaces[name]
        n = self._look_side(m, tab)
        half, _, _ = tab.side_frame(n)
        xy = tab.center + n * (half + self.p.look_distance)
        return np.array([xy[0], xy[1], math.atan2(-n[1], -n[0])])

    def _place_pose(self, m: SearchMemory, tab: Table, back: float = 0.0) -> np.ndarray:
        """(x, y, yaw) facing ``tab`` across ``m.side`` from which, the arm as at the pick,
        the object is over the top's centre line ``place_inset`` inside its near edge (deeper
        if that would bring the base nearer than ``place_standoff`` to the edge; with
        ``back`` [m], the base at least that far from the edge)."""
        _, tan, _ = tab.side_frame(m.side)
        left = np.array([m.side[1], -m.side[0]])  # the robot's left facing -n
        ox, oy = float(m.o_pick[0]), float(m.o_pick[1])
        standoff = max(ox - self.p.place_inset, self.p.place_standoff, back)
        return pose_at(tab, m.side, -oy * float(left @ tan), standoff)

    def _drop_point(self, m: SearchMemory, p_WB, yaw: float, tab: Table) -> np.ndarray:
        """p_WH to release at: where the hand held the object at the pick relative to the base
        (heading frame), as high over ``tab``'s top as it was over the pick table's plus
        ``place_clearance`` (so the object's bottom is that far above the top) [m]."""
        c, s = math.cos(yaw), math.sin(yaw)
        rx, ry = float(m.r_pick[0]), float(m.r_pick[1])
        return np.array([p_WB[0] + c * rx - s * ry, p_WB[1] + s * rx + c * ry,
                         tab.height + m.hand_over_top + self.p.place_clearance])

    def _carry_point(self, m: SearchMemory, p_WB, yaw: float) -> np.ndarray:
        x, y, z = self.p.carry
        y = y if m.hand == 0 else -y
        c, s = math.cos(yaw), math.sin(yaw)
        return np.array([p_WB[0] + c * x - s * y, p_WB[1] + s * x + c * y, p_WB[2] + z])

    def _plan(self, m: SearchMemory, p_WB, goal: np.ndarray) -> bool:
        try:
            m.path = plan_path(self._grid(m), p_WB[:2], goal[:2], self.nav.robot_radius)
            m.path_version = m.map.version
            m.lenient = False
        except NoPathError as e:
            m.log.append(f"no path: {e}")
            m.path = None
            return False
        m.goal = goal
        return True

    def _steps(self, m: SearchMemory, p_WB, yaw: float) -> bool:
        """Proportional small steps onto ``m.goal``; True when there."""
        p = self.p
        ex, ey = heading_frame(yaw, m.goal[:2] - p_WB[:2])
        e_yaw = _wrap(m.goal[2] - yaw)
        if math.hypot(ex, ey) < p.position_tolerance and abs(e_yaw) < math.radians(
                p.yaw_tolerance_deg):
            m.cmd = np.zeros(3)
            return True
        s = p.approach_speed
        m.cmd = np.array([min(max(p.approach_gain * ex, -s), s),
                             min(max(p.approach_gain * ey, -s), s),
                             min(max(p.approach_yaw_gain * e_yaw, -0.4), 0.4)])
        return False

    def _close_enough(self, m: SearchMemory, p_WB, yaw: float, t: float) -> bool:
        """After ``approach_timeout`` of small steps (the table edge may stop the body short
        of the goal), within ``approach_accept`` [m] and twice the yaw tolerance is enough."""
        p = self.p
        return bool(t - m.t_stage > p.approach_timeout
                    and np.linalg.norm(m.goal[:2] - p_WB[:2]) < p.approach_accept
                    and abs(_wrap(m.goal[2] - yaw)) < 2 * math.radians(p.yaw_tolerance_deg))

    def _walk(self, m: SearchMemory, p_WB, yaw: float, t: float) -> bool:
        """Follow ``m.path`` to ``m.goal`` (planned again when the map shows it blocked); True
        within ``approach_radius`` of the goal, or of the path's end where the map moved that
        off the goal (:meth:`_path_end_reached`), or circling near it (:meth:`_walk_circles`).
        No path left: the stage gives its goal up (:meth:`_give_up_goal`)."""
        if np.linalg.norm(m.goal[:2] - p_WB[:2]) < self.p.approach_radius:
            return True
        if self._path_end_reached(m, p_WB, t):
            return True
        if self._walk_circles(m, p_WB, t):
            return True
        if self._path_blocked(m, p_WB) and not self._replan(m, p_WB, t):
            m.cmd = np.zeros(3)
            self._give_up_goal(m, p_WB, t)
            return False
        m.cmd = follow_velocity(m.path, p_WB, yaw, None, self.nav)
        return False

    def _grasp_point(self, m: SearchMemory, offset: float) -> np.ndarray:
        """``offset`` [m] from the object's centre (inside the pick distance): towards the
        hand's shoulder, not below the centre plus ``grasp_height``; but when another object
        seen would be less than ``grasp_margin`` farther from that point than the target (the
        pick latches the nearest object), the first of the other directions (turned about the
        target, then higher over it) that keeps that margin and stays within ``reach`` of the
        shoulder, else the one with the widest margin."""
        p = self.p
        o = m.p_WO
        s = self.model.shoulder_position(m.hand)
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
                margin = min((float(np.linalg.norm(g - q)) for q in m.others),
                             default=np.inf) - offset
                if margin >= p.grasp_margin and np.linalg.norm(g - s) <= p.reach:
                    return g
                key = (np.linalg.norm(g - s) <= p.reach, margin)
                if best_key is None or key > best_key:
                    best, best_key = g, key
        return best

    def _start_hand_path(self, m: SearchMemory, points: list, t: float) -> None:
        start = self.model.hand_point(m.hand)[0].copy()
        m.hand_path = [start] + [np.asarray(x, float) for x in points]
        m.hand_t0 = t

    def _follow_hand(self, m: SearchMemory, t: float, hold: float = 0.3) -> bool:
        """Move the hand target along ``m.hand_path`` (``reach_time`` per segment, smooth);
        True when its end has been held for ``hold`` [s]."""
        T = self.p.reach_time
        m.targets[m.hand], k = along_path(m.hand_path, m.hand_t0, t, T)
        return k >= len(m.hand_path) - 1 + hold / T

    def _start_approach(self, m: SearchMemory, p_WB, t: float) -> None:
        tab = m.surfaces[m.place]
        look = self._look_side(m, tab)
        # Stand at the side nearest the object (when there is room), else the look side.
        n = self._pick_side(m, tab, float(p_WB[2]))
        m.sides_tried = []
        m.approach_tries = 0
        if not np.allclose(n, look) and self._walk_round(m, tab, n, p_WB, t):
            return
        m.hand, m.pick_goal = self._pick_pose(m, tab, look, self.p.pick_standoff)
        m.side = look
        m.goal = m.pick_goal
        self._go(m, Stage.APPROACH, t)

    def _walk_round(self, m: SearchMemory, tab: Table, n: np.ndarray, p_WB, t: float) -> bool:
        """Walk to the pick pose across side ``n`` of ``tab`` (via its stage point), then
        APPROACH; False (nothing changed but the path) when no path reaches it."""
        hand, stage = self._pick_pose(m, tab, n, self.p.stage_distance)
        if not self._plan(m, p_WB, stage):
            return False
        m.hand, m.pick_goal = self._pick_pose(m, tab, n, self.p.pick_standoff)
        m.side = n
        m.nav_then = Stage.APPROACH
        self._go(m, Stage.NAVIGATE, t)
        return True

    def _next_pick_side(self, m: SearchMemory, tab: Table) -> Optional[np.ndarray]:
        """The side of ``tab`` not in ``m.sides_tried`` whose edge is nearest the object, with
        free floor (on the map inflated by the robot's radius) in front of the object; None
        when there is none."""
        d = m.p_WO[:2] - tab.center
        g = self._grid(m).inflated(self.nav.robot_radius)
        best, best_depth = None, math.inf
        for n in (np.array([1.0, 0.0]), np.array([-1.0, 0.0]), np.array([0.0, 1.0]),
                  np.array([0.0, -1.0])):
            if any(np.allclose(n, s) for s in m.sides_tried):
                continue
            half, tan, half_len = tab.side_frame(n)
            along = float(np.clip(d @ tan, -half_len, half_len))
            depth = half - float(d @ n)
            if depth < best_depth and g.free(
                    tab.center + n * (half + self.p.stage_distance) + tan * along):
                best, best_depth = n, depth
        return best

    def _pick_pose(self, m: SearchMemory, tab: Table, n: np.ndarray, standoff: float):
        """(hand, (x, y, yaw)): the hand on the object's side and the pose ``standoff`` from
        the edge across ``n``, facing the table, in line with the object but for
        ``hand_lateral`` (the hand's shoulder nearer it)."""
        _, tan, _ = tab.side_frame(n)
        along = float((m.p_WO[:2] - tab.center) @ tan)
        left = np.array([n[1], -n[0]])  # the robot's left when it faces -n
        hand = 0 if along * float(left @ tan) > 0 else 1
        sign = 1.0 if hand == 0 else -1.0
        along -= sign * self.p.hand_lateral * float(left @ tan)
        return hand, pose_at(tab, n, along, standoff)

    def _pick_side(self, m: SearchMemory, tab: Table, z_base: float) -> np.ndarray:
        """The look side, or, when the object is beyond reach from its pick pose (farther
        than ``pick_reach`` from the hand's shoulder there; the base at height ``z_base``),
        the side (of the four) whose edge is nearest the object, where there is floor to
        stand on in front of the object."""
        look = self._look_side(m, tab)
        d = m.p_WO[:2] - tab.center

        def depth(n: np.ndarray) -> float:
            return tab.side_frame(n)[0] - float(d @ n)

        if self._shoulder_to_object(m, tab, look, z_base) <= self.p.pick_reach:
            return look
        g = self._grid(m).inflated(self.nav.robot_radius)
        best, best_depth = look, depth(look) - 0.05  # walking round must gain something
        for n in (-look, np.array([-look[1], look[0]]), np.array([look[1], -look[0]])):
            half, tan, half_len = tab.side_frame(n)
            along = float(np.clip(d @ tan, -half_len, half_len))
            if depth(n) < best_depth and g.free(
                    tab.center + n * (half + self.p.stage_distance) + tan * along):
                best, best_depth = n, depth(n)
        return best

    def _shoulder_to_object(self, m: SearchMemory, tab: Table, n: np.ndarray,
                            z_base: float) -> float:
        """Distance [m] from the picking hand's shoulder, at the pick pose across ``n``, to
        the object (the shoulder's place in the base frame from the robot model)."""
        hand, (x, y, yaw) = self._pick_pose(m, tab, n, self.p.pick_standoff)
        r = self.p_BS[hand]
        c, s = math.cos(yaw), math.sin(yaw)
        p_WS = np.array([x + c * r[0] - s * r[1], y + s * r[0] + c * r[1], z_base + r[2]])
        return float(np.linalg.norm(p_WS - m.p_WO))

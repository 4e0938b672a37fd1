"""The task-6 search sequencer's recovery paths (issue 29): what a stage does when feedback shows
that it stalled or failed, instead of waiting on a condition that never comes
(:class:`RecoveryStages`, a part of
:class:`pr2_drake.agents.search.sequencer.ObjectSearchSequencer`).

Everything here reads what the agent observes (its base pose and joints through the robot
model, the map it made, the detections): no simulator state.

- Progress watch (:meth:`RecoveryStages._stalled`): a walk or an approach whose distance to
  its goal has not shrunk by a step for a while. Under randomised physics the gait can step
  sideways the other way than commanded (a base centre of mass 2 cm off to one side): the
  small steps of an approach then walk away from their goal for good, and a walk's pursuit
  circles its goal.
- A stalled approach settles where it stands when that pose serves (pick: the object within
  ``reach_accept`` of the picking hand's shoulder; place: the object, held as at the pick,
  over the top ``place_margin`` inside its edges), else (``approach_retries`` times in all) a
  place turns on the spot where a heading within ``place_turn_deg`` of facing the table brings
  the object over the top, and both walk there again on a path (forward walking steers out a
  sideways drift).
- A walk circling its goal (or its path's end) within ``walk_arrive`` ends there, and a walk
  at the end of a path that the map ends short of its goal (a standoff pose inside the grown
  obstacles) ends at once: the next stage's steps take over.
- No path to the destination: the other sides of the coffee table, then the same counting the
  map's weak obstacles (a few stray points over floor seen many times: depth noise) as free;
  no path to a stage's goal at all: the stage gives that goal up (the next top, the next side
  of the table, the next frontier) instead of standing.
- After a place (VERIFY, :meth:`RecoveryStages._verify`): the camera looks for the object
  (the arm, which hides it while placing, is down by then): seen resting on the coffee table,
  done; seen on another top (it fell there), picked up and placed again (``place_retries``);
  on the floor (out of the arm's reach) or not seen, FAILED with the reason.

Positions in m, world frame W; times in s.
"""

from __future__ import annotations

import math

import numpy as np

from pr2_drake.agents.search.memory import SearchMemory, Stage
from pr2_drake.agents.search.navigation import NoPathError, OccupancyGrid, plan_path
from pr2_drake.agents.search.tables import pose_at, sides_by_preference
from pr2_drake.agents.sequencer import Now


def _wrap(a: float) -> float:
    return math.atan2(math.sin(a), math.cos(a))


class RecoveryStages:
    """The recovery moves (module docstring). Uses the sequencer's ``p``, ``nav``, ``model``,
    ``destination`` and the stage moves of :class:`~.stages.SearchStages` and
    :class:`~.explore.ExploreStages`."""

    __slots__ = ()

    # ---- progress ----------------------------------------------------------------------------
    @staticmethod
    def _stalled(m: SearchMemory, err: float, t: float, step: float, wait: float) -> bool:
        """Track the least distance ``err`` [m] to the stage's goal (``m.best_err``, reset by
        each stage change); True when it has not shrunk by ``step`` [m] for ``wait`` [s]."""
        if err < m.best_err - step:
            m.best_err, m.t_best = err, t
            return False
        return t - m.t_best > wait

    def _path_end(self, m: SearchMemory) -> np.ndarray:
        """Where the walk's path ends (x, y) [m]: the free cell nearest the goal (the goal
        itself unless the map's grown obstacles cover it), or the goal with no path."""
        return m.goal[:2] if m.path is None else np.asarray(m.path[-1], float)

    def _path_end_reached(self, m: SearchMemory, p_WB, t: float) -> bool:
        """A path that ends farther than a map cell from its goal (a standoff pose inside the
        grown obstacles) is walked to its end (within ``approach_radius``): then on from
        there (True), logged; the path follower stops at that end, and without this the walk
        waited for the stall watch, or, farther than ``walk_arrive`` out, for ever."""
        end = self._path_end(m)
        short = float(np.linalg.norm(m.goal[:2] - end))
        if short <= self.mp.resolution or \
                np.linalg.norm(end - p_WB[:2]) >= self.p.approach_radius:
            return False
        m.log.append(f"{t:7.2f} at the path's end, {short:.2f} m short of its goal (the map's "
                     f"free space): on from here")
        return True

    def _walk_circles(self, m: SearchMemory, p_WB, t: float) -> bool:
        """A walk within ``walk_arrive`` of its goal or of its path's end that has not come
        ``walk_progress`` nearer the goal for ``walk_stall_time``: it ends there (True),
        logged."""
        p = self.p
        d = float(np.linalg.norm(m.goal[:2] - p_WB[:2]))
        near = min(d, float(np.linalg.norm(self._path_end(m) - p_WB[:2])))
        if self._stalled(m, d, t, p.walk_progress, p.walk_stall_time) and near < p.walk_arrive:
            m.log.append(f"{t:7.2f} walk stalled {d:.2f} m from its goal: on from here")
            return True
        return False

    def _approach_stalled(self, m: SearchMemory, now: Now) -> bool:
        """The approach has stalled farther than ``approach_accept`` from its goal (progress:
        the distance plus ``approach_yaw_weight`` times the heading error: turning counts)."""
        p = self.p
        dist = float(np.linalg.norm(m.goal[:2] - now.p_WB[:2]))
        err = dist + p.approach_yaw_weight * abs(_wrap(m.goal[2] - now.yaw))
        return self._stalled(m, err, now.t, p.approach_progress,
                             p.approach_stall_time) and dist > p.approach_accept

    def _heading_serves(self, m: SearchMemory, yaw: float) -> bool:
        return abs(_wrap(m.goal[2] - yaw)) < 2 * math.radians(self.p.yaw_tolerance_deg)

    # ---- approaches that stalled ------------------------------------------------------------
    def _pick_pose_serves(self, m: SearchMemory, now: Now) -> bool:
        """Facing the table (twice the yaw tolerance) with the object within ``reach_accept``
        of the picking hand's shoulder (the robot model at the observed state)."""
        d = float(np.linalg.norm(self.model.shoulder_position(m.hand) - m.p_WO))
        return self._heading_serves(m, now.yaw) and d <= self.p.reach_accept

    def _held_object_at(self, m: SearchMemory, p_WB, yaw: float) -> np.ndarray:
        """Where the held object would be (x, y) with the arm as at the pick [m]."""
        c, s = math.cos(yaw), math.sin(yaw)
        ox, oy = float(m.o_pick[0]), float(m.o_pick[1])
        return np.array([p_WB[0] + c * ox - s * oy, p_WB[1] + s * ox + c * oy])

    def _object_over_top(self, m: SearchMemory, p_WB, yaw: float) -> bool:
        """With the base at p_WB, heading ``yaw`` within ``place_turn_deg`` of facing the
        table across ``m.side``, the object (the arm as at the pick) over the destination
        ``place_margin`` inside its edges."""
        facing = math.atan2(-m.side[1], -m.side[0])
        return abs(_wrap(yaw - facing)) <= math.radians(self.p.place_turn_deg) and \
            self.destination.contains(self._held_object_at(m, p_WB, yaw), -self.p.place_margin)

    def _place_turn(self, m: SearchMemory, now: Now):
        """The heading nearest the robot's (in steps of 2.5 deg) at which, standing where it
        stands, the object is over the top (:meth:`_object_over_top`); None if none is."""
        for k in range(int(2 * self.p.place_turn_deg / 2.5) + 1):
            for sign in ((1.0,) if k == 0 else (1.0, -1.0)):
                yaw = now.yaw + sign * math.radians(2.5 * k)
                if self._object_over_top(m, now.p_WB, yaw):
                    return _wrap(yaw)
        return None

    def _recover_pick_approach(self, m: SearchMemory, now: Now) -> None:
        """A stalled approach to the pick pose: settle if the object is within reach; else walk
        round to the pose again (``approach_retries`` times); then settle anyway (the pick's
        own tries and sides decide)."""
        err = float(np.linalg.norm(m.goal[:2] - now.p_WB[:2]))
        what = f"{now.t:7.2f} approach stalled {err:.2f} m from the pick pose"
        if self._pick_pose_serves(m, now):
            m.log.append(f"{what}: the object is within reach, settle")
        elif m.approach_tries < self.p.approach_retries and self._walk_round(
                m, m.surfaces[m.place], m.side, now.p_WB, now.t):
            m.approach_tries += 1
            m.log.append(f"{what}: walk there again ({m.approach_tries})")
            return
        else:
            m.log.append(f"{what}: settle anyway")
        m.cmd = np.zeros(3)
        self._go(m, Stage.SETTLE, now.t)

    def _recover_place_approach(self, m: SearchMemory, now: Now) -> None:
        """A stalled approach to the place pose: settle if the object is over the top; else
        (``approach_retries`` times) turn on the spot to a heading that brings it there, or
        carry it on a path to the place pose set back to ``stage_distance``; then FAILED."""
        t, p = now.t, self.p
        err = float(np.linalg.norm(m.goal[:2] - now.p_WB[:2]))
        what = f"{t:7.2f} approach stalled {err:.2f} m from the place pose"
        yaw = None if m.approach_tries >= p.approach_retries else self._place_turn(m, now)
        if self._object_over_top(m, now.p_WB, now.yaw):
            m.log.append(f"{what}: the object is over the top, settle")
            m.cmd = np.zeros(3)
            self._go(m, Stage.SETTLE_TABLE, t)
        elif yaw is not None:
            m.approach_tries += 1
            m.log.append(f"{what}: turn to {math.degrees(yaw):.0f} deg, the object over the "
                         f"top ({m.approach_tries})")
            self._go(m, Stage.APPROACH_TABLE, t)
            m.goal = np.array([now.p_WB[0], now.p_WB[1], yaw])
        elif m.approach_tries < p.approach_retries and self._plan(
                m, now.p_WB, self._place_pose(m, self.destination, p.stage_distance)):
            m.approach_tries += 1
            m.log.append(f"{what}: carry it there again ({m.approach_tries})")
            self._go(m, Stage.CARRY, t)
        else:
            m.failure = "the place pose was not reached"
            m.log.append(f"{what}: {m.failure}")
            self._go(m, Stage.FAILED, now.t)

    def _place_drop(self, m: SearchMemory, now: Now) -> np.ndarray:
        """p_WH to release at: the drop point where the base stands (:meth:`_drop_point`), the
        hand moved (horizontally, by at most ``place_reach`` [m]) to where the place pose
        ``m.goal`` would hold the object, at least ``place_inset`` inside the near edge. The
        approach accepts a base ``approach_accept`` off its pose, and the base keeps
        ``place_standoff`` from the edge: without this a flat object held near the body was set
        down over the edge, propped on the thigh, and fell when the robot stepped back."""
        tab, p = self.destination, self.p
        here = self._drop_point(m, now.p_WB, now.yaw, tab)
        want = self._drop_point(m, m.goal[:2], m.goal[2], tab)
        n = np.asarray(m.side, float)  # the near edge's outward normal
        half = tab.side_frame(n)[0]
        depth = half - float(n @ (self._held_object_at(m, m.goal[:2], m.goal[2]) - tab.center))
        want[:2] -= n * max(p.place_inset - depth, 0.0)
        shift = want[:2] - here[:2]
        norm = float(np.linalg.norm(shift))
        if norm > p.place_reach:
            shift *= p.place_reach / norm
        if norm > 0.01:
            m.log.append(f"{now.t:7.2f} place: the hand reaches {np.linalg.norm(shift):.2f} m "
                         f"towards the planned drop ({norm:.2f} m off where the base stands)")
        here[:2] += shift
        return here

    def _hand_down(self, m: SearchMemory, now: Now) -> bool:
        """At the end of a place's hand path (the drop point): True once the hand, as
        measured, is within ``place_tolerance`` above the drop point, or ``place_settle_time``
        after the path ended (logged); until then the hand's target moves down by
        ``place_gain`` times the height error per second, at most ``place_lower_max``: the
        hand tracks its target a few cm high when the arm's load is heavier or its motors
        weaker than the model's, and the object would drop that far. Lowered that far and
        still high, the target is drawn back horizontally towards the base at the same rate,
        at most ``place_pull_max``: a target the base stopped short of lies beyond the arm's
        reach (the controller clips it onto a sphere about the shoulder), and an apple
        dropped from 1.6 cm rolled off the table."""
        p = self.p
        drop = np.asarray(m.hand_path[-1], float)
        error = float(self.model.hand_point(m.hand)[0][2] - drop[2])
        ended = m.hand_t0 + p.reach_time * (len(m.hand_path) - 1)  # the target got there
        if error <= p.place_tolerance or now.t - ended >= p.place_settle_time:
            if m.place_lower > 0.0:
                m.log.append(f"{now.t:7.2f} place: the hand {error:+.3f} m off its drop point, "
                             f"its target moved {m.place_lower:.3f} m down and "
                             f"{m.place_pull:.3f} m back")
            return True
        step = p.place_gain * error * p.period
        if m.place_lower >= p.place_lower_max:
            m.place_pull = min(m.place_pull + step, p.place_pull_max)
        m.place_lower = min(m.place_lower + step, p.place_lower_max)
        back = np.asarray(now.p_WB[:2], float) - drop[:2]
        back *= m.place_pull / max(float(np.linalg.norm(back)), 1e-9)
        m.targets[m.hand] = drop + [back[0], back[1], -m.place_lower]
        return False

    # ---- after a place ----------------------------------------------------------------------
    def _verify(self, m: SearchMemory, now: Now, context) -> None:
        """Stand still, take frames as a look does (``verify_frames``); the object seen:
        :meth:`_placed_seen`; not seen in any: FAILED."""
        p, t = self.p, now.t
        taken, det = self._still_frame(m, now, context)
        if not taken:
            return
        if det is not None:
            self._placed_seen(m, now, det)
        elif m.look_tries >= p.verify_frames:
            m.failure = "the placed object was not seen on the table"
            m.log.append(f"{t:7.2f} {m.failure}")
            self._go(m, Stage.FAILED, t)

    def _placed_seen(self, m: SearchMemory, now: Now, det: np.ndarray) -> None:
        """The object seen at ``det`` (its centre, W) after a place: resting on the destination
        (inside its top, the centre ``verify_height`` from the top plus half the object's
        height): DONE; on another top of the map: pick it up again (``place_retries``); else
        (the floor): FAILED."""
        t, p = now.t, self.p
        where = np.round(det, 3).tolist()

        def rests_on(tab, margin: float) -> bool:
            return tab.contains(det, margin) and abs(
                det[2] - tab.height - 0.5 * self.object_height) < p.verify_height

        if rests_on(self.destination, 0.0):
            m.log.append(f"{t:7.2f} placed: seen resting on the destination at {where}")
            self._go(m, Stage.DONE, t)
            return
        top = next((s for s in m.map.surfaces(self.mp) if rests_on(s, p.search_margin)), None)
        if top is None or m.place_tries >= p.place_retries:
            m.failure = ("the placed object fell off the table" if top is None
                         else "the placed object fell off the table again")
            m.log.append(f"{t:7.2f} {m.failure}: seen at {where}")
            self._go(m, Stage.FAILED, t)
            return
        m.place_tries += 1
        m.log.append(f"{t:7.2f} the placed object is on a top at {np.round(top.center, 2)}"
                     f" ({where}): pick it up again ({m.place_tries})")
        m.surfaces["fallen"] = top
        m.place, m.p_WO, m.others = "fallen", np.asarray(det, float), []
        self._start_approach(m, now.p_WB, t)

    # ---- paths -------------------------------------------------------------------------------
    def _nav_grid(self, m: SearchMemory) -> OccupancyGrid:
        """The grid paths are planned and checked on: the map's (:meth:`_grid`), or without its
        weak obstacles when the path was planned so (``m.lenient``)."""
        return self._lenient_grid(m) if m.lenient else self._grid(m)

    def _lenient_grid(self, m: SearchMemory) -> OccupancyGrid:
        """The map's grid without its weak obstacles (``weak_obstacle``, ``weak_floor_ratio``),
        the coffee table of the priors occupied."""
        g = m.map.grid_without_weak(self.p.weak_obstacle, self.p.weak_floor_ratio)
        d = self.destination
        box = np.all(np.abs(g.cell_centers() - d.center) <= d.size / 2, axis=-1)
        return OccupancyGrid(g.occupied | box, g.origin, g.resolution)

    def _plan_destination(self, m: SearchMemory, p_WB, t: float) -> bool:
        """Plan to the pose ``look_distance`` out from a side of the destination: its sides best
        first (:func:`~.tables.sides_by_preference`) on the map, then on the map without its
        weak obstacles; sets ``m.side``, ``m.goal``, ``m.path``. False: no path to any."""
        tab, p = self.destination, self.p
        sides = sides_by_preference(self._grid(m), tab, p.look_distance, self.nav.robot_radius)
        for lenient in (False, True):
            grid = self._lenient_grid(m) if lenient else self._grid(m)
            for n in sides:
                goal = pose_at(tab, n, 0.0, p.look_distance)
                try:
                    path = plan_path(grid, p_WB[:2], goal[:2], self.nav.robot_radius)
                except NoPathError:
                    continue
                if lenient:
                    m.log.append(f"{t:7.2f} a path to the destination past weak obstacles")
                m.path, m.path_version, m.lenient = path, m.map.version, lenient
                m.side, m.goal = n, goal
                return True
        m.log.append(f"{t:7.2f} no path to any side of the destination")
        m.path = None
        return False

    def _give_up_goal(self, m: SearchMemory, p_WB, t: float) -> None:
        """No path is left to the stage's goal: give it up (the next top to search, the next
        side to pick from, the next frontier) instead of standing; FAILED while carrying."""
        m.log.append(f"{t:7.2f} no path left to {np.round(m.goal[:2], 2).tolist()}: give it up")
        if m.stage == Stage.CARRY:
            m.failure = "no path to the destination"
            self._go(m, Stage.FAILED, t)
        elif m.nav_then == Stage.LOOK and m.place is not None:
            self._searched(m)
            self._next_place(m, p_WB, t)
        elif m.nav_then == Stage.APPROACH:
            self._pick_missed(m, p_WB, t)
        else:
            self._explore(m, p_WB, t)

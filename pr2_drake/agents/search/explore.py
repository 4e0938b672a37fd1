"""The task-6 search sequencer's map-making stages: a scan on the spot, the map fed from the head
camera's depth as the robot goes, the order in which the tops seen are searched, paths planned
again when the map shows them blocked, and exploring when no top is left (:class:`ExploreStages`,
a part of :class:`pr2_drake.agents.search.sequencer.ObjectSearchSequencer`).

What the agent may know of the house: the priors (the objects' models, the coffee table's
centre, size and height, the sentence), the arena, the camera, and what holds in every house of
the task (its own and every generated one): the robot starts in the target's room, every piece
of furniture keeps its size and height, walls and furniture are axis-aligned. Nothing else of
the layout: walls, doorways, tables and decor are found in the map.
Positions in m, world frame W.
"""

from __future__ import annotations

import math
from typing import Optional

import numpy as np
from pydrake.math import RigidTransform

from pr2_drake.agents.search.memory import SearchMemory, Stage
from pr2_drake.agents.search.navigation import OccupancyGrid
from pr2_drake.agents.search.tables import Table, seen_on, surface_order
from pr2_drake.agents.sequencer import Now


def _wrap(a: float) -> float:
    return math.atan2(math.sin(a), math.cos(a))


class ExploreStages:
    """The mapping stages and moves (module docstring). Uses the sequencer's ``p``, ``mp``
    (MappingParams), ``nav``, ``K`` (camera intrinsics), ``kin``, ``camera_period``,
    ``destination``, ``expected_height``, ``instruction`` and the stage moves of
    :class:`~.stages.SearchStages`."""

    __slots__ = ()

    # ---- the map -----------------------------------------------------------------------------
    def _grid(self, m: SearchMemory) -> OccupancyGrid:
        return m.map.grid()

    def _integrate(self, m: SearchMemory, now: Now, context) -> None:
        """Feed a new camera frame to the map (with the camera pose of the update at the time
        it was rendered), look for the target in it while scanning; remember the camera pose
        of this update if a frame is rendered now; decide whether the next sample renders."""
        frame = self._rgbd.Eval(context)
        if frame.depth.size and frame.time > m.frame_time + 1e-9:
            X = next((X for t, X in m.poses if abs(t - frame.time) < 1e-6), None)
            X_WC = RigidTransform(X) if X is not None else self._camera_pose(context)
            m.frame_time = frame.time
            m.map = m.map.integrate(frame.depth, X_WC, self.K, now.p_WB, self.mp)
            m.frames += 1
            if m.stage == Stage.SCAN and m.frames % max(1, self.p.scan_detect_every) == 0:
                hit = self._find(m, frame, X_WC)
                if hit is not None:
                    m.hints.append(hit)
                    m.log.append(f"{now.t:7.2f} scan: {self.instruction.target} seen near "
                                 f"{np.round(hit, 2).tolist()}")
        if m.capture and self._on_sample(now.t):
            m.poses = [(now.t, self._camera_pose(context).GetAsMatrix4())] + m.poses[:3]
        every = {Stage.LOOK: 1, Stage.VERIFY: 1, Stage.SCAN: self.p.scan_capture_every}.get(
            m.stage, self.p.walk_capture_every if m.stage in (Stage.NAVIGATE, Stage.CARRY)
            else 0)
        m.capture = bool(every) and self._sample_index(now.t + self.p.period) % every == 0 \
            and self._on_sample(now.t + self.p.period)
        m.capture_color = self._detector_may_see(m, now)

    def _detector_may_see(self, m: SearchMemory, now: Now) -> bool:
        """Whether the next frame may reach the detector: frames rendered while scanning
        (:meth:`_integrate`) or checking a place (VERIFY), those of a look from ``color_lead``
        before its detection (:meth:`_look` detects on the frame of the update
        :meth:`_frame_wait` after the robot stood still: that frame may be 0.2 s old, a sample
        skipped where the 10 Hz sample times fall just after the 50 Hz update times in
        floating point), and those of the walk to a scan's spot rendered near its end (the
        stage may turn to SCAN before such a frame is mapped; a scan's spot is
        ``explore_distance`` away when it is chosen). Other frames only feed the map."""
        p = self.p
        if m.stage in (Stage.SCAN, Stage.VERIFY):
            return True
        if m.stage == Stage.LOOK:
            return bool(m.t_still >= 0
                        and now.t - m.t_still >= self._frame_wait(m) - p.color_lead)
        return bool(m.stage == Stage.NAVIGATE and m.nav_then == Stage.SCAN
                    and np.linalg.norm(m.goal[:2] - now.p_WB[:2])
                    < p.approach_radius + p.color_margin)

    def _sample_index(self, t: float) -> int:
        return int(round(t / self.camera_period))

    def _on_sample(self, t: float) -> bool:
        return abs(t / self.camera_period - round(t / self.camera_period)) < 1e-6

    # ---- the stages --------------------------------------------------------------------------
    def _scan(self, m: SearchMemory, now: Now, context) -> None:
        """Turn on the spot through ``scan_turn_deg`` at ``scan_rate``, mapping; then search."""
        if m.scan_yaw is None:
            m.scan_yaw, m.scan_turned = now.yaw, 0.0
        m.scan_turned += _wrap(now.yaw - m.scan_yaw)
        m.scan_yaw = now.yaw
        if abs(m.scan_turned) >= math.radians(self.p.scan_turn_deg):
            m.cmd = np.zeros(3)
            m.scan_yaw = None
            self._next_place(m, now.p_WB, now.t)
        else:
            m.cmd = np.array([0.0, 0.0, self.p.scan_rate])

    def _next_place(self, m: SearchMemory, p_WB, t: float) -> None:
        """Walk to the look pose of the most likely top not yet searched (:func:`surface_order`);
        none left: explore; nothing left to explore: FAILED."""
        tops = [s for s in m.map.surfaces(self.mp) if not self._excluded(m, s)]
        order = surface_order(tops, m.hints, self.expected_height, p_WB, self.p)
        m.surfaces = {s.name: s for s in order}
        m.look_sides = []
        for s in order:
            goal = self._look_pose(m, s.name)
            if self._plan(m, p_WB, goal):
                m.place = s.name
                m.look_k = 0
                m.nav_then = Stage.LOOK
                m.log.append(f"{t:7.2f} search the top at {np.round(s.center, 2).tolist()} "
                             f"({s.height:.2f} m high)")
                self._go(m, Stage.NAVIGATE, t)
                return
        self._explore(m, p_WB, t)

    def _look_again(self, m: SearchMemory, p_WB, t: float) -> bool:
        """After a look that found nothing: when the target was seen on this top while
        scanning (a hint, as :func:`surface_order` counts them), walk to its next side
        (``look_sides`` in all) and look again: another object can hide it from one side.
        False when there is none left (or no path to it)."""
        tab = m.surfaces[m.place]
        if not any(seen_on(tab, h, self.p.search_margin) for h in m.hints):
            return False
        # The side just looked from: the look pose faces the top (the map grown since may
        # rank the sides otherwise now).
        m.look_sides.append(np.array([-math.cos(m.goal[2]), -math.sin(m.goal[2])]))
        while len(m.look_sides) < self.p.look_sides:
            goal = self._look_pose(m, m.place)
            if self._plan(m, p_WB, goal):
                m.look_k = 0
                m.nav_then = Stage.LOOK
                m.log.append(f"{t:7.2f} {self.instruction.target} not seen on the top at "
                             f"{np.round(tab.center, 2).tolist()}, where the scan saw it: "
                             f"look from another side")
                self._go(m, Stage.NAVIGATE, t)
                return True
            m.look_sides.append(self._look_side(m, tab))
        return False

    def _excluded(self, m: SearchMemory, s: Table) -> bool:
        """The destination, and the tops searched already."""
        d = self.destination
        if np.all(np.abs(s.center - d.center) < (s.size + d.size) / 2 + 0.1):
            return True
        return any(s.contains(c, self.p.searched_margin) for c in m.searched)

    def _explore(self, m: SearchMemory, p_WB, t: float) -> None:
        """Walk to the nearest frontier (free floor next to unknown) at least
        ``explore_distance`` away and scan there; FAILED after ``explore_max`` of them."""
        if m.explored < self.p.explore_max:
            far = [f for f in m.map.frontiers(self.mp)
                   if np.linalg.norm(f - p_WB[:2]) >= self.p.explore_distance]
            far.sort(key=lambda f: float(np.linalg.norm(f - p_WB[:2])))
            for f in far:
                yaw = math.atan2(f[1] - p_WB[1], f[0] - p_WB[0])
                if self._plan(m, p_WB, np.array([f[0], f[1], yaw])):
                    m.explored += 1
                    m.place = None
                    m.nav_then = Stage.SCAN
                    m.log.append(f"{t:7.2f} explore towards {np.round(f, 2).tolist()}")
                    self._go(m, Stage.NAVIGATE, t)
                    return
        m.failure = f"target {self.instruction.target!r} not found on any table"
        self._go(m, Stage.FAILED, t)

    def _refresh_place(self, m: SearchMemory) -> None:
        """The top being searched as the map shows it now (the look saw it whole)."""
        old = m.surfaces[m.place]
        for s in m.map.surfaces(self.mp):
            if abs(s.height - old.height) < self.p.height_tolerance and np.all(
                    np.abs(s.center - old.center) < (s.size + old.size) / 2):
                m.surfaces[m.place] = Table(old.name, s.center, s.size, s.height)
                return

    def _searched(self, m: SearchMemory) -> None:
        """The top looked at holds no target: never again."""
        m.searched.append(np.array(m.surfaces[m.place].center))

    # ---- paths -------------------------------------------------------------------------------
    def _path_blocked(self, m: SearchMemory, p_WB) -> bool:
        """Whether the map, since the path was planned, shows an obstacle on what is left of
        it (farther than ``blocked_distance`` from the robot: near it, the path leaves the
        furniture it starts by)."""
        if m.path is None or m.path_version == m.map.version:
            return False
        m.path_version = m.map.version
        g = self._nav_grid(m).inflated(self.nav.robot_radius)
        p = np.asarray(p_WB[:2], float)
        path = np.asarray(m.path, float)
        k = max(0, int(np.argmin(np.linalg.norm(path - p, axis=1))) - 1)
        for a, b in zip(path[k:], path[k + 1:]):
            n = max(2, int(np.linalg.norm(b - a) / 0.05))
            for s in np.linspace(0.0, 1.0, n):
                q = a + s * (b - a)
                if np.linalg.norm(q - p) > self.p.blocked_distance and not g.free(q):
                    return True
        return False

    def _replan(self, m: SearchMemory, p_WB, t: float) -> bool:
        """Plan again to the stage's goal (recomputed for a look or a place pose, whose
        table may now be better known); False when no path is left."""
        goal = m.goal
        m.log.append(f"{t:7.2f} path blocked: plan again")
        if m.stage == Stage.CARRY:
            return self._plan_destination(m, p_WB, t)
        if m.stage == Stage.NAVIGATE and m.nav_then == Stage.LOOK and m.place is not None:
            goal = self._look_pose(m, m.place)
        return self._plan(m, p_WB, goal)

    # ---- the camera --------------------------------------------------------------------------
    def _camera_pose(self, context):
        return self.kin.camera_pose(self._bs.Eval(context), self._js.Eval(context))

    def _find(self, m: SearchMemory, frame, X_WC) -> Optional[np.ndarray]:
        """The target's centre in this frame (W), or None."""
        target = self.instruction.target
        if frame.color.size == 0:  # a depth-only frame (see _detector_may_see): not seen
            return None
        if hasattr(self.detector, "detect"):
            found = self.detector.detect(frame.color, frame.depth, X_WC)
            hit = next((d for d in found if d.label == target), None)
            if hit is not None and m.stage == Stage.LOOK:
                m.others = [np.asarray(d.p_WO, float) for d in found if d is not hit]
        else:
            hit = self.detector.find(frame.color, frame.depth, X_WC, target)
        return None if hit is None else np.asarray(hit.p_WO, float)


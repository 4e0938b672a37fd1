"""Getting around the task-6 house: occupancy grid, A* paths, a path-following velocity source.

The search agent's grid comes from its map (:meth:`~.mapping.HeightMap.grid`: what the head
camera has seen). :meth:`OccupancyGrid.from_scene` builds one from a scene description instead
(the ``scene`` block of ``tasks/6_object_search.yaml`` or of a generated house: wall segments
and thickness, table footprints, decor boxes), for tests and tools that check a layout.

- :class:`OccupancyGrid`: a 2-D boolean grid over the arena, world frame W (x east, y north),
  cell (i, j) covers x in [x0 + j r, x0 + (j+1) r), y in [y0 + i r, ...), r = resolution [m].
- :func:`plan_path`: A* (8-connected, octile heuristic) on the grid inflated by the robot's
  radius, then shortcut by line of sight; returns waypoints (x, y) [m] in W.
- :class:`PathFollower`: a LeafSystem ``body_state`` -> ``velocity_command`` (vx, vy, yaw
  rate in the heading frame, like :class:`~pr2_drake.agents.walk_to_goal.GoalVelocityPlanner`)
  that pursues a point ``lookahead`` ahead along the path, stops at its end and then turns to
  an optional final heading. The path lives in the context (``set_path``).
"""

import heapq
import math
from dataclasses import dataclass
from typing import ClassVar, Optional

import cv2
import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, LeafSystem

from pr2_drake.agents.walk_to_goal import GoalPlannerParams, goal_velocity, yaw_from_quaternion
from pr2_drake.lifetime import weak_calc
from pr2_drake.params import Params
from pr2_drake.ports import BODY_STATE_SIZE, P_WB, QUAT_WB



class NoPathError(RuntimeError):
    """No collision-free path between the two points; the message says which end is blocked."""


@dataclass(frozen=True)
class Box2:
    """An axis-aligned obstacle rectangle in W: centre (x, y) and size (x, y) [m]."""

    center: tuple[float, float]
    size: tuple[float, float]
    name: str = ""

    def distance(self, p: np.ndarray) -> np.ndarray:
        """Distance [m] from points p (..., 2) to the rectangle (0 inside)."""
        d = np.abs(np.asarray(p, float) - self.center) - np.asarray(self.size) / 2
        return np.linalg.norm(np.maximum(d, 0.0), axis=-1)


def house_obstacles(scene: dict) -> list[Box2]:
    """Walls, tables and decor of the task YAML's ``scene`` block as rectangles."""
    t = float(scene["walls"]["thickness"])
    out = []
    for k, (p0, p1) in enumerate(scene["walls"]["segments"]):
        p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
        size = np.abs(p1 - p0) + t
        out.append(Box2(tuple((p0 + p1) / 2), tuple(size), f"wall_{k}"))
    for name, f in scene["furniture"].items():
        out.append(Box2(tuple(f["center"]), tuple(f["size"]), name))
    for d in scene.get("decor", []):
        out.append(Box2(tuple(d["center"]), tuple(d["size"][:2]), d["name"]))
    return out


@dataclass
class OccupancyGrid:
    """Occupied cells (True) over [x0, x0 + cols r) x [y0, y0 + rows r) in W."""

    occupied: np.ndarray
    origin: tuple[float, float]
    resolution: float

    @staticmethod
    def from_obstacles(obstacles: list[Box2], lo, hi, resolution: float = 0.05) -> "OccupancyGrid":
        """Cells whose centre is inside an obstacle, or outside [lo, hi] (the arena)."""
        lo, hi = np.asarray(lo, float), np.asarray(hi, float)
        cols, rows = np.ceil((hi - lo) / resolution).astype(int)
        grid = OccupancyGrid(np.zeros((rows, cols), bool), (float(lo[0]), float(lo[1])),
                             float(resolution))
        centers = grid.cell_centers()
        for box in obstacles:
            grid.occupied |= box.distance(centers) <= 0.0
        return grid

    @staticmethod
    def from_scene(scene: dict, resolution: float = 0.05) -> "OccupancyGrid":
        """The house's fixed layout (task YAML ``scene`` block) within its arena."""
        arena = scene.get("arena") or {"min": [-4.0, -4.0], "max": [4.0, 4.0]}
        return OccupancyGrid.from_obstacles(house_obstacles(scene), arena["min"], arena["max"],
                                            resolution)

    def cell_centers(self) -> np.ndarray:
        rows, cols = self.occupied.shape
        x = self.origin[0] + (np.arange(cols) + 0.5) * self.resolution
        y = self.origin[1] + (np.arange(rows) + 0.5) * self.resolution
        return np.stack(np.meshgrid(x, y), axis=-1)

    def cell(self, p) -> tuple[int, int]:
        """(row, col) of the cell holding point p = (x, y) [m]."""
        j = int(math.floor((p[0] - self.origin[0]) / self.resolution))
        i = int(math.floor((p[1] - self.origin[1]) / self.resolution))
        return i, j

    def center(self, cell) -> np.ndarray:
        i, j = cell
        return np.array([self.origin[0] + (j + 0.5) * self.resolution,
                         self.origin[1] + (i + 0.5) * self.resolution])

    def inside(self, cell) -> bool:
        return 0 <= cell[0] < self.occupied.shape[0] and 0 <= cell[1] < self.occupied.shape[1]

    def free(self, p) -> bool:
        c = self.cell(p)
        return self.inside(c) and not self.occupied[c]

    def inflated(self, radius: float) -> "OccupancyGrid":
        """Cells within ``radius`` [m] of an occupied cell become occupied too."""
        free = (~self.occupied).astype(np.uint8)
        dist = cv2.distanceTransform(free, cv2.DIST_L2, 5) * self.resolution
        return OccupancyGrid(dist <= radius, self.origin, self.resolution)


@dataclass
class NavigationParams(Params):
    """See params/agents/search_navigation.yaml (m, m/s, rad/s)."""

    FILE: ClassVar[str] = "params/agents/search_navigation.yaml"
    resolution: float = 0.05
    robot_radius: float = 0.32
    lookahead: float = 0.35
    goal_tolerance: float = 0.10
    heading_tolerance: float = 0.08
    forward_speed: float = 0.25
    max_yaw_rate: float = 0.4
    yaw_gain: float = 1.2
    slow_radius: float = 0.4
    turn_in_place_angle: float = 0.6



def _nearest_free(grid: OccupancyGrid, cell, max_cells: int = 40):
    """The free cell nearest ``cell`` (within max_cells), or None."""
    if grid.inside(cell) and not grid.occupied[cell]:
        return cell
    free = np.argwhere(~grid.occupied)
    if len(free) == 0:
        return None
    d = np.abs(free - np.asarray(cell)).max(axis=1)
    k = int(np.argmin(np.linalg.norm(free - np.asarray(cell), axis=1)))
    return tuple(int(v) for v in free[k]) if d[k] <= max_cells else None


def line_free(grid: OccupancyGrid, a, b) -> bool:
    """The segment a -> b [m] crosses no occupied cell (sampled at a quarter cell)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    n = max(2, int(np.linalg.norm(b - a) / (0.25 * grid.resolution)) + 1)
    return all(grid.free(a + s * (b - a)) for s in np.linspace(0.0, 1.0, n))


def plan_path(grid: OccupancyGrid, start, goal, radius: float = 0.32) -> np.ndarray:
    """Waypoints (N x 2) [m] from ``start`` to ``goal`` keeping ``radius`` from obstacles.

    A start or goal inside the inflated obstacles is moved to the nearest free cell (the robot
    may start close to a wall; a standoff pose may hug a table). Raises :class:`NoPathError`.
    """
    g = grid.inflated(radius)
    s = _nearest_free(g, g.cell(start))
    t = _nearest_free(g, g.cell(goal))
    if s is None or t is None:
        raise NoPathError(f"no free cell near the {'start' if s is None else 'goal'} "
                          f"{np.round(start if s is None else goal, 2).tolist()}")
    steps = [(di, dj, math.hypot(di, dj)) for di in (-1, 0, 1) for dj in (-1, 0, 1)
             if di or dj]

    def h(c):
        di, dj = abs(c[0] - t[0]), abs(c[1] - t[1])
        return max(di, dj) + (math.sqrt(2) - 1) * min(di, dj)

    cost = {s: 0.0}
    parent = {s: None}
    heap = [(h(s), 0.0, s)]
    rows, cols = g.occupied.shape
    while heap:
        _, c_cost, c = heapq.heappop(heap)
        if c == t:
            break
        if c_cost > cost[c]:
            continue
        for di, dj, step in steps:
            n = (c[0] + di, c[1] + dj)
            if not (0 <= n[0] < rows and 0 <= n[1] < cols) or g.occupied[n]:
                continue
            if di and dj and (g.occupied[c[0] + di, c[1]] or g.occupied[c[0], c[1] + dj]):
                continue  # no corner cutting
            new = c_cost + step
            if new < cost.get(n, math.inf):
                cost[n] = new
                parent[n] = c
                heapq.heappush(heap, (new + h(n), new, n))
    if t not in parent:
        raise NoPathError(f"no path from {np.round(start, 2).tolist()} to "
                          f"{np.round(goal, 2).tolist()}")
    cells = [t]
    while parent[cells[-1]] is not None:
        cells.append(parent[cells[-1]])
    pts = [g.center(c) for c in reversed(cells)]
    # Line-of-sight shortcuts on the inflated grid.
    out = [pts[0]]
    k = 0
    while k < len(pts) - 1:
        j = len(pts) - 1
        while j > k + 1 and not line_free(g, pts[k], pts[j]):
            j -= 1
        out.append(pts[j])
        k = j
    return np.asarray(out)


def pursuit_point(path: np.ndarray, p: np.ndarray, lookahead: float) -> tuple[np.ndarray, float]:
    """The point ``lookahead`` [m] along ``path`` past the point of it nearest p, and the
    remaining path length from there [m]."""
    path = np.asarray(path, float)
    if len(path) == 1:
        return path[0], 0.0
    seg = path[1:] - path[:-1]
    length = np.linalg.norm(seg, axis=1)
    s_start = np.concatenate([[0.0], np.cumsum(length)])
    best, best_s = math.inf, 0.0
    for k in range(len(seg)):
        u = 0.0 if length[k] == 0 else float(np.clip((p - path[k]) @ seg[k] / length[k] ** 2,
                                                       0.0, 1.0))
        d = float(np.linalg.norm(path[k] + u * seg[k] - p))
        if d < best - 1e-12:
            best, best_s = d, s_start[k] + u * length[k]
    s = min(best_s + lookahead, s_start[-1])
    k = int(np.clip(np.searchsorted(s_start, s, side="right") - 1, 0, len(seg) - 1))
    u = 0.0 if length[k] == 0 else (s - s_start[k]) / length[k]
    return path[k] + u * seg[k], float(s_start[-1] - s)


def follow_velocity(path: np.ndarray, p_WB: np.ndarray, yaw: float,
                    final_yaw: Optional[float], params: NavigationParams) -> np.ndarray:
    """[vx, vy, yaw_rate] (heading frame) that follows ``path`` from base position p_WB."""
    p = np.asarray(p_WB[:2], float)
    end = np.asarray(path[-1], float)
    if np.linalg.norm(end - p) <= params.goal_tolerance:
        if final_yaw is None:
            return np.zeros(3)
        err = math.atan2(math.sin(final_yaw - yaw), math.cos(final_yaw - yaw))
        if abs(err) <= params.heading_tolerance:
            return np.zeros(3)
        rate = float(np.clip(params.yaw_gain * err, -params.max_yaw_rate, params.max_yaw_rate))
        return np.array([0.0, 0.0, rate])
    target, remaining = pursuit_point(path, p, params.lookahead)
    gp = GoalPlannerParams(forward_speed=params.forward_speed, max_yaw_rate=params.max_yaw_rate,
                           yaw_gain=params.yaw_gain, slow_radius=params.slow_radius,
                           stop_radius=0.0, turn_in_place_angle=params.turn_in_place_angle)
    v = goal_velocity(p, yaw, target, gp)
    # Slow down by the distance left along the path, not to the pursuit point.
    left = remaining + float(np.linalg.norm(target - p))
    v[0] = min(v[0], params.forward_speed * min(1.0, left / params.slow_radius))
    return v


class PathFollower(LeafSystem):
    """``body_state`` in, ``velocity_command`` (vx, vy, yaw rate) out: follows the path held in
    the context (waypoints N x 2 in W [m], optional final heading [rad]); zero without one.

    Output port ``path_done`` (1): 1 when at the end of the path (and at its final heading).
    """

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    def __init__(self, params: NavigationParams | None = None, path=None,
                 final_yaw: Optional[float] = None):
        super().__init__()
        self.params = params or NavigationParams.load()
        self._body = self.DeclareVectorInputPort("body_state", BODY_STATE_SIZE)
        initial = (None if path is None else np.asarray(path, float).reshape(-1, 2), final_yaw)
        self._path = self.DeclareAbstractState(AbstractValue.Make(initial))
        self.DeclareVectorOutputPort("velocity_command", 3, weak_calc(self._calc))
        self.DeclareVectorOutputPort("path_done", 1, weak_calc(self._calc_done))

    def set_path(self, context, path, final_yaw: Optional[float] = None) -> None:
        """Follow ``path`` (N x 2 [m] in W; None = stand still) from now on."""
        value = (None if path is None else np.asarray(path, float).reshape(-1, 2), final_yaw)
        context.get_mutable_abstract_state(int(self._path)).set_value(value)

    def _command(self, context) -> np.ndarray:
        path, final_yaw = context.get_abstract_state(int(self._path)).get_value()
        if path is None or len(path) == 0:
            return np.zeros(3)
        x = self._body.Eval(context)
        return follow_velocity(path, x[P_WB], yaw_from_quaternion(x[QUAT_WB]), final_yaw,
                               self.params)

    def _calc(self, context, output: BasicVector) -> None:
        output.SetFromVector(self._command(context))

    def _calc_done(self, context, output: BasicVector) -> None:
        path, _ = context.get_abstract_state(int(self._path)).get_value()
        done = path is not None and not np.any(self._command(context))
        output.SetFromVector([1.0 if done else 0.0])

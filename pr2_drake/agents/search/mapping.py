"""The task-6 search agent's map of the house, made from the head camera's depth as it goes.

A :class:`HeightMap` is a grid over the arena (world frame W, cell (i, j) covers
x in [x0 + j r, x0 + (j+1) r), y in [y0 + i r, ...), r = ``resolution`` [m]). Each depth frame
(:meth:`HeightMap.integrate`) is back-projected with the camera pose X_WC (from the robot's own
state) and binned:

- floor: points below ``floor_height``: the cell is seen free;
- obstacle: points from ``obstacle_min`` to ``obstacle_max`` above the floor (walls, furniture,
  legs, objects): the cell is occupied;
- surface: points on horizontal faces (surface normal within acos(``horizontal_normal_z``) of
  vertical) between ``surface_min`` and ``surface_max``: per frame the cell's lowest such height
  (a table top under the objects on it), blended into the cell's height by ``surface_blend``
  (an exponential average over frames: the camera pose comes from the robot's noisy state, and
  the lowest height over many frames read a 0.50 m top as 0.48 m).

Points within ``self_radius`` of the base (the robot's own arms, a held object) are left out,
and the floor under the robot is free where it stands. A cell neither seen free nor occupied is
unknown. From the map: an :class:`~.navigation.OccupancyGrid` (unknown cells count as free:
paths are planned optimistically and planned again when the map shows them blocked),
:meth:`HeightMap.surfaces` (the flat tops the objects may stand on: axis-aligned rectangles of
cells at one height) and :meth:`HeightMap.frontiers` (free cells next to unknown ones).

A map is never changed in place: :meth:`integrate` and the ``with_*`` methods return a new one,
so the sequencer's memory (copied at each update) shares it until it changes.

(No ``from __future__ import annotations``: ``yaml_load_typed`` reads the field types.)
"""

import math
from dataclasses import dataclass, field
from typing import ClassVar

import cv2
import numpy as np
from pydrake.math import RigidTransform

from pr2_drake.agents.search.navigation import OccupancyGrid
from pr2_drake.agents.search.perception import CameraIntrinsics
from pr2_drake.agents.search.tables import Table
from pr2_drake.params import Params


@dataclass
class MappingParams(Params):
    """See params/agents/search_mapping.yaml (m)."""

    FILE: ClassVar[str] = "params/agents/search_mapping.yaml"
    resolution: float = 0.05
    stride: int = 4
    min_range: float = 0.6
    max_range: float = 5.0
    self_radius: float = 0.45
    footprint_radius: float = 0.25
    floor_height: float = 0.03
    obstacle_min: float = 0.06
    obstacle_max: float = 1.6
    horizontal_normal_z: float = 0.93
    surface_min: float = 0.3
    surface_max: float = 1.0
    surface_bin: float = 0.01
    surface_min_area: float = 0.12
    surface_min_extent: float = 0.3
    surface_blend: float = 0.1
    frontier_min_cells: int = 12


@dataclass(eq=False)
class HeightMap:
    """Counts of floor and obstacle points and the surface height per cell (module
    docstring). ``version`` counts the frames integrated."""

    origin: tuple[float, float]
    resolution: float
    floor: np.ndarray  # int32 (rows, cols): floor points seen
    obstacle: np.ndarray  # int32: obstacle points seen
    surface: np.ndarray  # float32: horizontal surface height [m], inf where none
    version: int = 0
    _cache: dict = field(default_factory=dict, repr=False)

    def __deepcopy__(self, memo) -> "HeightMap":
        return self  # never changed in place (module docstring)

    @staticmethod
    def empty(lo, hi, resolution: float = 0.05) -> "HeightMap":
        """A map of [lo, hi] (x, y) [m] with every cell unknown."""
        cols, rows = (int(math.ceil((h - lo_) / resolution)) for lo_, h in zip(lo, hi))
        return HeightMap((float(lo[0]), float(lo[1])), float(resolution),
                         np.zeros((rows, cols), np.int32), np.zeros((rows, cols), np.int32),
                         np.full((rows, cols), np.inf, np.float32))

    @property
    def shape(self) -> tuple[int, int]:
        return self.floor.shape

    def cell_index(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(rows, cols) of points (N, 2) and whether each is inside the map."""
        j = np.floor((xy[:, 0] - self.origin[0]) / self.resolution).astype(np.int64)
        i = np.floor((xy[:, 1] - self.origin[1]) / self.resolution).astype(np.int64)
        rows, cols = self.shape
        ok = (i >= 0) & (i < rows) & (j >= 0) & (j < cols)
        return i * cols + j, ok

    def _copy(self, **changes) -> "HeightMap":
        new = HeightMap(self.origin, self.resolution, self.floor, self.obstacle, self.surface,
                        self.version + 1)
        for k, v in changes.items():
            setattr(new, k, v)
        return new

    # -- adding what is seen or known -------------------------------------------------------
    def integrate(self, depth: np.ndarray, X_WC: RigidTransform, K: CameraIntrinsics, p_WB,
                  params: MappingParams) -> "HeightMap":
        """This map with one depth frame (distance to the image plane [m], H x W) taken from
        X_WC by a camera of intrinsics K, the base at p_WB."""
        P = params
        pts, horizontal = _points(depth, X_WC, K, P)
        keep = np.isfinite(pts[:, 2])
        keep &= np.hypot(pts[:, 0] - p_WB[0], pts[:, 1] - p_WB[1]) > P.self_radius
        pts, horizontal = pts[keep], horizontal[keep]
        idx, inside = self.cell_index(pts[:, :2])
        pts, horizontal, idx = pts[inside], horizontal[inside], idx[inside]
        z, n = pts[:, 2], self.floor.size
        floor = self.floor + np.bincount(idx[z < P.floor_height], minlength=n).reshape(
            self.shape).astype(np.int32)
        obst = (z >= P.obstacle_min) & (z <= P.obstacle_max)
        obstacle = self.obstacle + np.bincount(idx[obst], minlength=n).reshape(
            self.shape).astype(np.int32)
        flat = horizontal & (z >= P.surface_min) & (z <= P.surface_max)
        surface = self.surface.copy().reshape(-1)
        order = np.argsort(-z[flat], kind="stable")  # the lowest written last
        lowest = np.full(n, np.inf, np.float32)
        lowest[idx[flat][order]] = z[flat][order]
        both = np.isfinite(surface) & np.isfinite(lowest)
        seen, new = surface[both], lowest[both]
        surface = np.minimum(surface, lowest)  # first sight of a cell: its height as seen
        surface[both] = seen + np.float32(P.surface_blend) * (new - seen)
        surface = surface.reshape(self.shape)
        floor += self._disc(p_WB, P.footprint_radius)
        return self._copy(floor=floor, obstacle=obstacle, surface=surface)

    def with_free_disc(self, p, radius: float) -> "HeightMap":
        """This map with the floor within ``radius`` of p (x, y) seen free (where the robot
        stands)."""
        return self._copy(floor=self.floor + self._disc(p, radius))

    def _disc(self, p, radius: float) -> np.ndarray:
        """1 in the cells whose centre is within ``radius`` of p (x, y), else 0."""
        r = self.resolution
        x = self.origin[0] + (np.arange(self.shape[1]) + 0.5) * r - p[0]
        y = self.origin[1] + (np.arange(self.shape[0]) + 0.5) * r - p[1]
        return (x[None, :] ** 2 + y[:, None] ** 2 <= radius * radius).astype(np.int32)

    def with_box(self, center, size, height: float) -> "HeightMap":
        """This map with a known box (e.g. the coffee table of the priors) occupied, its top at
        ``height`` [m]."""
        c = self.cell_centers()
        box = np.all(np.abs(c - np.asarray(center[:2])) <= np.asarray(size[:2]) / 2, axis=-1)
        surface = self.surface.copy()
        surface[box] = np.minimum(surface[box], height)
        return self._copy(obstacle=self.obstacle + box.astype(np.int32), surface=surface)

    # -- what the map says ------------------------------------------------------------------
    def cell_centers(self) -> np.ndarray:
        rows, cols = self.shape
        x = self.origin[0] + (np.arange(cols) + 0.5) * self.resolution
        y = self.origin[1] + (np.arange(rows) + 0.5) * self.resolution
        return np.stack(np.meshgrid(x, y), axis=-1)

    def known(self) -> np.ndarray:
        return (self.floor > 0) | (self.obstacle > 0)

    def grid(self) -> OccupancyGrid:
        """Occupied cells (obstacles seen, and the map's border); unknown cells are free."""
        if "grid" not in self._cache:
            self._cache["grid"] = self._occupancy(self.obstacle > 0)
        return self._cache["grid"]

    def grid_without_weak(self, max_count: int, floor_ratio: float) -> OccupancyGrid:
        """As :meth:`grid`, but a cell with at most ``max_count`` obstacle points that was seen
        as floor at least ``floor_ratio`` times as often as an obstacle counts as free (depth
        noise: a few stray points over floor seen many times)."""
        key = ("weak", int(max_count), float(floor_ratio))
        if key not in self._cache:
            weak = (self.obstacle <= max_count) & (self.floor >= floor_ratio * self.obstacle)
            self._cache[key] = self._occupancy((self.obstacle > 0) & ~weak)
        return self._cache[key]

    def _occupancy(self, occ: np.ndarray) -> OccupancyGrid:
        occ[[0, -1], :] = True
        occ[:, [0, -1]] = True
        return OccupancyGrid(occ, self.origin, self.resolution)

    def surfaces(self, params: MappingParams) -> list[Table]:
        """The flat tops seen (tables, seats, counters): per height level (``surface_bin``),
        each connected patch at least ``surface_min_area`` large and ``surface_min_extent``
        across, as its axis-aligned bounding rectangle at the patch's median height; where two
        levels give the same top, the larger. Largest first; named ``s<k>``."""
        s, r, P = self.surface, self.resolution, params
        finite = np.isfinite(s) & (s >= P.surface_min) & (s <= P.surface_max)
        if not finite.any():
            return []
        found = []
        min_cells = P.surface_min_area / (r * r)
        levels, counts = np.unique(np.round(s[finite] / P.surface_bin), return_counts=True)
        near = np.array([counts[np.abs(levels - lv) <= 1].sum() for lv in levels])
        for level in levels[near >= min_cells]:
            mask = finite & (np.abs(s - level * P.surface_bin) <= P.surface_bin)
            n, labels, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), 8)
            for k in range(1, n):
                x, y, w, h, area = (int(v) for v in stats[k])
                if area * r * r < P.surface_min_area or min(w, h) * r < P.surface_min_extent:
                    continue
                lo = np.array([self.origin[0] + x * r, self.origin[1] + y * r])
                size = np.array([w * r, h * r])
                found.append((area, lo + size / 2, size, float(np.median(s[labels == k]))))
        found.sort(key=lambda f: -f[0])
        out: list[Table] = []
        for area, center, size, height in found:
            if not any(abs(t.height - height) < 3 * P.surface_bin and _overlap(t, center, size)
                       for t in out):
                out.append(Table(f"s{len(out)}", center, size, height))
        return out

    def frontiers(self, params: MappingParams) -> list[np.ndarray]:
        """Centres (x, y) of the groups of free cells next to unknown ones (at least
        ``frontier_min_cells`` each), largest first."""
        known = self.known()
        free = (self.floor > 0) & (self.obstacle == 0)
        unknown = (~known).astype(np.uint8)
        edge = free & (cv2.dilate(unknown, np.ones((3, 3), np.uint8)) > 0)
        n, labels, stats, _ = cv2.connectedComponentsWithStats(edge.astype(np.uint8), 8)
        centers = self.cell_centers()
        out = []
        for k in np.argsort(-stats[1:, cv2.CC_STAT_AREA]) + 1:
            if stats[k, cv2.CC_STAT_AREA] < params.frontier_min_cells:
                break
            cells = centers[labels == k]
            mid = cells.mean(axis=0)
            out.append(cells[np.argmin(np.linalg.norm(cells - mid, axis=1))])
        return out


def _overlap(t: Table, center, size) -> bool:
    return bool(np.all(np.abs(t.center - center) < (t.size + size) / 2))


def _points(depth: np.ndarray, X_WC: RigidTransform, K: CameraIntrinsics,
            P: MappingParams) -> tuple[np.ndarray, np.ndarray]:
    """World points (N x 3, float32; NaN out of range) of every ``stride``-th pixel of a depth
    frame, and whether each lies on a horizontal face (its normal, from the neighbouring
    points, within acos(``horizontal_normal_z``) of vertical)."""
    s = max(1, int(P.stride))
    z = np.asarray(depth, np.float32)[::s, ::s]
    z = np.where((z > P.min_range) & (z < P.max_range), z, np.float32(np.nan))
    h, w = z.shape
    u = ((np.arange(w, dtype=np.float32) * s - K.cx) / K.fx)[None, :]
    v = ((np.arange(h, dtype=np.float32) * s - K.cy) / K.fy)[:, None]
    R = X_WC.rotation().matrix().astype(np.float32)
    t = X_WC.translation().astype(np.float32)
    xc, yc = u * z, v * z
    p = [R[k, 0] * xc + R[k, 1] * yc + R[k, 2] * z + t[k] for k in range(3)]
    dx = [c[1:-1, 2:] - c[1:-1, :-2] for c in p]
    dy = [c[2:, 1:-1] - c[:-2, 1:-1] for c in p]
    n = [dx[1] * dy[2] - dx[2] * dy[1], dx[2] * dy[0] - dx[0] * dy[2],
         dx[0] * dy[1] - dx[1] * dy[0]]
    with np.errstate(invalid="ignore"):
        flat = n[2] * n[2] > P.horizontal_normal_z ** 2 * (n[0] * n[0] + n[1] * n[1]
                                                           + n[2] * n[2])
    horizontal = np.zeros((h, w), bool)
    horizontal[1:-1, 1:-1] = flat
    return np.stack([c.reshape(-1) for c in p], axis=1), horizontal.reshape(-1)

"""The controller's terrain model: what the footstep planner believes about the ground.

A terrain model answers, for a swing sole's target, the height and landing pitch of the foothold
(``foothold``) and the height the swing must clear on its way (``swing_clearance``; lift, move,
lower: :class:`pr2_drake.controllers.planning.swing.SwingTrajectory`). It is built from what
the robot knows (its stance sole, the task's priors), never from the simulator's scene: the
scene's own ground (boxes in the plant, the referee's heights) is :mod:`pr2_drake.tasks.ground`.

- :class:`FlatTerrain`: the swing sole lands at the stance sole's height, level (the default);
- :class:`SlopeTerrain`: an incline of known angle (task 4's prior);
- :class:`RoughTerrain`: unknown low stones, touchdown from contact (task 1);
- :class:`PatchTerrain`: planar patches, each an axis-aligned rectangle in xy (W) with a plane
  z = z0 + gx (x - cx) + gy (y - cy) over it (c the rectangle's centre); it answers the ground
  height and the unit normal under a point (the highest patch containing it; the base height
  elsewhere). Steps and plateaus are level patches, a slope one tilted patch.
  :func:`stairs_terrain` builds a staircase; :func:`stairs_from_priors` builds task 5's from
  the priors (``step_height``, ``step_depth``, ``step_width``, ``step_count``,
  ``step_start_x``).

Units: m, rad; frames: W world (z up), S sole (x forward).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np


#: [m] heights closer than this are the same level.
LEVEL_TOLERANCE = 0.002
#: [m] spacing of terrain samples along a sole or a swing path.
SAMPLE_STEP = 0.005


class FlatTerrain:
    """Terrain model of the footstep planner: a swing sole lands at the stance sole's height,
    level. Subclasses estimate the height and pitch of a foothold from what the robot knows
    (its stance sole, the task's priors).

    ``known_heights``: whether :meth:`foothold` sets the swing target's height and pitch (then
    touchdown is detected against that target height; flat: against the stance sole).
    """

    known_heights = False

    def foothold(self, stance: np.ndarray, stance_slope: float,
                 target: np.ndarray) -> tuple[float, float]:
        """Height [m, W] and pitch [rad, rotation about the sole's y axis; negative = toe up]
        of a sole landing at ``target`` (x, y, z, yaw).

        Args:
            stance: the stance sole (x, y, z, yaw), measured.
            stance_slope: rise of the stance sole per metre along its x axis (measured).
        """
        return float(stance[2]), 0.0

    def swing_clearance(self, start: np.ndarray, target: np.ndarray) -> float | None:
        """Height [m, W] a swing sole from ``start`` to ``target`` (x, y, z, yaw) must clear
        (it lifts, moves, then lowers: :class:`pr2_drake.controllers.planning.swing.SwingTrajectory`),
        or None for the plain swing curve (no edge on the way; the default)."""
        return None

    def swing_lowering_start(self, start: np.ndarray, target: np.ndarray,
                             margin: float) -> float:
        """Fraction [0, 1] of a swing's straight xy path from ``start`` to ``target`` (x, y,
        z, yaw) after which the sole's heel is ``margin`` [m] past the last ground higher than
        the target (a step down: the sole may lower from then on); 0 when none (the default)."""
        return 0.0


class SlopeTerrain(FlatTerrain):
    """A planar incline of known angle between a lower and an upper level (the task-4 prior).

    The slope is taken to rise towards ``goal`` (xy, W).
    The stance sole is on the incline when it is pitched by more than ``on_slope_fraction`` of
    the angle; then the foothold height is the stance height plus the rise of the plane, capped
    at ``z_top`` (the plateau, e.g. the goal height), and the landing pitch is the plane's.
    Off the incline the foothold is level at the stance height (the first step onto the ramp
    lands early and is caught by touchdown detection).
    """

    known_heights = True

    def __init__(self, angle: float, goal, z_top: float, on_slope_fraction: float = 0.5):
        self.goal = np.asarray(goal, dtype=float)[:2]
        self.tan = float(np.tan(angle))
        self.z_top = float(z_top)
        self.on_slope_fraction = on_slope_fraction

    def foothold(self, stance, stance_slope, target):
        z0 = float(stance[2])
        if abs(stance_slope) < self.on_slope_fraction * self.tan:
            return z0, 0.0
        d = self.goal - np.asarray(stance[:2])
        n = float(np.linalg.norm(d))
        if n < 1e-6:
            return z0, 0.0
        gradient = np.sign(stance_slope) * self.tan * d / n
        # The incline the stance sole is on rises along its x axis; along the target's axis:
        axis = np.array([np.cos(target[3]), np.sin(target[3])])
        z = z0 + float(gradient @ (np.asarray(target[:2]) - stance[:2]))
        if z >= self.z_top - 0.01:
            return min(z, self.z_top), 0.0
        return z, -float(np.arctan(gradient @ axis))


class RoughTerrain(FlatTerrain):
    """Unknown low obstacles (stones): the swing sole aims ``drop`` below the stance sole, level,
    so that it meets the ground while still descending (early rather than late), and the
    touchdown is detected from contact (a blocked descent)."""

    known_heights = True

    def __init__(self, drop: float):
        self.drop = float(drop)

    def foothold(self, stance, stance_slope, target):
        return float(stance[2]) - self.drop, 0.0


@dataclass(frozen=True)
class PlanarPatch:
    """A planar patch over the rectangle [x_min, x_max] x [y_min, y_max] (W) [m].

    ``z`` is the height at the rectangle's centre, ``gx``, ``gy`` the plane's slope (dz/dx,
    dz/dy). Infinite bounds are allowed (a floor that goes on); then the slope must be zero.
    """

    x_min: float
    x_max: float
    y_min: float
    y_max: float
    z: float
    gx: float = 0.0
    gy: float = 0.0
    name: str = ""

    def contains(self, x: float, y: float) -> bool:
        return self.x_min <= x <= self.x_max and self.y_min <= y <= self.y_max

    def height(self, x, y):
        """Height [m] at (x, y) [m, W]: floats, or numpy arrays element by element."""
        if self.gx == 0.0 and self.gy == 0.0:
            return self.z
        cx = 0.5 * (self.x_min + self.x_max)
        cy = 0.5 * (self.y_min + self.y_max)
        return self.z + self.gx * (x - cx) + self.gy * (y - cy)

    def normal(self) -> np.ndarray:
        n = np.array([-self.gx, -self.gy, 1.0])
        return n / np.linalg.norm(n)


class PatchTerrain(FlatTerrain):
    """Terrain of planar patches (see the module docstring).

    Args:
        patches: the patches; where several contain a point the highest counts (boxes).
        base: height of the ground outside every patch [m].
        clearance: [m] a swing sole whose path crosses an edge clears the highest terrain
            under its path by this much (lift, move, lower).
        edge_margin: [m] a sole counts as on a patch when its heel and toe, each this far
            beyond the sole's ends, are over the same level (:meth:`on_one_level`).
        foot_length: sole length heel to toe [m].
        name: named in errors.
    """

    known_heights = True

    def __init__(self, patches: Sequence[PlanarPatch], base: float = 0.0,
                 clearance: float = 0.05, edge_margin: float = 0.03, foot_length: float = 0.15,
                 name: str = "terrain"):
        self.patches = list(patches)
        for p in self.patches:
            if not (p.x_min <= p.x_max and p.y_min <= p.y_max):
                raise ValueError(f"{name}: patch {p.name!r} has an empty rectangle")
            if (p.gx or p.gy) and not all(map(math.isfinite, (p.x_min, p.x_max, p.y_min,
                                                              p.y_max))):
                raise ValueError(f"{name}: sloped patch {p.name!r} must be bounded")
        self.base = float(base)
        self.clearance = float(clearance)
        self.edge_margin = float(edge_margin)
        self.foot_length = float(foot_length)
        self.name = name

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.name!r}, {len(self.patches)} patches)"

    # ---- queries ------------------------------------------------------------------------------
    def patch_at(self, x: float, y: float) -> PlanarPatch | None:
        """The highest patch containing (x, y), or None (base ground)."""
        best, z_best = None, -math.inf
        for p in self.patches:
            if p.contains(x, y):
                z = p.height(x, y)
                if z > z_best:
                    best, z_best = p, z
        return best

    def height(self, x: float, y: float) -> float:
        """Ground height under (x, y) [m, W]."""
        p = self.patch_at(x, y)
        return self.base if p is None else p.height(x, y)

    def normal(self, x: float, y: float) -> np.ndarray:
        """Unit ground normal under (x, y) (W)."""
        p = self.patch_at(x, y)
        return np.array([0.0, 0.0, 1.0]) if p is None else p.normal()

    def heights_along(self, x: float, y: float, yaw: float, s0: float, s1: float) -> np.ndarray:
        """Ground heights [m] sampled along the line through (x, y) with direction ``yaw``,
        from signed distance s0 to s1 [m] (every :data:`SAMPLE_STEP`, both ends included).
        The samples' heights are :meth:`height`'s, bit for bit, computed for all at once (the
        swing planner asks for some 70 of them at every tick of a swing over stairs)."""
        n = max(int(math.ceil((s1 - s0) / SAMPLE_STEP)), 1)
        d = np.linspace(s0, s1, n + 1)
        return self.heights_at(x + math.cos(yaw) * d, y + math.sin(yaw) * d)

    def heights_at(self, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        """:meth:`height` at each point (xs[i], ys[i]) [m, W]: the highest patch containing it
        (the first of equal ones), else the base height."""
        best = np.full(xs.shape, -math.inf)
        for p in self.patches:
            inside = (p.x_min <= xs) & (xs <= p.x_max) & (p.y_min <= ys) & (ys <= p.y_max)
            if inside.any():  # (PlanarPatch.height takes arrays)
                np.maximum(best, np.where(inside, p.height(xs, ys), -math.inf), out=best)
        return np.where(best == -math.inf, self.base, best)

    def on_one_level(self, sole: Sequence[float]) -> bool:
        """Whether a sole at (x, y, z, yaw) has heel and toe (plus the edge margin) over one
        level: no edge under it."""
        half = 0.5 * self.foot_length + self.edge_margin
        z = self.heights_along(sole[0], sole[1], sole[3], -half, half)
        return bool(z.max() - z.min() < LEVEL_TOLERANCE)

    def edges_along(self, x: float, y: float, yaw: float, s0: float, s1: float) -> list[float]:
        """Signed distances [m] along ``yaw`` from (x, y), within [s0, s1], where the height
        changes (edges, to :data:`SAMPLE_STEP`): the midpoint of each changing sample pair."""
        z = self.heights_along(x, y, yaw, s0, s1)
        d = np.linspace(s0, s1, len(z))
        jumps = np.nonzero(np.abs(np.diff(z)) > LEVEL_TOLERANCE)[0]
        return [float(0.5 * (d[i] + d[i + 1])) for i in jumps]

    def risers(self) -> list[tuple[float, float]]:
        """The edges across x of every patch (its finite x bounds, at its middle y): (x [m],
        height step dz [m], up along +x). Side edges (y bounds) are not risers."""
        out = []
        for p in self.patches:
            y = 0.5 * (p.y_min + p.y_max) if math.isfinite(p.y_min + p.y_max) else 0.0
            for x in (p.x_min, p.x_max):
                if math.isfinite(x):
                    dz = self.height(x + 1e-3, y) - self.height(x - 1e-3, y)
                    if abs(dz) > LEVEL_TOLERANCE:
                        out.append((float(x), float(dz)))
        return sorted(set(out))

    # ---- terrain model of the gait planner ----------------------------------------------------
    def foothold(self, stance, stance_slope, target) -> tuple[float, float]:
        """Height and pitch (about the sole's y axis, negative = toe up) of the ground under
        the target sole's centre."""
        x, y, yaw = float(target[0]), float(target[1]), float(target[3])
        n = self.normal(x, y)
        rise = n[0] * math.cos(yaw) + n[1] * math.sin(yaw)  # -dz/ds along the sole, times n_z
        return self.height(x, y), float(math.atan2(rise, n[2]))

    def swing_clearance(self, start, target) -> float | None:
        """Height [m, W] the swing sole must clear on its way from ``start`` to ``target``
        (x, y, z, yaw): the highest ground under the sole's footprint swept along the straight
        xy path, plus ``clearance``; None when the path crosses no edge (a plain swing)."""
        x0, y0 = float(start[0]), float(start[1])
        dx, dy = float(target[0]) - x0, float(target[1]) - y0
        dist = math.hypot(dx, dy)
        yaw = math.atan2(dy, dx) if dist > 1e-6 else float(start[3])
        half = 0.5 * self.foot_length + 0.02
        z = self.heights_along(x0, y0, yaw, -half, dist + half)
        if z.max() - z.min() < LEVEL_TOLERANCE:
            return None
        return float(z.max()) + self.clearance

    def swing_lowering_start(self, start, target, margin: float) -> float:
        x0, y0 = float(start[0]), float(start[1])
        dx, dy = float(target[0]) - x0, float(target[1]) - y0
        dist = math.hypot(dx, dy)
        if dist < 1e-6:
            return 0.0
        half = 0.5 * self.foot_length
        n = max(int(math.ceil((dist + half) / SAMPLE_STEP)), 1)
        d = np.linspace(0.0, dist + half, n + 1)  # under the sole's path, heel to toe
        z = self.heights_at(x0 + dx / dist * d, y0 + dy / dist * d)
        higher = np.nonzero(z > float(target[2]) + LEVEL_TOLERANCE)[0]
        if len(higher) == 0:
            return 0.0
        return min((float(d[higher[-1]]) + half + margin) / dist, 1.0)


def stairs_patches(start_x: float, heights: Sequence[float], lengths: Sequence[float],
                   width: float, center_y: float = 0.0) -> list[PlanarPatch]:
    """Level treads along +x from ``start_x``: tread k is ``lengths[k]`` long (inf: goes on)
    at height ``heights[k]`` [m], ``width`` wide about ``center_y``."""
    patches = []
    y0, y1 = center_y - 0.5 * width, center_y + 0.5 * width
    x = start_x
    for k, (h, length) in enumerate(zip(heights, lengths)):
        patches.append(PlanarPatch(x, x + length, y0, y1, float(h), name=f"tread_{k + 1}"))
        x += length
    return patches


def stairs_terrain(start_x: float, count: int, height: float, depth: float, width: float,
                   center_y: float = 0.0, floor_length: float = math.inf, down: bool = False,
                   **kwargs: Any) -> PatchTerrain:
    """``count`` steps of riser ``height`` up along +x from ``start_x``, then a floor
    ``floor_length`` long; with ``down`` the same steps down after the floor (to z = 0).
    ``kwargs`` go to :class:`PatchTerrain`."""
    heights = [height * (k + 1) for k in range(count)] + [height * count]
    lengths = [depth] * count + [floor_length]
    if down:
        heights += [height * k for k in range(count - 1, 0, -1)]
        lengths += [depth] * (count - 1)
    name = (f"stairs({count} x {height:.3f} m risers, {depth:.2f} m treads"
            f"{', up and down' if down else ''})")
    kwargs.setdefault("name", name)
    return PatchTerrain(stairs_patches(start_x, heights, lengths, width, center_y), **kwargs)


#: Priors :func:`stairs_from_priors` reads.
STAIRS_PRIORS = ("step_height", "step_depth", "step_width", "step_count", "step_start_x")


def stairs_from_priors(priors: dict[str, Any], **kwargs: Any) -> PatchTerrain:
    """Task 5's staircase from its priors: ``step_count`` steps of ``step_height`` and
    ``step_depth`` (``step_width`` wide, centred on y = 0) up along +x from ``step_start_x``,
    then a level floor that goes on. ``kwargs`` go to :class:`PatchTerrain`."""
    missing = [k for k in STAIRS_PRIORS if priors.get(k) is None]
    if missing:
        raise ValueError(f"stairs_from_priors: missing priors {missing}; got {sorted(priors)}")
    return stairs_terrain(float(priors["step_start_x"]), int(priors["step_count"]),
                          float(priors["step_height"]), float(priors["step_depth"]),
                          float(priors["step_width"]), **kwargs)

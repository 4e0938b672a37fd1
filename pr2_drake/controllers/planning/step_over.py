"""Stepping over low obstacles: footholds kept off them, and high swings across them.

:class:`StepOverFootstepPlanner` wraps a footstep planner (by default the velocity one) for the
gait planner (:class:`pr2_drake.controllers.planning.gait.GaitPlanner`, through the
:class:`pr2_drake.controllers.planning.footsteps.FootstepPlanner` interface). Given the obstacles (boxes
on the ground, :class:`Obstacle`), it

- moves each planned foothold along its sole's x axis until heel and toe (plus ``margin``) and
  the sole's width are clear of every obstacle: back, short of it, or forward, past it, when
  that is within ``reach`` of the stance sole (the smaller move wins, as long as a step moved
  back still advances ``min_progress``); a sole that would swing over an obstacle the stance
  sole has already passed lands beside the stance sole (step-to: the shortest swing over it);
- keeps landing points moved by step adjustment (capture point) off the obstacles
  (:meth:`constrain`);
- asks for a high swing (:meth:`swing_clearance`) when the swing sole's footprint, swept from
  lift-off to landing, passes over an obstacle: the sole lifts to the obstacle's top plus
  ``clearance``, moves, then lowers (:class:`pr2_drake.controllers.planning.swing.SwingTrajectory`,
  ``gait.swing_clear_lift`` / ``swing_clear_lower``).

``swing_apex`` (None: off) asks for that high swing on every step, ``swing_apex`` [m] above the
higher of the swing's two ends: a per-command option (set or clear it at any time; it applies
from the next lift-off). With no obstacles and ``swing_apex`` None the planner is the wrapped
one, step for step.

An agent walks over a known obstacle with::

    steps = StepOverFootstepPlanner(obstacles=[Obstacle(0.60, 0.65, -1.0, 1.0, 0.06)])
    walker = WalkingController(footsteps=steps)

Units: m, rad; frames: W world (z up), S sole (x forward). Footholds are (x, y, z, yaw).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from pr2_drake.controllers.planning.footsteps import FootstepPlanner, VelocityFootstepPlanner
from pr2_drake.controllers.walking_params import WalkingParams

#: [m] spacing of the footprint samples along a swing path.
PATH_STEP = 0.01


@dataclass(frozen=True)
class Obstacle:
    """A box on the ground: the rectangle [x_min, x_max] x [y_min, y_max] (W) [m], its top at
    height ``top`` [m, W]. A sole may not stand on it; a swing sole passes over it."""

    x_min: float
    x_max: float
    y_min: float
    y_max: float
    top: float
    name: str = ""

    def __post_init__(self):
        vals = (self.x_min, self.x_max, self.y_min, self.y_max, self.top)
        if not all(math.isfinite(v) for v in vals):
            raise ValueError(f"Obstacle {self.name!r}: bounds and top must be finite, got {vals}")
        if not (self.x_min < self.x_max and self.y_min < self.y_max):
            raise ValueError(f"Obstacle {self.name!r}: empty rectangle x [{self.x_min}, "
                             f"{self.x_max}], y [{self.y_min}, {self.y_max}]")


def _overlap_interval(obstacle: Obstacle, p: np.ndarray, yaw: float, half_length: float,
                      half_width: float) -> tuple[float, float] | None:
    """The shifts d [m] along the sole's x axis for which a footprint (``half_length`` x
    ``half_width`` about p (xy), yawed) overlaps the obstacle's rectangle, as an interval
    (separating axes: x, y, the sole's x and y), or None when no shift does."""
    u = np.array([math.cos(yaw), math.sin(yaw)])
    n = np.array([-u[1], u[0]])
    c = np.array([0.5 * (obstacle.x_min + obstacle.x_max), 0.5 * (obstacle.y_min + obstacle.y_max)])
    hx, hy = 0.5 * (obstacle.x_max - obstacle.x_min), 0.5 * (obstacle.y_max - obstacle.y_min)
    lo, hi = -math.inf, math.inf
    for a in (np.array([1.0, 0.0]), np.array([0.0, 1.0]), u, n):
        r = hx * abs(a[0]) + hy * abs(a[1]) + half_length * abs(a @ u) + half_width * abs(a @ n)
        off = float(a @ (p - c))
        slope = float(a @ u)
        if abs(slope) < 1e-12:
            if abs(off) >= r:
                return None
            continue
        d0, d1 = (-r - off) / slope, (r - off) / slope
        lo, hi = max(lo, min(d0, d1)), min(hi, max(d0, d1))
        if lo >= hi:
            return None
    return lo, hi


class StepOverFootstepPlanner(FootstepPlanner):
    """Footsteps off obstacles and high swings over them (see the module docstring).

    Args:
        base: the footstep planner wrapped (None: :class:`VelocityFootstepPlanner` with
            params/controllers/walking.yaml's gait and start threshold).
        obstacles: the boxes to step over.
        clearance: [m] the swing sole passes this far above an obstacle's top.
        margin: [m] heel, toe and sides of a standing sole stay this far from an obstacle.
        swing_apex: [m] when set, every swing lifts this far above its higher end (None: off).
        foot_length, foot_width: the sole's footprint [m] (KUAVO: 0.15 x 0.05).
        reach: [m] a foothold moved forward stays within this of the stance sole, along it.
        min_progress: [m] a foothold moved back must still advance this much past the stance.
    """

    def __init__(self, base: FootstepPlanner | None = None,
                 obstacles: Sequence[Obstacle] = (), clearance: float = 0.05,
                 margin: float = 0.03, swing_apex: float | None = None,
                 foot_length: float = 0.15, foot_width: float = 0.05, reach: float = 0.30,
                 min_progress: float = 0.03):
        if base is None:
            p = WalkingParams.load()
            base = VelocityFootstepPlanner(p.gait, p.limits.start_threshold)
        self.base = base
        self.adjustable = base.adjustable
        self.obstacles = list(obstacles)
        for k, o in enumerate(self.obstacles):
            if not isinstance(o, Obstacle):
                raise ValueError(f"StepOverFootstepPlanner: obstacles[{k}] is not an Obstacle: "
                                 f"{o!r}")
        for name, v in (("clearance", clearance), ("margin", margin),
                        ("foot_length", foot_length), ("foot_width", foot_width),
                        ("reach", reach)):
            if not (math.isfinite(v) and v >= 0.0):
                raise ValueError(f"StepOverFootstepPlanner: {name} must be >= 0, got {v}")
        self.clearance = float(clearance)
        self.margin = float(margin)
        self.swing_apex = swing_apex
        self.foot_length = float(foot_length)
        self.foot_width = float(foot_width)
        self.reach = float(reach)
        self.min_progress = float(min_progress)
        self._footholds: list = [None, None]

    @property
    def swing_apex(self) -> float | None:
        """[m] every swing lifts this far above its higher end (None: off)."""
        return self._swing_apex

    @swing_apex.setter
    def swing_apex(self, value: float | None) -> None:
        if value is not None and not (math.isfinite(value) and value >= 0.0):
            raise ValueError(f"StepOverFootstepPlanner: swing_apex must be None or >= 0, "
                             f"got {value}")
        self._swing_apex = None if value is None else float(value)

    # ---- geometry -----------------------------------------------------------------------------
    def blocked(self, sole: np.ndarray) -> list[tuple[float, float]]:
        """Intervals of shifts [m] along the sole's x axis for which the sole (x, y, z, yaw),
        plus ``margin`` all round, overlaps an obstacle, sorted."""
        p = np.asarray(sole[:2], dtype=float)
        hl = 0.5 * self.foot_length + self.margin
        hw = 0.5 * self.foot_width + self.margin
        out = [iv for o in self.obstacles
               if (iv := _overlap_interval(o, p, float(sole[3]), hl, hw)) is not None]
        return sorted(out)

    def is_free(self, sole: np.ndarray) -> bool:
        """Whether a sole at (x, y, z, yaw) stands clear of every obstacle (plus the margin)."""
        return not any(lo < 0.0 < hi for lo, hi in self.blocked(sole))

    @staticmethod
    def _free_shift(intervals, d: float, direction: float) -> float:
        """The nearest shift from d in ``direction`` (+1/-1) outside every interval."""
        moved = True
        while moved:
            moved = False
            for lo, hi in intervals:
                if lo < d < hi:
                    d = (hi + 1e-3) if direction > 0 else (lo - 1e-3)
                    moved = True
        return d

    def off_obstacles(self, target: np.ndarray, stance: np.ndarray,
                      swing: np.ndarray | None = None) -> np.ndarray:
        """``target`` moved along its x axis off the obstacles (see the module docstring);
        ``stance`` is the sole it steps from, ``swing`` where the swing sole starts."""
        target = np.asarray(target, dtype=float)
        c, s = math.cos(target[3]), math.sin(target[3])

        def advance(d: float) -> float:  # along the target's x, from the stance sole
            return c * (target[0] + c * d - stance[0]) + s * (target[1] + s * d - stance[1])

        if swing is not None and self._crosses(swing, stance):
            # The stance sole is past an obstacle the swing sole is behind: land beside it.
            if advance(0.0) > 0.0:
                target = target - np.array([c, s, 0.0, 0.0]) * advance(0.0)
        iv = self.blocked(target)
        if not any(lo < 0.0 < hi for lo, hi in iv):
            return target
        back = self._free_shift(iv, 0.0, -1.0)
        fwd = self._free_shift(iv, 0.0, 1.0)
        ok_fwd = advance(fwd) <= self.reach
        ok_back = advance(back) >= self.min_progress
        if ok_back and (not ok_fwd or abs(back) <= abs(fwd)):
            d = back
        elif ok_fwd:
            d = fwd
        else:
            d = back  # neither reaches: wait short of the obstacle
        return target + np.array([c * d, s * d, 0.0, 0.0])

    def _crosses(self, start: np.ndarray, target: np.ndarray) -> list[Obstacle]:
        """The obstacles the sole's footprint passes over on the straight way from ``start``
        to ``target`` (no margin: the swing's own clearance keeps it off)."""
        x0, y0 = float(start[0]), float(start[1])
        dx, dy = float(target[0]) - x0, float(target[1]) - y0
        dist = math.hypot(dx, dy)
        n = max(int(math.ceil(dist / PATH_STEP)), 1)
        dyaw = math.remainder(float(target[3]) - float(start[3]), 2 * math.pi)
        hl, hw = 0.5 * self.foot_length, 0.5 * self.foot_width
        out = []
        for o in self.obstacles:
            for k in range(n + 1):
                f = k / n
                p = np.array([x0 + f * dx, y0 + f * dy])
                iv = _overlap_interval(o, p, float(start[3]) + f * dyaw, hl, hw)
                if iv is not None and iv[0] < 0.0 < iv[1]:
                    out.append(o)
                    break
        return out

    # ---- FootstepPlanner ----------------------------------------------------------------------
    def keep_walking(self, command, footholds) -> bool:
        return self.base.keep_walking(command, footholds)

    def first_swing_side(self, command, footholds) -> int:
        return self.base.first_swing_side(command, footholds)

    def observe(self, footholds) -> None:
        self._footholds = footholds
        self.base.observe(footholds)

    def next_steps(self, stance, stance_side, heading, command, n):
        planned = self.base.next_steps(stance, stance_side, heading, command, n)
        if not self.obstacles:
            return planned
        out = []
        swing = self._footholds[1 - stance_side]
        for step in planned:
            step = self.off_obstacles(step, stance, swing)
            swing, stance = stance, step
            out.append(step)
        return out

    def constrain(self, target_xy, planned):
        target_xy = self.base.constrain(target_xy, planned)
        if not self.obstacles:
            return target_xy
        c, s = math.cos(planned[3]), math.sin(planned[3])
        along = c * (target_xy[0] - planned[0]) + s * (target_xy[1] - planned[1])
        iv = self.blocked(planned)
        lo = max([b for a, b in iv if b <= 0.0], default=-math.inf)
        hi = min([a for a, b in iv if a >= 0.0], default=math.inf)
        clipped = min(max(along, lo), hi)
        if clipped == along:
            return target_xy
        return np.array([target_xy[0] + c * (clipped - along),
                         target_xy[1] + s * (clipped - along)])

    def swing_clearance(self, start, target) -> float | None:
        """The obstacles' top plus ``clearance`` when the swing passes over one; with
        ``swing_apex`` set, at least ``swing_apex`` above the higher end; else None."""
        out = self.base.swing_clearance(start, target)
        if self._swing_apex is not None:
            z = max(float(start[2]), float(target[2])) + self._swing_apex
            out = z if out is None else max(out, z)
        crossed = self._crosses(start, target) if self.obstacles else []
        if crossed:
            z = max(o.top for o in crossed) + self.clearance
            out = z if out is None else max(out, z)
        return out

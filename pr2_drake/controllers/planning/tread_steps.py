"""Footholds on treads: velocity footsteps moved so that heel and toe stand on one level.

:class:`TreadFootstepPlanner` (a :class:`pr2_drake.controllers.planning.footsteps.FootstepPlanner`) asks
the velocity planner for each next footstep, then, when that sole (plus ``edge_margin`` beyond
heel and toe) would straddle an edge of the terrain (:class:`pr2_drake.controllers.
terrain_model.PatchTerrain`), moves it along the sole's x axis: back, so that the toe stops
short of the edge, or forward onto the next level, so that the heel is past it. Back wins when
it is the smaller move and still makes ``min_progress``; forward must stay within the stride
limit. Its height is the terrain's under it. Over a riser the robot steps to (:meth:`step_to`):
the swing sole first comes beside the stance sole before the edge, one sole steps up (or down)
onto the next tread, and the other joins it, so that no swing travels more than one riser
stride. Step-ups and step-downs land with the whole sole on the tread, away from the nosing.
When the DCM runs ahead of a step-to stop (a push, a fast approach), the stopping swing steps
onto the next level at once instead (:meth:`catch_step`, early in the swing): stopping would
leave the step up to a swing shortened until its toe catches the nosing.

A riser taller than ``max_step_height`` is refused: the constructor raises ValueError naming
the terrain and the riser (:meth:`PatchTerrain.risers`); at run time a step that would need one
(terrain not described by its patches) stays in front of the edge, and the robot marks time.

Every sole keeps ``edge_margin`` behind its heel and ``approach_margin`` in front of its toe
clear of an edge. A larger ``approach_margin`` leaves the toe of the sole that stops short of a
riser room to rise before it moves on; it also lengthens the stride over the riser, and 0.07 m
fell more often at 0.12 m risers than 0.03 m (the value in tread_planner.yaml, = edge_margin).

The CoM height on stairs (params/controllers/walking_stairs.yaml, :class:`pr2_drake.controllers.planning.gait.
GaitPlanner`): the LIPM and the DCM stay horizontal, with one constant omega =
sqrt(g / com_height) (com_height 0.54 m above the stance soles); footholds enter the DCM laws by
their xy only. The height is a separate reference tracked by the QP's CoM-z objective: com_height
above the mean foothold height in double support, above the stance sole in single support
(``com_height_over_stance``), above the lower tread before and during a step-down
(``com_height_step_down``: the CoM descends before the swing sole has to reach down, so the
swing knee does not straighten), at most ``com_reach`` from every supporting sole counting the
CoM's offset along the heading (knee-limit-aware: after a step-up the rear sole, still on the
lower tread, keeps its knee bent), moved at ``height_rate`` (0.2 m/s). The horizontal LIPM law
goes to the QP as a CoM acceleration, not as a CoP: the QP finds contact forces for it, so the
vertical motion changes the CoP those forces need ((g + zdd) / (z - z_cop)) rather than the
horizontal motion. What the constant omega gets wrong while the height changes is a model
error that the feedback on the measured DCM corrects: the ankle term in single support, the
step adjustment of the swing target every tick, and the weight shift in double support.

Parameters: params/controllers/tread_planner.yaml. Units m, rad; frames W, sole S (x forward).

(No ``from __future__ import annotations``: ``yaml_load_typed`` reads the field types.)
"""

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from pr2_drake.controllers.planning.footsteps import FootstepPlanner, VelocityFootstepPlanner
from pr2_drake.controllers.planning.terrain import LEVEL_TOLERANCE, SAMPLE_STEP, PatchTerrain
from pr2_drake.controllers.walking_params import GaitParams
from pr2_drake.params import Params

#: [m] a swing sole within this of the stance sole along the heading stands beside it.
BESIDE = 0.05
#: [m] step adjustment moves a step up or down at most this far forward of its plan.
LEVEL_CHANGE_SLACK = 0.03
#: :meth:`TreadFootstepPlanner.catch_step` decides after this many calls (control ticks).
CATCH_MIN_TICKS = 5


@dataclass
class TreadPlannerParams(Params):
    """See params/controllers/tread_planner.yaml (m)."""

    FILE: ClassVar[str] = "params/controllers/tread_planner.yaml"
    edge_margin: float = 0.03  # heel and toe stay this far from an edge
    clearance: float = 0.05  # swing soles clear the highest ground on their way by this
    max_step_height: float = 0.12  # taller risers are refused
    min_progress: float = 0.03  # a step moved back must still advance this much
    approach_margin: float = 0.03  # the sole stopping short of a riser keeps its toe (heel,
    # going down) this far from the edge: room for the toe to rise before it moves on
    catch_excess: float = math.inf  # a swing planned short of an edge steps onto the next level
    catch_phase: float = 0.0  # when the DCM wants it this far beyond, before this swing phase



class TreadFootstepPlanner(FootstepPlanner):
    """Velocity footsteps on treads (see the module docstring).

    Args:
        gait: step period, width and limits (the stride limit of forward moves).
        start_threshold: |command| above this starts walking [m/s, rad/s].
        terrain: the terrain (its ``edge_margin`` and ``clearance`` are set from ``params``).
        params: planner parameters (None: params/controllers/tread_planner.yaml).

    Raises:
        ValueError: the terrain has a riser taller than ``params.max_step_height``.
    """

    # Step adjustment (capture point) may move a landing point, sideways freely and along the
    # sole only within its tread (:meth:`constrain`).
    adjustable = True

    def __init__(self, gait: GaitParams, start_threshold: float, terrain: PatchTerrain,
                 params: "TreadPlannerParams | None" = None):
        self.params = p = params or TreadPlannerParams.load()
        self.gait = gait
        self.terrain = terrain
        terrain.edge_margin = p.edge_margin
        terrain.clearance = p.clearance
        self.velocity = VelocityFootstepPlanner(gait, start_threshold)
        self._range_cache: dict[tuple, tuple[float, float]] = {}
        self._footholds: list = [None, None]
        self._catch_key: tuple | None = None  # the stop :meth:`catch_step` averages over ...
        self._catch_sum = (0.0, 0)  # ... and its excess sum [m] and count
        if not (p.catch_excess > 0.0 and 0.0 <= p.catch_phase <= 1.0):  # (NaN fails too)
            raise ValueError(
                f"TreadPlannerParams: catch_excess must be > 0 (inf: never) and catch_phase in "
                f"[0, 1], got catch_excess = {p.catch_excess}, catch_phase = {p.catch_phase}")
        for x, dz in terrain.risers():
            if abs(dz) > p.max_step_height + 1e-9:
                raise ValueError(
                    f"TreadFootstepPlanner: {terrain!r} has a {abs(dz):.3f} m riser at x = "
                    f"{x:.3f} m, taller than the planner's limit max_step_height = "
                    f"{p.max_step_height:.3f} m")

    def keep_walking(self, command, footholds) -> bool:
        return self.velocity.keep_walking(command, footholds)

    def first_swing_side(self, command, footholds) -> int:
        return self.velocity.first_swing_side(command, footholds)

    def observe(self, footholds) -> None:
        self._footholds = footholds

    def next_steps(self, stance, stance_side, heading, command, n):
        steps = []
        side = stance_side
        other = self._footholds[1 - stance_side]  # where the first swing sole starts
        for _ in range(n):
            proposed = self.velocity.next_steps(stance, side, heading, command, 1)[0]
            step = self.step_to(self.on_tread(proposed, stance), stance, other)
            other, stance = stance, step
            side = 1 - side
            steps.append(step)
        return steps

    def step_to(self, target: np.ndarray, stance: np.ndarray, swing: np.ndarray | None
                ) -> np.ndarray:
        """Step-to over risers, so that no swing sole travels more than one riser stride: a
        sole changes level only from beside the stance sole (both on one level), and the next
        one then joins it beside. Otherwise ``target`` (on a tread) is kept.

        Args:
            target: the planned foothold on a tread (x, y, z, yaw).
            stance: the stance sole; swing: where the swing sole starts (None: unknown).
        """
        if swing is None:
            return target
        t = self.terrain
        z_target = float(target[2])
        z_stance = t.height(float(stance[0]), float(stance[1]))
        z_swing = t.height(float(swing[0]), float(swing[1]))
        c, s = math.cos(target[3]), math.sin(target[3])
        beside = abs(c * (swing[0] - stance[0]) + s * (swing[1] - stance[1])) < BESIDE
        crossing = abs(z_target - z_stance) >= LEVEL_TOLERANCE
        joining = abs(z_swing - z_stance) >= LEVEL_TOLERANCE
        if crossing and not joining:
            # First up to the edge: the sole stops short of it (heel and toe plus the margin on
            # the stance sole's level) when the stance sole is farther back than that.
            half = 0.5 * t.foot_length + max(self.params.edge_margin,
                                             self.params.approach_margin)
            edges = t.edges_along(float(stance[0]), float(stance[1]), float(target[3]), 0.0,
                                  half + self.gait.max_step_forward + 0.1)
            if edges:
                short = edges[0] - half - 1e-3  # from the stance sole, along the target's x
                if short > BESIDE:
                    return np.array([stance[0] + c * short, stance[1] + s * short, z_stance,
                                     target[3]]) + self._lateral(target, stance, c, s)
        if not (joining or (crossing and not beside)):
            return target
        # Beside the stance sole: the target moved along its x axis to the stance sole's.
        along = c * (stance[0] - target[0]) + s * (stance[1] - target[1])
        return np.array([target[0] + c * along, target[1] + s * along, z_stance, target[3]])

    @staticmethod
    def _lateral(target, stance, c: float, s: float) -> np.ndarray:
        """The target's offset from the stance sole across its x axis, as a 4-vector."""
        lat = -s * (target[0] - stance[0]) + c * (target[1] - stance[1])
        return np.array([-s * lat, c * lat, 0.0, 0.0])

    def constrain(self, target_xy: np.ndarray, planned: np.ndarray) -> np.ndarray:
        """The adjusted landing point with its offset along the planned sole's x axis clipped
        so that heel and toe (plus the margin) stay on the planned foothold's level, and a
        step up or down at most :data:`LEVEL_CHANGE_SLACK` forward of its plan."""
        lo, hi = self._level_range(planned)
        if self._changes_level(planned):  # a step up or down: no longer stride over the riser
            hi = min(hi, LEVEL_CHANGE_SLACK)
        c, s = math.cos(planned[3]), math.sin(planned[3])
        dx, dy = float(target_xy[0] - planned[0]), float(target_xy[1] - planned[1])
        along = c * dx + s * dy
        clipped = min(max(along, lo), hi)
        if clipped == along:
            return target_xy
        return np.array([target_xy[0] + c * (clipped - along), target_xy[1] + s * (clipped - along)])

    def catch_step(self, wish_xy: np.ndarray, planned: np.ndarray, stance: np.ndarray,
                   progress: float) -> np.ndarray | None:
        """The step onto the next level, when ``planned`` stays on the stance sole's level short
        of an edge (a step-to stop) but step adjustment wishes the landing more than
        ``catch_excess`` past the front limit of that level, before swing phase
        ``catch_phase``: the DCM runs ahead (a push, a fast approach), and stopping short would
        leave the step up to a shortened swing that catches its toe on the nosing. The new
        foothold has its heel (plus ``edge_margin``) just past the edge, within the stride limit
        and ``max_step_height``; otherwise None (keep the plan)."""
        p = self.params
        if progress >= p.catch_phase or abs(float(planned[2]) - float(stance[2])) > 0.02:
            return None
        _, hi = self._level_range(planned)
        x, y, yaw = float(planned[0]), float(planned[1]), float(planned[3])
        c, s = math.cos(yaw), math.sin(yaw)
        # The excess averaged over this swing's calls so far: one tick's wish moves by
        # centimetres with the sensor noise (the DCM's error grows ~5x to the landing).
        key = (x, y)
        total, n = self._catch_sum if self._catch_key == key else (0.0, 0)
        total, n = total + c * (wish_xy[0] - x) + s * (wish_xy[1] - y) - hi, n + 1
        self._catch_key, self._catch_sum = key, (total, n)
        if n < CATCH_MIN_TICKS or total / n < p.catch_excess:
            return None
        t = self.terrain
        half = 0.5 * t.foot_length + p.edge_margin
        edges = t.edges_along(x, y, yaw, 0.0, hi + half + 0.02)
        if not edges:
            return None
        d = edges[0] + half + SAMPLE_STEP  # (an edge is known to a sample)
        x, y = x + c * d, y + s * d
        z = t.heights_along(x, y, yaw, -half, half)
        advance = c * (x - float(stance[0])) + s * (y - float(stance[1]))
        if (z.max() - z.min() >= LEVEL_TOLERANCE or advance > self.gait.max_step_forward + 0.05
                or abs(float(z[0]) - float(stance[2])) > p.max_step_height + 1e-9):
            return None
        return np.array([x, y, float(z[0]), yaw])

    def _changes_level(self, planned: np.ndarray) -> bool:
        """Whether ``planned`` is on another level than both soles now."""
        return all(f is None or abs(float(planned[2]) - float(f[2])) > 0.02
                   for f in self._footholds)

    def _level_range(self, planned: np.ndarray) -> tuple[float, float]:
        """Shifts [m] along the planned sole's x axis that keep it on its level (cached)."""
        key = (round(float(planned[0]), 4), round(float(planned[1]), 4),
               round(float(planned[3]), 4))
        r = self._range_cache.get(key)
        if r is None:
            if len(self._range_cache) > 64:
                self._range_cache.clear()
            half = 0.5 * self.terrain.foot_length + self.params.edge_margin
            reach = self.gait.max_step_forward + 0.1
            x, y, yaw = float(planned[0]), float(planned[1]), float(planned[3])
            edges = self.terrain.edges_along(x, y, yaw, -reach - half, reach + half)
            behind = [e for e in edges if e < 0.0]
            ahead = [e for e in edges if e > 0.0]
            lo = (behind[-1] + half) if behind else -reach
            hi = (ahead[0] - half) if ahead else reach
            r = (min(lo, 0.0), max(hi, 0.0))
            self._range_cache[key] = r
        return r

    def on_tread(self, target: np.ndarray, stance: np.ndarray) -> np.ndarray:
        """``target`` (x, y, z, yaw) moved along its x axis onto one level (see the module
        docstring), with the terrain height; ``stance`` is the sole it steps from."""
        t = self.terrain
        p = self.params
        half = 0.5 * t.foot_length + p.edge_margin
        # In front of the toe the margin is approach_margin: a sole that stops short of an
        # edge leaves its toe room to rise before it moves on (no catch on the nosing).
        front = 0.5 * t.foot_length + max(p.edge_margin, p.approach_margin)
        yaw = float(target[3])
        c, s = math.cos(yaw), math.sin(yaw)
        x, y = float(target[0]), float(target[1])
        z_stance = t.height(float(stance[0]), float(stance[1]))

        def advance(d: float) -> float:  # progress along yaw from the stance sole
            return c * (x + c * d - stance[0]) + s * (y + s * d - stance[1])

        def level(d: float) -> float | None:  # the height under the sole moved by d, or None
            z = t.heights_along(x + c * d, y + s * d, yaw, -half, front)
            return float(z[0]) if z.max() - z.min() < LEVEL_TOLERANCE else None

        options = []
        for direction in (-1.0, 1.0):
            d = 0.0
            for _ in range(6):  # past up to a few short treads
                if level(d) is not None:
                    break
                edges = t.edges_along(x + c * d, y + s * d, yaw, -half, front)
                d += (edges[0] - front) if direction < 0 else (edges[-1] + half)
                d += direction * 1e-3
            z = level(d)
            if z is not None:
                options.append((d, z))
        reach = self.gait.max_step_forward + 0.05
        ok = [(d, z) for d, z in options
              if abs(z - z_stance) <= p.max_step_height + 1e-9 and advance(d) <= reach]
        if not ok:  # refused (riser too tall or too far): stay at the stance sole's level
            ok = [(d, z) for d, z in options if abs(z - z_stance) < LEVEL_TOLERANCE] or [
                (0.0, z_stance)]
        back = [o for o in ok if o[0] <= 0.0]
        fwd = [o for o in ok if o[0] > 0.0]
        if back and (not fwd or (advance(back[0][0]) >= p.min_progress
                                 and abs(back[0][0]) <= abs(fwd[0][0]))):
            d, z = back[0]
        elif fwd:
            d, z = fwd[0]
        else:
            d, z = back[0]
        return np.array([x + c * d, y + s * d, z, yaw])

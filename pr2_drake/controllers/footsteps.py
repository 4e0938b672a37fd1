"""Footstep planner: the velocity command -> the next sole poses.

A footstep is a sole pose on flat ground, ``(x, y, z, yaw)`` in W [m, rad]. Sides: 0 left, 1
right; ``SIDE_SIGN[side]`` is +1 for the left sole (lateral offset to +y of the heading frame).

One step moves the heading frame H (midway between the soles, x along the heading yaw) by the
command times the step period, and places the swing sole at half the stance width beside it.
Walking sideways, the leading foot steps out wide and the trailing foot returns to the nominal
width, so the feet never cross. Step lengths, extra width and yaw per step are clamped.
"""

from __future__ import annotations

import numpy as np

from pr2_drake.controllers.walking_params import GaitParams

SIDE_SIGN = (1.0, -1.0)


def rot2(yaw: float) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s], [s, c]])


def wrap(angle: float) -> float:
    return float((angle + np.pi) % (2 * np.pi) - np.pi)


def next_footstep(stance: np.ndarray, stance_side: int, heading: float, command: np.ndarray,
                  gait: GaitParams) -> np.ndarray:
    """Pose of the swing sole (side ``1 - stance_side``) one step from now.

    Args:
        stance: stance sole (x, y, z, yaw).
        heading: yaw of the heading frame now [rad] (closes the heading loop: feet land along it,
            not along a drifted stance foot).
        command: (vx, vy, yaw_rate) in the heading frame [m/s, m/s, rad/s].
    """
    swing_side = 1 - stance_side
    s = SIDE_SIGN[swing_side]
    period = gait.step_period
    vx, vy, wz = command
    dx = float(np.clip(vx * period, -gait.max_step_backward, gait.max_step_forward))
    dy = float(np.clip(vy * period, -gait.max_step_lateral, gait.max_step_lateral))
    dyaw = float(np.clip(wz * period, -gait.max_step_yaw, gait.max_step_yaw))
    # Heading frame under the stance foot now, then moved by one step.
    p_H = stance[:2] + rot2(heading) @ np.array([0.0, s * gait.step_width / 2])
    yaw_new = heading + dyaw
    p_H_new = p_H + rot2(heading + dyaw / 2) @ np.array([dx, dy])
    # Swing sole beside it; the leading side of a sideways walk steps out by |dy|.
    lateral = s * (gait.step_width / 2 + abs(dy))
    p = p_H_new + rot2(yaw_new) @ np.array([0.0, lateral])
    return np.array([p[0], p[1], stance[2], wrap(yaw_new)])


def clamp_to_stance(target: np.ndarray, stance: np.ndarray, stance_side: int,
                    gait: GaitParams) -> np.ndarray:
    """Keep a swing target reachable from the stance sole: bounded stride, no crossing."""
    s = SIDE_SIGN[1 - stance_side]
    R = rot2(stance[3])
    d = R.T @ (target[:2] - stance[:2])
    d[0] = np.clip(d[0], -gait.max_step_backward - 0.05, gait.max_step_forward + 0.05)
    lateral = s * d[1]
    lateral = np.clip(lateral, gait.min_step_width,
                      gait.step_width + 2 * gait.max_step_lateral + 0.05)
    d[1] = s * lateral
    out = target.copy()
    out[:2] = stance[:2] + R @ d
    dyaw = wrap(target[3] - stance[3])
    out[3] = stance[3] + np.clip(dyaw, -gait.max_step_yaw - 0.1, gait.max_step_yaw + 0.1)
    return out


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
        (it lifts, moves, then lowers: :class:`pr2_drake.controllers.swing.SwingTrajectory`),
        or None for the plain swing curve (no edge on the way; the default)."""
        return None


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


class FootstepPlanner:
    """Interface of a footstep planner: which sole steps first and where the next soles land.

    The gait state machine (:class:`pr2_drake.controllers.gait.GaitPlanner`) asks it at the
    start of a walk and at every touchdown; step adjustment may then move the landing point.
    Footsteps are sole poses (x, y, z, yaw) in W [m, rad]; sides 0 left, 1 right.

    ``adjustable``: whether step adjustment (capture point) may move a planned landing point
    and time (True: robust to pushes; False: the soles land on the planned footholds).
    """

    adjustable = True

    def keep_walking(self, command: np.ndarray, footholds: list) -> bool:
        """Whether to (keep) step(ping), given the velocity command and the soles' footholds."""
        raise NotImplementedError

    def first_swing_side(self, command: np.ndarray, footholds: list) -> int:
        """The side that lifts off first when a walk starts."""
        raise NotImplementedError

    def next_steps(self, stance: np.ndarray, stance_side: int, heading: float,
                   command: np.ndarray, n: int) -> list[np.ndarray]:
        """The ``n`` footholds after a sole at ``stance`` (side ``stance_side``): the first on
        the other side, then alternating."""
        raise NotImplementedError

    def observe(self, footholds: list) -> None:
        """The soles' footholds now, [left, right] (x, y, z, yaw) in W, given every tick before
        any planning (a planner that needs the swing sole's start keeps them). Default: unused."""

    def constrain(self, target_xy: np.ndarray, planned: np.ndarray) -> np.ndarray:
        """Where an adjusted landing point (xy, W) of the planned footstep ``planned`` (x, y,
        z, yaw) may go (e.g. kept on its tread); step adjustment calls it. Default: anywhere."""
        return target_xy


class VelocityFootstepPlanner(FootstepPlanner):
    """Footsteps from the velocity command (:func:`next_footstep`), clamped per step.

    Args:
        gait: step period, width and limits.
        start_threshold: |command| above this [m/s or rad/s] starts (and keeps) walking.
    """

    def __init__(self, gait: GaitParams, start_threshold: float):
        self.gait = gait
        self.start_threshold = float(start_threshold)

    def keep_walking(self, command, footholds) -> bool:
        th = self.start_threshold
        return bool(abs(command[0]) > th or abs(command[1]) > th or abs(command[2]) > th)

    def first_swing_side(self, command, footholds) -> int:
        # Lead with the foot on the side of motion (sideways or turning), else the right foot.
        th = self.start_threshold
        if abs(command[1]) > th:
            return 0 if command[1] > 0 else 1
        if abs(command[2]) > th:
            return 0 if command[2] > 0 else 1
        return 1

    def next_steps(self, stance, stance_side, heading, command, n):
        steps = []
        side = stance_side
        for _ in range(n):
            stance = next_footstep(stance, side, heading, command, self.gait)
            side = 1 - side
            steps.append(stance)
        return steps


class FixedFootstepPlanner(FootstepPlanner):
    """A given list of footholds, stepped in order, then stop with the feet side by side.

    Args:
        footholds: sole poses (x, y, z, yaw) in W, alternating sides, the first on
            ``first_side``.
        first_side: side of the first footstep (0 left, 1 right).
        gait: the nominal step width (the closing step beside the last foothold).
        tolerance: [m] a sole within this of a listed foothold (same side) has landed there.
        adjustable: let step adjustment move the landings (default False: land on the list).
    """

    def __init__(self, footholds, first_side: int, gait: GaitParams, tolerance: float = 0.05,
                 adjustable: bool = False):
        self.adjustable = bool(adjustable)
        self.steps = [np.asarray(f, dtype=float).reshape(4) for f in footholds]
        if not self.steps or any(not np.all(np.isfinite(f)) for f in self.steps):
            raise ValueError("FixedFootstepPlanner: footholds must be finite (x, y, z, yaw)")
        if first_side not in (0, 1):
            raise ValueError(f"FixedFootstepPlanner: first_side must be 0 or 1, got {first_side}")
        self.first_side = first_side
        self.gait = gait
        self.tolerance = float(tolerance)

    def side(self, k: int) -> int:
        return self.first_side if k % 2 == 0 else 1 - self.first_side

    def _index(self, sole: np.ndarray, side: int) -> int:
        """Index of the listed foothold at ``sole`` (same side), or -1."""
        for k in range(len(self.steps) - 1, -1, -1):
            if (self.side(k) == side
                    and np.hypot(*(self.steps[k][:2] - sole[:2])) < self.tolerance):
                return k
        return -1

    def keep_walking(self, command, footholds) -> bool:
        last = len(self.steps) - 1
        f = footholds[self.side(last)]
        return f is None or self._index(f, self.side(last)) != last

    def first_swing_side(self, command, footholds) -> int:
        return self.first_side

    def next_steps(self, stance, stance_side, heading, command, n):
        k = self._index(stance, stance_side)
        out = list(self.steps[k + 1:k + 1 + n])
        side = stance_side if not out else self.side(k + len(out))
        last = stance if not out else out[-1]
        zero = np.zeros(3)
        while len(out) < n:  # then close: step beside the last foothold
            last = next_footstep(last, side, float(last[3]), zero, self.gait)
            side = 1 - side
            out.append(last)
        return out

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

from pr2_drake.controllers.frames import rot2, wrap
from pr2_drake.controllers.walking_params import GaitParams

SIDE_SIGN = (1.0, -1.0)


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


def square_stance(a: np.ndarray, b: np.ndarray, side_a: int, gait: GaitParams) -> bool:
    """True when sole a (x, y, z, yaw; side ``side_a``) stands about beside sole b: a stance
    to stop on."""
    d = rot2(b[3]).T @ (a[:2] - b[:2])
    lateral = SIDE_SIGN[side_a] * d[1]
    return bool(abs(d[0]) < 0.06 and gait.min_step_width <= lateral <= gait.step_width + 0.08
                and abs(wrap(a[3] - b[3])) < 0.15)


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


class FootstepPlanner:
    """Interface of a footstep planner: which sole steps first and where the next soles land.

    The gait state machine (:class:`pr2_drake.controllers.planning.gait.GaitPlanner`) asks it at the
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

    def catch_step(self, wish_xy: np.ndarray, planned: np.ndarray, stance: np.ndarray,
                   progress: float) -> np.ndarray | None:
        """A footstep (x, y, z, yaw) that replaces ``planned`` mid-swing when the landing point
        step adjustment wishes for (xy, W) lies beyond what ``planned``'s level allows (e.g. a
        step-to stop before a riser while the DCM runs ahead: step onto the next tread now);
        ``stance`` is the stance sole, ``progress`` the swing phase. Default: None (keep it)."""
        return None

    def swing_clearance(self, start: np.ndarray, target: np.ndarray) -> float | None:
        """Height [m, W] the swing sole from ``start`` to ``target`` (x, y, z, yaw) must clear
        (a high lift-move-lower swing, e.g. stepping over an obstacle: :mod:`pr2_drake.
        controllers.step_over`), or None (default: the terrain model decides). The gait
        planner asks at lift-off; the higher of this and the terrain's clearance counts."""
        return None


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

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

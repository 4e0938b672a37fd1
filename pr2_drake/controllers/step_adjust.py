"""Step adjustment: where and when the swing sole lands, from the capture point (DCM).

With the ZMP on the stance sole at p, the DCM xi = c + cdot / omega of the linear inverted
pendulum diverges as xi(t) = p + (xi_now - p) exp(omega (t - t_now)). A swing sole landing at u
at time T leaves the DCM at xi(T) - u from the new stance sole; the walk continues as planned
when that offset equals b, the periodic offset of the planned next steps. So the ideal landing
point for a landing time T is u*(T) = xi(T) - b.

:func:`choose_step` searches the landing time over a grid (earlier or later than planned, within
the swing-time limits) and, for each, puts the sole at u*(T) clipped to what the stance leg can
reach (stride box in the stance sole's frame, feet never crossing). It minimises

    w_x r_x^2 + w_out max(r_out, 0)^2 + w_in min(r_out, 0)^2 + w_t (T - T_plan)^2

with r = u*(T) - u the part of the ideal step the leg cannot reach (x along the stance sole,
r_out sideways, positive away from the stance sole). An outward residual leaves the DCM outside
the new stance sole (only a crossing step could catch it), so it weighs most; an inward one
leaves it between the feet, where the next step catches it. This is the step-location and
step-timing adjustment of Khadiv et al. (2016) solved by enumeration: one dimension, a few
dozen candidates, exact and deterministic.

Positions are xy in W [m], times absolute [s].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pr2_drake.controllers.footsteps import SIDE_SIGN, rot2
from pr2_drake.controllers.walking_params import GaitParams


@dataclass
class StepChoice:
    """The chosen landing: sole xy [m, W], landing time [s], and its cost terms."""

    target_xy: np.ndarray
    landing_time: float
    cost: float
    residual: np.ndarray  # (x along the stance sole, outward) [m], unreachable part of u*


def reach_box(gait: GaitParams) -> tuple[float, float, float, float]:
    """Reachable swing-sole offsets from the stance sole (its frame): x_min, x_max [m] and
    lateral min, max [m] (away from the stance sole)."""
    return (-gait.max_step_backward - 0.05, gait.max_step_forward + 0.05,
            gait.recovery_min_step_width, gait.step_width + 2 * gait.max_step_lateral + 0.05)


def choose_step(t: float, xi: np.ndarray, p_st: np.ndarray, stance: np.ndarray, stance_side: int,
                plan_xy: np.ndarray, b: np.ndarray, heading: float, t_earliest: float,
                t_planned: float, t_latest: float, t_current: float, gait: GaitParams,
                omega: float) -> StepChoice:
    """Best landing point and time for the swing sole (side ``1 - stance_side``).

    Args:
        t: now [s]. xi: DCM now (xy, W). p_st: ZMP point of the stance sole (xy, W).
        stance: stance sole (x, y, z, yaw). plan_xy: the planned footstep (xy, W).
        b: periodic DCM offset at the switch onto the planned footstep (xy, W).
        heading: heading yaw [rad] (axes of the ``dcm_gain`` blend).
        t_earliest, t_latest: landing-time window [s, absolute] (empty: keep t_current).
        t_planned: the planned landing time [s, absolute].
        t_current: the landing time the swing follows now (always a candidate); others cost
            ``retime_penalty`` more (no dithering between nearly equal times).
    """
    g = gait
    if t_latest >= t_earliest:
        n = int(round((t_latest - t_earliest) / max(g.timing_grid, 1e-3))) + 1
        times = np.unique(np.r_[np.linspace(t_earliest, t_latest, max(n, 2)), t_current])
    else:
        times = np.array([t_current])
    growth = np.exp(omega * (times - t + 0.5 * g.double_support))
    xi_pred = p_st[None, :] + (xi - p_st)[None, :] * growth[:, None]  # (n, 2)
    # Ideal landing points, blended with the plan per heading-frame axis.
    R_h = rot2(heading)
    gain = np.asarray(g.dcm_gain, dtype=float)
    e_H = (xi_pred - b[None, :] - plan_xy[None, :]) @ R_h  # rows: R_h^T (u* - plan)
    u_star = plan_xy[None, :] + (e_H * gain[None, :]) @ R_h.T
    # Into the stance sole's frame, clip to the reachable box.
    R_s = rot2(stance[3])
    d = (u_star - stance[None, :2]) @ R_s  # (n, 2): x, y in the stance frame
    s = SIDE_SIGN[1 - stance_side]
    x_min, x_max, w_min, w_max = reach_box(g)
    x = np.clip(d[:, 0], x_min, x_max)
    lat = np.clip(s * d[:, 1], w_min, w_max)
    r_x = d[:, 0] - x
    r_out = s * d[:, 1] - lat
    cost = (g.step_cost_x * r_x**2 + g.step_cost_outward * np.maximum(r_out, 0.0) ** 2
            + g.step_cost_inward * np.minimum(r_out, 0.0) ** 2
            + g.step_cost_timing * (times - t_planned) ** 2
            + np.where(np.abs(times - t_current) > 1e-6, g.retime_penalty, 0.0))
    k = int(np.argmin(cost))
    target = stance[:2] + R_s @ np.array([x[k], s * lat[k]])
    return StepChoice(target, float(times[k]), float(cost[k]), np.array([r_x[k], r_out[k]]))

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

import math
from dataclasses import dataclass

import numpy as np

from pr2_drake.controllers.planning.com_plan import zmp_point
from pr2_drake.controllers.planning.footsteps import SIDE_SIGN
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
    back = gait.recovery_step_backward or gait.max_step_backward + 0.05
    return (-back, gait.max_step_forward + 0.05,
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
    # Candidate landing times: the window on the timing grid, and the current time. (Plain
    # Python on purpose: a few dozen scalars every control tick are cheaper than numpy calls.)
    if t_latest >= t_earliest:
        n = max(int(round((t_latest - t_earliest) / max(g.timing_grid, 1e-3))) + 1, 2)
        step = (t_latest - t_earliest) / (n - 1)
        times = [t_earliest + i * step for i in range(n)] + [t_current]
    else:
        times = [t_current]
    px, py = float(p_st[0]), float(p_st[1])
    ex, ey = float(xi[0]) - px, float(xi[1]) - py
    bx, by = float(b[0]), float(b[1])
    gx, gy = float(g.dcm_gain[0]), float(g.dcm_gain[1])
    blend = gx != 1.0 or gy != 1.0
    ch, sh = math.cos(heading), math.sin(heading)
    cs, ss = math.cos(stance[3]), math.sin(stance[3])
    sx, sy = float(stance[0]), float(stance[1])
    sgn = SIDE_SIGN[1 - stance_side]
    x_min, x_max, w_min, w_max = reach_box(g)
    half_ds = 0.5 * g.double_support
    w_x, w_out, w_in = g.step_cost_x, g.step_cost_outward, g.step_cost_inward
    w_t, penalty = g.step_cost_timing, g.retime_penalty
    if blend:
        # The blend is affine in the growth: u = u0 + growth u1 (plan p0 plus, in the heading
        # frame, the gains times u* - p0), its terms computed once for all candidates.
        p0x, p0y = float(plan_xy[0]), float(plan_xy[1])
        ax, ay = px - bx - p0x, py - by - p0y
        h0x, h0y = (ch * ax + sh * ay) * gx, (-sh * ax + ch * ay) * gy
        h1x, h1y = (ch * ex + sh * ey) * gx, (-sh * ex + ch * ey) * gy
        u0x, u0y = p0x + ch * h0x - sh * h0y, p0y + sh * h0x + ch * h0y
        u1x, u1y = ch * h1x - sh * h1y, sh * h1x + ch * h1y
    exp = math.exp
    best = None
    for T in times:
        growth = exp(omega * (T - t + half_ds))
        # Ideal landing point u* = xi(T) - b, blended with the plan per heading-frame axis.
        if blend:
            ux = u0x + growth * u1x
            uy = u0y + growth * u1y
        else:
            ux = px + ex * growth - bx
            uy = py + ey * growth - by
        # In the stance sole's frame, clipped to the reachable box.
        rx, ry = ux - sx, uy - sy
        dx = cs * rx + ss * ry
        dlat = sgn * (-ss * rx + cs * ry)
        # min(max(dx, x_min), x_max), without the builtins' call overhead (same comparisons)
        x = x_min if x_min > dx else dx
        x = x_max if x_max < x else x
        lat = w_min if w_min > dlat else dlat
        lat = w_max if w_max < lat else lat
        r_x, r_out = dx - x, dlat - lat
        cost = (w_x * r_x * r_x + (w_out if r_out > 0.0 else w_in) * r_out * r_out
                + w_t * (T - t_planned) ** 2 + (penalty if abs(T - t_current) > 1e-6 else 0.0))
        if best is None or cost < best[0]:
            best = (cost, T, x, lat, r_x, r_out)
    cost, T, x, lat, r_x, r_out = best
    y = sgn * lat
    target = np.array([sx + cs * x - ss * y, sy + ss * x + cs * y])
    return StepChoice(target, T, cost, np.array([r_x, r_out]))


def periodic_dcm_offset(footsteps, f1: np.ndarray, side: int, heading: float,
                        command: np.ndarray, gait: GaitParams, omega: float) -> np.ndarray:
    """Periodic DCM offset b (xy, W) [m] at the switch onto footstep ``f1`` (x, y, z, yaw) of
    sole ``side``: for the next two planned steps L1, L2 (``footsteps.next_steps``) of period
    T, b = (L1 exp(omega T) + L2) / (exp(2 omega T) - 1)."""
    f2, f3 = footsteps.next_steps(f1, side, heading, command, 2)
    L1 = zmp_point(f2, gait) - zmp_point(f1, gait)
    L2 = zmp_point(f3, gait) - zmp_point(f2, gait)
    e = np.exp(omega * gait.step_period)
    return (L1 * e + L2) / (e * e - 1.0)

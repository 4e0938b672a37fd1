"""CoM planning with the linear inverted pendulum and ZMP preview (pydrake ZmpPlanner).

``plan`` takes a piecewise-linear desired ZMP (knot times and xy points) and the measured CoM
state; every tick ``comdd`` evaluates the planner's optimal feedback policy (the LQR solution of
the ZMP-tracking problem) at the measured state. The walking controller uses it to bring the
CoM to rest over the middle of the soles after the last step. All positions are xy in W [m],
times in s.
"""

from __future__ import annotations

import math

import numpy as np
from pydrake.planning import ZmpPlanner
from pydrake.trajectories import PiecewisePolynomial

from pr2_drake.controllers.walking_params import GaitParams


def zmp_point(step: np.ndarray, gait: GaitParams) -> np.ndarray:
    """Reference ZMP of a sole pose (x, y, z, yaw): its centre plus the configured x offset."""
    # rot2(yaw) @ (x_offset, 0), written out: a product with a zero adds nothing.
    yaw, dx = step[3], gait.zmp_offset_x
    return step[:2] + np.array([math.cos(yaw) * dx, math.sin(yaw) * dx])


class ComPlanner:
    """Wraps ZmpPlanner: plan from knots, then the optimal CoM acceleration per tick."""

    def __init__(self, gait: GaitParams, gravity: float = 9.81):
        self.gait = gait
        self.gravity = gravity
        self.planner: ZmpPlanner | None = None
        self.t_end = -np.inf
        self.zmp_traj: PiecewisePolynomial | None = None

    def plan(self, times: np.ndarray, points: np.ndarray, com_xy: np.ndarray,
             comd_xy: np.ndarray, height: float) -> None:
        """Plan from the measured CoM state (xy position [m] and velocity [m/s])."""
        traj = PiecewisePolynomial.FirstOrderHold(times, points)
        planner = ZmpPlanner()
        x0 = np.concatenate([com_xy, comd_xy])
        g = self.gait
        planner.Plan(traj, x0, height, self.gravity, g.zmp_qy * np.eye(2), g.zmp_r * np.eye(2))
        self.planner = planner
        self.zmp_traj = traj
        self.t_end = float(times[-1])

    def comdd(self, t: float, com_xy: np.ndarray, comd_xy: np.ndarray) -> np.ndarray:
        """Optimal CoM acceleration [m/s^2] (xy) at time t for the measured state."""
        t = min(t, self.t_end)
        return self.planner.ComputeOptimalCoMdd(t, np.concatenate([com_xy, comd_xy]))

    def nominal(self, t: float):
        """Planned CoM position and velocity (xy) at time t."""
        t = min(t, self.t_end)
        return (self.planner.get_nominal_com(t).reshape(-1)[:2],
                self.planner.get_nominal_comd(t).reshape(-1)[:2])

    def desired_zmp(self, t: float) -> np.ndarray:
        t = min(t, self.t_end)
        return self.zmp_traj.value(t).reshape(-1)

"""Online estimate of the offset between the robot's centre of mass and the model's.

The controller's model has nominal link masses and the base's centre of mass where the URDF
puts it. A real robot differs (a battery, a cable loom, a heavier limb): a CoM a centimetre to
one side of the model's is a steady gravity torque the gait does not plan for. In single support
the DCM then drifts to that side at every step; step adjustment catches it by stepping further
out, and the robot walks sideways (task 1 with ``randomize.enabled=true``: 8 of the 10 episodes
that left the road sideways had the base's CoM drawn 1-2 cm to one side of the model's).

The estimate integrates the single-support DCM error, expressed in the pelvis' yaw frame (the
offset moves with the body) and clipped to ``com_bias_error_max`` [m] (a stumble's or a push's
error of 10 cm counts no more than a bias would), at ``com_bias_rate`` [1/s], within
``com_bias_max`` [m] per axis.
The gait planner then plans with the measured CoM plus the estimate: it holds the real CoM, not
the model's, over its ZMP. Errors that alternate with the stance side (the swing leg's own
dynamics) and transients (a push, a stone) average out over steps; a bias does not.
``com_bias_rate`` 0 turns it off: the default (params/controllers/walking.yaml); the rocky-road,
valve and stairs agents turn it on (walking_rough.yaml, walking_valve.yaml,
walking_stairs.yaml), and the task-6 search agent at 0.5 /s (walking_search.yaml).
"""

from __future__ import annotations

import math

import numpy as np


class ComBiasEstimator:
    """The offset p_CmC (x forward, y left in the pelvis' yaw frame) [m] and its update.

    Args:
        gait: the gait parameters (``walking_params.GaitParams``): ``com_bias_rate`` [1/s],
            ``com_bias_error_max`` [m], ``com_bias_max`` [m] and ``com_bias_axes`` ("xy" or
            "y").
    """

    def __init__(self, gait):
        self.gait = gait
        self.mask = (1.0 if "x" in gait.com_bias_axes else 0.0,
                     1.0 if "y" in gait.com_bias_axes else 0.0)
        self.reset()

    @property
    def enabled(self) -> bool:
        """Whether the estimate learns (``com_bias_rate`` > 0)."""
        return self.gait.com_bias_rate > 0.0

    def reset(self) -> None:
        self.x = 0.0
        self.y = 0.0

    def shifted(self, com: np.ndarray, yaw: float) -> np.ndarray:
        """The CoM p_WC [m] the planner should use: ``com`` (the model's) plus the offset,
        rotated by the pelvis' yaw [rad]. Returns ``com`` itself while the offset is zero."""
        if self.x == 0.0 and self.y == 0.0:
            return com
        c, s = math.cos(yaw), math.sin(yaw)
        out = np.array(com, dtype=float)
        out[0] += c * self.x - s * self.y
        out[1] += s * self.x + c * self.y
        return out

    def observe(self, xi_err_W: np.ndarray, yaw: float, dt: float) -> None:
        """One single-support tick of dt [s]: the DCM error xi - xi_ref (xy, W) [m]."""
        g = self.gait
        rate = g.com_bias_rate * dt
        if rate <= 0.0:
            return
        c, s = math.cos(yaw), math.sin(yaw)
        ex, ey = float(xi_err_W[0]), float(xi_err_W[1])
        e_lim, lim = g.com_bias_error_max, g.com_bias_max
        ex, ey = (min(max(c * ex + s * ey, -e_lim), e_lim),
                  min(max(-s * ex + c * ey, -e_lim), e_lim))
        self.x = min(max(self.x + rate * self.mask[0] * ex, -lim), lim)
        self.y = min(max(self.y + rate * self.mask[1] * ey, -lim), lim)

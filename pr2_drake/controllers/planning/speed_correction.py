"""Integral correction of the planned walking speed (x, y in the heading frame).

Footsteps planned for the commanded speed do not give exactly that speed: a CoM off the model's
(a heavier limb, the base's centre of mass a centimetre off), friction and the soles' roll bias
every step a little, and the robot drifts. At each touchdown the CoM's mean velocity over the
last step is compared with the command and ``speed_gain`` times the error is added to the
speed the footstep planner is given (clipped to ``speed_correction_max`` [m/s]).

The integration holds while the linear command really changes (a ramp of the acceleration
limit, or a change beyond ``speed_hold_change`` [m/s] since the step began), so that a new
command is not fought as an error (wind-up), and the correction then shrinks by the factor
``speed_hold_decay`` per step: it was learnt for another command. Sideways, an agent's small
per-tick adjustments (a heading loop trims vx and the yaw rate at every tick) do not hold it:
with them held, a bias was never corrected and the robot left a road sideways. Forward, a step
counts only when the command did not change at all during it (a faster forward correction
on rough ground sped the robot into stumbles).

The speed compared is the mean over the last ``speed_window_steps`` steps. One step (the
default) sees the sideways sway: a step's mean lateral speed swings by 0.1-0.5 m/s from one
step to the next, and the correction swings with it. Two steps (a stride) cancel the sway and
leave the drift. A window whose error exceeds ``speed_error_max`` [m/s] (0: no limit) is not
integrated: a push, not a bias, moved the robot, and the step adjustment answers it.
"""

from __future__ import annotations

import math

import numpy as np

from pr2_drake.controllers.frames import rot2


class SpeedCorrection:
    """The correction [m/s] (``value``, xy in the heading frame) and its memory.

    Args:
        gait: the gait parameters (``walking_params.GaitParams``).
    """

    def __init__(self, gait):
        self.gait = gait
        self.reset(-math.inf, np.zeros(2))

    def reset(self, t: float, com_xy: np.ndarray) -> None:
        """Start from no correction at a step beginning at time t [s], CoM at ``com_xy``."""
        self.value = np.zeros(2)
        self._marks = [(t, np.array(com_xy[:2], dtype=float))]  # touchdowns: (t [s], CoM xy W)
        self._anchor = None  # linear command [m/s] the current hold-free span began with
        self._t_change = math.inf
        self._t_any_change = math.inf
        self._last = [0.0, 0.0, 0.0]

    def observe_command(self, t: float, target: list, command: list) -> None:
        """The tick's command: ``target`` (clipped, before the rate limit) and ``command`` (the
        rate-limited one used), each (vx, vy, yaw_rate)."""
        ramping = (abs(target[0] - command[0]) > 1e-9 or abs(target[1] - command[1]) > 1e-9)
        if any(abs(x - c) > 1e-9 for x, c in zip(command, self._last)):
            self._t_any_change = t
        self._last = list(command)
        a = self._anchor
        if (ramping or a is None
                or max(abs(command[0] - a[0]), abs(command[1] - a[1]))
                > self.gait.speed_hold_change):
            self._anchor = (command[0], command[1])
            self._t_change = t

    def touchdown(self, t: float, com_xy: np.ndarray, command: np.ndarray,
                  heading: float) -> None:
        """A touchdown at t [s], CoM at ``com_xy`` (W): integrate the speed error of the window
        of the last ``speed_window_steps`` steps (heading frame, ``heading`` [rad])."""
        g = self.gait
        n = g.speed_window_steps
        t_last = self._marks[-1][0]
        self._marks.append((t, np.array(com_xy[:2], dtype=float)))
        del self._marks[:-(n + 1)]
        if t_last < self._t_change:
            # The command changed: what was learnt for the old one fades (a lateral correction
            # wound up while turning cancelled a valve approach's small sideways steps).
            self.value *= g.speed_hold_decay
            return
        if len(self._marks) < n + 1:
            return  # the window is not full yet
        t0, c0 = self._marks[0]
        if t0 < self._t_change:
            return  # the window began under another command
        if t - t0 < 0.5 * n * g.step_period or t - t0 > 3.0 * n * g.step_period:
            return  # no integration over odd steps
        v_H = rot2(heading).T @ (com_xy[:2] - c0) / (t - t0)
        err = command[:2] - v_H
        if t0 < self._t_any_change:
            err[0] = 0.0
        if g.speed_error_max > 0.0 and np.linalg.norm(err) > g.speed_error_max:
            return  # a push moved the robot, not a bias
        lim = g.speed_correction_max
        self.value = np.clip(self.value + g.speed_gain * err, -lim, lim)

"""When a weight shift ends: the lift-off rule of double support, robust to sensor noise.

The gait planner moves the divergent component of motion (DCM, xi = c + cdot / omega) towards
the point the next step needs during double support, then lifts the swing sole. Two rules
decide when, both on the DCM error e = |xi - xi_target| [m]:

- runaway: once ``min_double_support`` has passed, a DCM that is far off (e > runaway_dcm_error)
  and moving away is caught by stepping now;
- extension: at the planned end, the shift lasts longer (up to ``max_shift_extension``) only
  while it still reduces the error from tick to tick and e > liftoff_dcm_tolerance.

The measured DCM carries the estimator's noise (a few mm of base position, a few cm/s of
velocity, divided by omega ~ 4.4 /s): from one 4 ms tick to the next it jitters by more than
the shift moves it. Compared tick to tick, a noisy error "grows" half of the time, so a
tick-to-tick runaway rule fires at the first chance and every double support shrinks to its
minimum (task 1 then left its road). The runaway rule therefore uses the error low-passed
with time constant ``dcm_error_filter`` [s] (12 ms), and "moving away" means exceeding the smallest
filtered error of this shift by ``runaway_dcm_growth`` [m]; with a noise-free measurement it
fires a few ticks later than a tick-to-tick comparison. The extension stays tick to tick on
the raw error: noise only ends it sooner (at the planned duration), while a lagging filtered
error kept sideways steps in double support so long that they stopped moving the robot.

How long a shift is planned to last (:func:`shift_duration`, on when ``shift_time_factor`` > 0):
the DCM moves away from the ZMP as xi - z ~ exp(omega t), and with the ZMP held at most on the
old stance sole, a DCM that starts a0 ahead of that sole needs ln((a0 + n) / a0) / omega to
move a distance n. A wide step (after a push, while turning) leaves it near the old sole, and
a shift of the planned 0.10 s then ended half-way, which fed the next, wider step (task 1
under randomised physics: docs/benchmarks.md, fourteenth round).
"""

from __future__ import annotations

import math

import numpy as np


class LiftoffRule:
    """The filtered DCM error of the current weight shift and the two lift-off rules.

    Args:
        gait: the gait parameters (``walking_params.GaitParams``).
    """

    def __init__(self, gait):
        self.gait = gait
        self.reset()

    def reset(self) -> None:
        """A new weight shift begins."""
        self.raw = math.inf  # [m] DCM error of this tick
        self.previous = math.inf  # [m] ... of the previous tick
        self.filtered = math.inf  # [m] low-passed DCM error
        self.smallest = math.inf  # [m] smallest filtered error of this shift

    def update(self, err: float, dt: float) -> None:
        """Take this tick's DCM error ``err`` [m], ``dt`` [s] after the previous tick."""
        tau = self.gait.dcm_error_filter
        self.previous = self.raw
        self.raw = err
        if math.isinf(self.filtered) or tau <= 0.0:
            self.filtered = err
        else:
            self.filtered += min(dt / tau, 1.0) * (err - self.filtered)
        self.smallest = min(self.smallest, self.filtered)

    def running_away(self) -> bool:
        """Far off and moving away from the target: step now."""
        g = self.gait
        return (self.filtered > g.runaway_dcm_error
                and self.filtered > self.smallest + g.runaway_dcm_growth)

    def done(self, elapsed: float, duration: float) -> bool:
        """At or after the planned end (``elapsed`` of ``duration`` [s]): lift off unless the
        shift still reduces a large error and may still be extended."""
        g = self.gait
        return (self.raw < g.liftoff_dcm_tolerance
                or self.raw >= self.previous - 1e-4
                or elapsed >= duration + g.max_shift_extension - 1e-9)


def shift_duration(xi0, xi_end, p_old, omega: float, gait) -> float:
    """Double support's duration [s]: ``shift_time_factor`` times the least time the DCM needs
    to go from ``xi0`` to ``xi_end`` (xy, W) [m] with the ZMP held on the old stance sole's ZMP
    point ``p_old`` (xy, W) [m], within [double_support, double_support + max_shift_extension].

    A DCM less than 1 cm ahead of the old sole along the shift (at or behind it: after a push)
    keeps the planned ``double_support``: the least time is unbounded there, and the lift-off
    rule's runaway check already handles a DCM that moves the wrong way.
    """
    g = gait
    d = np.asarray(xi_end, dtype=float) - np.asarray(xi0, dtype=float)
    n = math.hypot(float(d[0]), float(d[1]))  # [m] the shift's length
    if g.shift_time_factor <= 0.0 or n < 1e-6:
        return g.double_support
    a0 = float(np.dot(np.asarray(xi0, dtype=float) - np.asarray(p_old, dtype=float), d / n))
    if a0 < 0.01:
        return g.double_support
    need = g.shift_time_factor * math.log((a0 + n) / a0) / omega
    return min(max(need, g.double_support), g.double_support + g.max_shift_extension)

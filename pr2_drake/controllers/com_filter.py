"""The CoM state the gait planner sees: the measured one, filtered against sensor noise.

The planner's decisions (when to lift off, where to step) follow the divergent component of
motion xi = c + cdot / omega, and omega ~ 4.4 /s turns a few cm/s of velocity noise into
centimetres of DCM. With the randomised sensor noise (pr2_drake/randomize.py: base position
2 mm, base velocity 0.02 m/s, joint velocities 0.05 rad/s, white at every physics step) the
measured DCM jitters by about 1 cm from one 4 ms tick to the next: double supports end early
and the next step catches the error by stepping wide and short (docs/benchmarks.md, seventh
round). A plain low-pass would delay the DCM by its time constant; this filter predicts
instead, with the CoM acceleration the whole-body QP commanded on the previous tick
(a_WC = J_C vdot + Jdot_C v: the model's contact and hand forces over the mass, plus gravity),
and corrects the prediction towards the measurement:

    predict:  c <- c + cdot dt + a dt^2 / 2,   cdot <- cdot + a dt
    correct:  c <- c + k_p (c_meas - c),       cdot <- cdot + k_v (cdot_meas - cdot)

with k = min(dt / tau, 1) per tick. Only what the model does not know (a push, a latency's
lag, a stone under the sole) lags, by tau - dt once settled: a 40 N push on the 34.5 kg robot
(1.16 m/s^2) by 1.9 cm/s at tau = 20 ms, 4 mm of DCM. White noise shrinks by sqrt(k / (2 - k)) (0.33 at
k = 0.2: 20 ms at 250 Hz). Both time constants 0 (the default, params/controllers/walking.yaml
``com_filter``) pass the measurement through unchanged.
"""

from __future__ import annotations

import numpy as np


class ComStateFilter:
    """p_WC [m] and v_WC [m/s] of the centre of mass (W), predicted and corrected each tick.

    Args:
        params: ``walking_params.ComFilterParams``: ``position_time`` and ``velocity_time`` [s]
            (0 = that one unfiltered), ``max_gap`` [s] (a longer gap between ticks restarts
            from the measurement).
    """

    def __init__(self, params):
        self.params = params
        self._on = params.position_time > 0.0 or params.velocity_time > 0.0
        self.reset()

    @property
    def enabled(self) -> bool:
        """Whether the filter does anything (a time constant > 0)."""
        return self._on

    def reset(self) -> None:
        """Forget the estimate: the next tick starts from its measurement."""
        self.t: float | None = None
        # (Three Python floats each: cheaper per tick than numpy calls on 3-vectors, and the
        # same IEEE operations in the same order.)
        self.c = [0.0, 0.0, 0.0]  # [m] p_WC
        self.cdot = [0.0, 0.0, 0.0]  # [m/s] v_WC
        self.accel = [0.0, 0.0, 0.0]  # [m/s^2] the prediction's CoM acceleration (W)

    def set_acceleration(self, a_WC: np.ndarray | None) -> None:
        """The CoM acceleration [m/s^2] (W) the controller commanded for the coming interval;
        None (a failed QP) predicts none."""
        self.accel = [0.0, 0.0, 0.0] if a_WC is None else [float(x) for x in a_WC]

    def update(self, t: float, c_meas: np.ndarray, cdot_meas: np.ndarray):
        """This tick's measured CoM position and velocity at time t [s] in, the estimate out
        (new arrays; the measured arrays themselves while the filter is off)."""
        if not self._on:
            return c_meas, cdot_meas
        p = self.params
        dt = None if self.t is None else t - self.t
        self.t = t
        mc, mv = c_meas.tolist(), cdot_meas.tolist()
        if dt is None or dt <= 0.0 or dt > p.max_gap:
            self.c, self.cdot = mc, mv
            return np.array(mc), np.array(mv)
        h = 0.5 * dt * dt
        k_p = 1.0 if p.position_time <= 0.0 else min(dt / p.position_time, 1.0)
        k_v = 1.0 if p.velocity_time <= 0.0 else min(dt / p.velocity_time, 1.0)
        c, v = [], []
        for ci, vi, ai, mci, mvi in zip(self.c, self.cdot, self.accel, mc, mv):
            ci = ci + (vi * dt + ai * h)  # predict
            vi = vi + ai * dt
            c.append(ci + k_p * (mci - ci))  # correct
            v.append(vi + k_v * (mvi - vi))
        self.c, self.cdot = c, v
        return np.array(c), np.array(v)

"""Swing-sole trajectory from lift-off to the next footstep.

The swing follows a phase tau in [0, 1] (0 at lift-off, 1 at the planned landing). Horizontal
position and yaw follow a quintic blend of tau (zero velocity and acceleration at both ends);
the height adds a bump ``64 h tau^3 (1 - tau)^3`` (apex h at mid swing, smooth ends). The
target may move during the swing (foot placement feedback) and the landing may be brought
forward (step timing): the phase rate then changes so that tau reaches 1 at the new landing
time. After the planned landing the sole reference keeps descending (``descent_speed``) until
contact is detected.
"""

from __future__ import annotations

import numpy as np

from pr2_drake.controllers.frames import wrap
from pr2_drake.controllers.planning.terrain import LEVEL_TOLERANCE

#: Latest swing phase at which a step-down's lowering may start (it keeps 5 % of the phase).
LATEST_LOWERING = 0.95


def _quintic(tau: float):
    """s, ds/dtau, d2s/dtau2 of 10 tau^3 - 15 tau^4 + 6 tau^5 on [0, 1]."""
    t = min(max(tau, 0.0), 1.0)
    s = t**3 * (10 - 15 * t + 6 * t * t)
    ds = 30 * t * t * (1 - t) ** 2
    dds = 60 * t * (1 - t) * (1 - 2 * t)
    return s, ds, dds


class SwingTrajectory:
    """Desired sole position (W) and yaw during one swing.

    Args:
        t0: lift-off time [s].
        duration: planned single-support time [s].
        start, target: sole poses (x, y, z, yaw) at lift-off and landing.
        height: apex above the higher of the two ends [m].
        land_fraction: part of the single support after which the sole is at the target.
    """

    def __init__(self, t0: float, duration: float, start: np.ndarray, target: np.ndarray,
                 height: float, land_fraction: float, lift_fraction: float = 0.0,
                 descent_speed: float = 0.5, max_descent: float = 0.05):
        self.t0 = t0
        self.duration = duration
        self.t_land = land_fraction * duration  # landing time after t0 [s]
        self.start = np.array(start, dtype=float)
        self.target = np.array(target, dtype=float)
        self.height = height
        # Horizontal motion waits for this fraction of the swing phase after lift-off (lift
        # vertically: a toe next to a stone's edge does not catch on it).
        self.lift_fraction = float(np.clip(lift_fraction, 0.0, 0.5))
        self._tau = 0.0
        self._rate = 1.0 / self.t_land
        self._t = t0
        # Sole pitch [rad] about its y axis at lift-off and landing (terrain-aware landing).
        self.pitch_start = 0.0
        self.pitch_target = 0.0
        # After the planned landing the reference keeps descending at descent_speed [m/s] to
        # max_descent [m] below the target, until contact (a late landing is a short one).
        self.descent_speed = descent_speed
        self.max_descent = max_descent
        # Over an edge: the height [m, W] to clear (None: the plain curve above) and the
        # fractions of the swing phase for the lift and the lowering (see _clearance_z).
        self.clear_z: float | None = None
        self.clear_fractions = (0.3, 0.3)
        # A step down over an edge: the phase at which the horizontal motion starts and the
        # phase from which the sole lowers (None: the clearance fractions decide both).
        self.step_down: tuple[float, float] | None = None

    def phase(self, t: float) -> float:
        """Fraction of the planned single support elapsed (can exceed 1 when landing late)."""
        return (t - self.t0) / self.duration

    @property
    def progress(self) -> float:
        """Swing phase tau in [0, 1] at the last evaluation (1 = planned landing)."""
        return self._tau

    @property
    def landing_time(self) -> float:
        """Absolute planned landing time [s]."""
        return self.t0 + self.t_land

    def pitch(self) -> tuple[float, float]:
        """Desired sole pitch [rad] and pitch rate [rad/s] at the last evaluation."""
        s, ds, _ = _quintic(self._tau)
        d = self.pitch_target - self.pitch_start
        return self.pitch_start + s * d, ds * self._rate * d

    def retime(self, t: float, landing_time: float) -> None:
        """Bring the landing forward to ``landing_time`` (absolute) from time t."""
        self.advance(t)
        remaining = landing_time - t
        if remaining <= 1e-3 or self._tau >= 1.0:
            return
        self._rate = (1.0 - self._tau) / remaining
        self.t_land = landing_time - self.t0

    def advance(self, t: float) -> None:
        """Move the swing phase on to time t (``progress``); :meth:`evaluate` does it too."""
        dt = t - self._t
        if dt > 0:
            self._tau = min(self._tau + self._rate * dt, 1.0)
            self._t = t

    def evaluate(self, t: float):
        """p, v, a (3 each, W) and yaw, yaw rate of the desired sole at time t."""
        self.advance(t)
        tau, r = self._tau, self._rate
        if self.clear_z is not None:
            return self._evaluate_clearance(t, tau, r)
        f = self.lift_fraction
        k = 1.0 / (1.0 - f)
        s, ds, dds = _quintic((tau - f) * k)  # horizontal (and yaw) blend
        ds, dds = ds * k, dds * k * k
        sz, dsz, ddsz = _quintic(tau)  # height blend between the two ends
        # (Scalar math per component, in the order the vector expressions had.)
        x0, y0, z0, yaw0 = self.start.tolist()
        x1, y1, z1, yaw1 = self.target.tolist()
        dx, dy, dz = x1 - x0, y1 - y0, z1 - z0
        vr, ar = ds * r, dds * r * r
        pz = z0 + sz * dz
        vz = dsz * r * dz
        az = ddsz * r * r * dz
        dyaw = wrap(yaw1 - yaw0)
        yaw = yaw0 + s * dyaw
        yawd = ds * r * dyaw
        # Height bump on top of the straight blend.
        top = max(z0, z1) - z0 - sz * dz
        bump = self.height + max(top, 0.0)
        pz += bump * 64 * tau**3 * (1 - tau) ** 3
        vz += bump * 64 * 3 * tau**2 * (1 - tau) ** 2 * (1 - 2 * tau) * r
        az += bump * 64 * 6 * tau * (1 - tau) * (1 - 5 * tau + 5 * tau * tau) * r * r
        late = (t - self.t0) - self.t_land
        if tau >= 1.0 and late > 0:
            pz = z1 - min(self.descent_speed * late, self.max_descent)
            vz = -self.descent_speed if self.descent_speed * late < self.max_descent else 0.0
            az = 0.0
        return (np.array([x0 + s * dx, y0 + s * dy, pz]), np.array([vr * dx, vr * dy, vz]),
                np.array([ar * dx, ar * dy, az]), yaw, yawd)

    def plan_over_terrain(self, terrain, gait) -> None:
        """The height to clear on the way (``terrain.swing_clearance``; None: the plain
        curve) and the lift and lowering fractions (``gait``: GaitParams). A step down over an
        edge starts its horizontal motion at ``gait.swing_down_move_start`` and lowers only
        once its planned heel is ``gait.swing_down_heel_margin`` past the higher ground
        (``terrain.swing_lowering_start``), at the latest from :data:`LATEST_LOWERING`."""
        self.clear_z = terrain.swing_clearance(self.start, self.target)
        self.clear_fractions = (gait.swing_clear_lift, gait.swing_clear_lower)
        self.step_down = None
        if self.clear_z is None or self.target[2] >= self.start[2] - LEVEL_TOLERANCE:
            return
        h0, h1 = gait.swing_down_move_start, 1.0 - 0.6 * gait.swing_clear_lower
        s_low = terrain.swing_lowering_start(self.start, self.target, gait.swing_down_heel_margin)
        lo, hi = 0.0, (1.0 if s_low > 0.0 else 0.0)  # the blend's argument at s_low
        for _ in range(30 if s_low > 0.0 else 0):  # (bisection)
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if _quintic(mid)[0] < s_low else (lo, mid)
        lower_from = max(1.0 - gait.swing_clear_lower, h0 + hi * (h1 - h0))
        self.step_down = (h0, min(lower_from, LATEST_LOWERING))

    def _evaluate_clearance(self, t: float, tau: float, r: float):
        """Lift, move, lower: the sole rises from its start height to ``clear_z`` over the
        first ``clear_fractions[0]`` of the phase, holds it, and lowers to the target height
        over the last ``clear_fractions[1]``; the horizontal motion (and yaw) blends between
        60 % of the lift and 40 % into the lowering, so toe and heel pass the edge high. A
        step down (``step_down``) moves from its own start and lowers from its own phase."""
        lift, lower = self.clear_fractions
        z0, z1 = float(self.start[2]), float(self.target[2])
        zc = max(float(self.clear_z), z0, z1)
        h0, h1 = 0.6 * lift, 1.0 - 0.6 * lower
        down = self.step_down
        if down is not None:
            h0 = down[0]
        k = 1.0 / (h1 - h0)
        s, ds, dds = _quintic((tau - h0) * k)
        ds, dds = ds * k, dds * k * k
        d = self.target[:3] - self.start[:3]
        p = self.start[:3] + s * d
        v = ds * r * d
        a = dds * r * r * d
        if tau < (1.0 - lower if down is None else down[1]):
            sz, dsz, ddsz = _quintic(tau / lift)
            p[2], v[2], a[2] = (z0 + sz * (zc - z0), dsz / lift * r * (zc - z0),
                                ddsz / lift ** 2 * r * r * (zc - z0))
        else:
            if down is None:
                sz, dsz, ddsz = _quintic((tau - 1.0 + lower) / lower)
            else:
                lower = 1.0 - down[1]
                sz, dsz, ddsz = _quintic((tau - down[1]) / lower)
            p[2], v[2], a[2] = (zc + sz * (z1 - zc), dsz / lower * r * (z1 - zc),
                                ddsz / lower ** 2 * r * r * (z1 - zc))
        dyaw = wrap(self.target[3] - self.start[3])
        yaw = self.start[3] + s * dyaw
        yawd = ds * r * dyaw
        late = (t - self.t0) - self.t_land
        if tau >= 1.0 and late > 0:
            p[2] = self.target[2] - min(self.descent_speed * late, self.max_descent)
            v[2] = -self.descent_speed if self.descent_speed * late < self.max_descent else 0.0
            a[2] = 0.0
        return p, v, a, yaw, yawd

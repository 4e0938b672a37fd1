"""Where and why a walk on stairs failed: snapshots of the walk and the first sign of trouble.

:class:`pr2_drake.bench.rigs.StairsSim` takes a :func:`snapshot` every check of its walk and,
when the robot falls, :func:`diagnose` reads the last :data:`SNAPSHOTS` of them: a knee at its
limit, a swing toe caught on a riser's nosing, a heel or toe off an edge, a sole off the side,
the DCM outside the support.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

TREAD = 0.40  # [m] the bench staircase's tread; a point within half of it is "at" a riser
#: [m] a DCM this far outside the soles' box (heel/toe, xy) is a sign of a fall coming (a
#: walk at 0.25 m/s keeps it within about 0.15 m of the stance sole).
DCM_MARGIN = 0.25
#: Snapshots (one per ``check_every``) the fall diagnosis looks back over.
SNAPSHOTS = 10


@dataclass
class Snapshot:
    """One look at the walk: time [s], CoM p_WCcm (3), DCM xy (W) [m], heel and toe of each
    sole (2 x 3 each, W), knee angles [rad], gait phase, stance side, swing target."""

    t: float
    com: np.ndarray
    dcm: np.ndarray
    soles: list
    knees: list
    phase: int
    stance: int
    target: np.ndarray | None


@dataclass
class Fall:
    """Where a walk failed: sim time [s], section ("up", "top floor", "down", "start",
    "end"), riser number in that flight (0 off the risers) of ``risers``, and the cause."""

    t: float
    section: str
    riser: int
    risers: int
    cause: str

    def __str__(self) -> str:
        where = (f"{self.section} riser {self.riser}/{self.risers}" if self.riser
                 else self.section)
        return f"t = {self.t:.1f} s, {where}; first sign: {self.cause}"


def snapshot(sim) -> Snapshot:
    """The state the fall diagnosis reads, of a :class:`pr2_drake.bench.rigs.StairsSim`."""
    gp = sim.walker.core.planner
    com = sim.plant.CalcCenterOfMassPositionInWorld(sim.plant_context)
    vcom = sim.plant.CalcCenterOfMassTranslationalVelocityInWorld(sim.plant_context)
    omega = math.sqrt(sim.walker.core.model.gravity / sim.params.gait.com_height)
    knees = [sim.plant.GetJointByName(n, sim.testbed.robot).get_angle(sim.plant_context)
             for n in ("l_knee", "r_knee")]
    swing = gp.swing
    return Snapshot(sim.time, com.copy(), com[:2] + vcom[:2] / omega,
                    [sim.sole_points(0), sim.sole_points(1)], knees, int(gp.phase),
                    gp.stance, None if swing is None else swing.target.copy())


def where(terrain, x: float) -> tuple[str, int, int]:
    """(section, riser number, risers in that flight) of a point at x [m] on ``terrain``
    (a PatchTerrain): "up" / "down" with the nearest riser of that flight (1 = first
    crossed), or "top floor" / "start" / "end" (riser 0) when farther than half a tread from
    every riser."""
    risers = terrain.risers()
    up = [r for r in risers if r[1] > 0]
    down = [r for r in risers if r[1] < 0]
    near = min(risers, key=lambda r: abs(r[0] - x), default=None)
    if near is None or abs(near[0] - x) > 0.5 * TREAD:
        if up and x < up[0][0]:
            return "start", 0, len(up)
        if down and x > down[-1][0]:
            return "end", 0, len(down)
        return "top floor", 0, len(up)
    flight = up if near[1] > 0 else down
    return ("up" if near[1] > 0 else "down"), flight.index(near) + 1, len(flight)


def _sole_signs(s: Snapshot, terrain, knee_lo: float, knee_hi: float) -> list[str]:
    """The signs of trouble of one snapshot's soles and knees."""
    t = terrain
    half_w = [0.5 * (p.y_max - p.y_min) for p in t.patches if math.isfinite(p.y_max)]
    reasons = []
    for side, pts in enumerate(s.soles):
        name = ("left", "right")[side]
        if half_w and max(abs(pts[:, 1])) > min(half_w) and max(
                t.height(x, y) for x, y, _ in pts) > t.base + 0.01:
            reasons.append(f"{name} sole off the side of the stairs "
                           f"(y = {pts[:, 1].mean():+.2f} m)")
        stance = s.phase != 2 or s.stance == side
        under = [t.height(x, y) for x, y, _ in pts]
        if stance and min(under) < max(under) - 0.01 and pts[:, 2].max() > min(under) + 0.01:
            end = "heel" if under[0] < under[1] else "toe"
            reasons.append(f"{name} {end} off the edge")
        if not stance:  # swing sole below the ground ahead of it: caught on a riser
            x_front = pts[1, 0] + 0.01
            if pts[:, 2].min() < t.height(x_front, pts[1, 1]) - 0.005:
                reasons.append(f"{name} swing toe caught on a riser/nosing")
        if s.knees[side] > knee_hi or s.knees[side] < knee_lo:
            role = "stance" if stance else "swing"
            reasons.append(f"{name} ({role}) knee at its limit "
                           f"({math.degrees(s.knees[side]):.0f} deg)")
    return reasons


def diagnose(sim) -> Fall:
    """Where the fall of ``sim`` (a StairsSim) happened and the first sign of trouble in its
    last :data:`SNAPSHOTS` snapshots (see :class:`Fall`)."""
    snaps = sim.snapshots
    last = snaps[-1] if snaps else snapshot(sim)
    section, riser, n = where(sim.terrain, float(last.com[0]))
    cause = "unclear"
    knee_lo = math.radians(-120.0) + sim.params.qp.joint_limit_margin + 0.05
    knee_hi = sim.params.qp.knee_max - 0.05
    for s in snaps[:-2] or snaps:  # the last ones show the fall itself, not its cause
        reasons = _sole_signs(s, sim.terrain, knee_lo, knee_hi)
        if not reasons:
            soles = np.vstack([p for side, p in enumerate(s.soles)
                               if s.phase != 2 or s.stance == side])
            lo, hi = soles[:, :2].min(axis=0), soles[:, :2].max(axis=0)
            if np.any(s.dcm < lo - DCM_MARGIN) or np.any(s.dcm > hi + DCM_MARGIN):
                reasons.append("DCM far outside the support (x, y = "
                               f"{s.dcm[0]:.2f}, {s.dcm[1]:.2f} m)")
        if reasons:
            cause = f"t = {s.t:.2f} s: " + "; ".join(reasons)
            break
    return Fall(sim.time, section, riser, n, cause)

"""Jumping benchmark: vertical and forward jumps of the JumpController on flat ground.

    pr2-drake bench jumping [--repeats 10] [--apex 0.05,0.10,0.15,...] [--forward 0.1,0.2,0.3]
                            [--forward-apex 0.08] [--quick]

Forward jumps fly at ``--forward-apex``, or higher where the distance needs a take-off speed
above the controller's ``max_speed`` (:func:`forward_apex`: 0.3 m flies at 0.12 m).
    python -m pr2_drake.bench.jumping [...]

Runs the testbed (flat ground, discrete SAP at the default physics step) in closed loop with the JumpController and the
ArmPosture block: stand 1 s, jump (take-off at 2.0 s plus a small per-repeat offset), then 3 s
after landing. Per case it prints: requested and achieved CoM apex (rise above the take-off CoM
height), highest lowest-sole point (both soles off the ground), landing error (horizontal
distance of the landing sole midpoint from the ballistic target), falls within 3 s of landing,
peak |torque| / limit per joint group over the jump, the MPC solve time and the closed-loop
real-time factor during the jump. Vertical apex heights go on past the requested list (in
0.05 m steps) until a case fails (a fall, or an achieved apex below 80 % of the request).

:class:`pr2_drake.bench.rigs.JumpSim` is the closed loop (settable velocity and jump commands).
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from dataclasses import dataclass, field

import numpy as np

from pr2_drake.bench.rigs import JumpSim
from pr2_drake.controllers.jump_params import JumpParams


@dataclass
class JumpResult:
    """One jump, measured from the plant (not from the controller's estimates)."""

    apex_requested: float
    distance_requested: float
    com_apex: float = math.nan  # [m] CoM rise above its take-off height
    com_rise: float = math.nan  # [m] CoM maximum above its standing height before the jump
    sole_apex: float = math.nan  # [m] max over time of the lower sole's lowest point
    airborne: float = 0.0  # [s] longest time with both soles above 5 mm
    distance: float = math.nan  # [m] landing sole midpoint travel along x
    landing_error: float = math.nan  # [m] horizontal, from the planned landing point
    fell: bool = False
    peak_ratio: dict = field(default_factory=dict)  # joint group -> max |tau| / limit
    mpc_ms: list = field(default_factory=list)
    rtf: float = math.nan
    landed: bool = False


def run_jump(apex: float, distance: float = 0.0, t_takeoff: float = 2.0,
             after: float = 3.0, sim: JumpSim | None = None) -> JumpResult:
    """One jump from standing at the origin; forward ``distance`` [m] along x."""
    sim = sim or JumpSim()
    res = JumpResult(apex, distance)
    g = sim.walker.core.model.gravity
    jp = sim.walker.jump.params
    vz = math.sqrt(2 * g * apex)
    # Flight time: take-off CoM height to landing CoM height (ballistic).
    dh = jp.takeoff_height - jp.landing_height
    t_flight = (vz + math.sqrt(vz * vz + 2 * g * dh)) / g
    vx = distance / t_flight
    sim.advance(1.0)
    c_stand, _ = sim.com()
    feet0 = sim.sole_positions()
    mid0 = 0.5 * (feet0[0] + feet0[1])
    sim.set_jump((t_takeoff, vx, 0.0, apex))
    effort = sim.walker.core.model.effort[8:]
    peak = np.zeros(10)
    com_max, sole_max = -np.inf, -np.inf
    c_to = None
    air_t0, air = None, 0.0
    wall = time.perf_counter()
    t_start = sim.time
    t_end_jump = None
    dt = 0.005
    while sim.time < t_takeoff + 4.0 + after:
        sim.advance(sim.time + dt)
        ph = int(sim.jump_status()[0])
        c, _ = sim.com()
        h = sim.sole_heights()
        peak = np.maximum(peak, np.abs(sim.leg_torques()))
        if ph == 3 and c_to is None:
            c_to = c.copy()
        if c_to is not None:
            com_max = max(com_max, c[2])
        sole_max = max(sole_max, float(h.min()))
        if h.min() > 0.005:
            air_t0 = sim.time if air_t0 is None else air_t0
            air = max(air, sim.time - air_t0)
        else:
            air_t0 = None
        if sim.fallen():
            res.fell = True
            break
        if t_end_jump is None and ph == 0 and sim.walker.jump.jumps > 0:
            t_end_jump = sim.time
            res.rtf = (t_end_jump - t_start) / (time.perf_counter() - wall)
            res.landed = True
        if t_end_jump is not None and sim.time > t_end_jump + after:
            break
    hist = sim.walker.jump.history
    log = hist[-1] if hist else sim.walker.jump.planner.log
    if "com_takeoff" in log:
        c_to = log["com_takeoff"]
    if c_to is not None:
        res.com_apex = float(com_max - c_to[2])
        res.com_rise = float(com_max - c_stand[2])
    res.sole_apex = float(sole_max)
    res.airborne = air
    feet = sim.sole_positions()
    mid = 0.5 * (feet[0] + feet[1])
    if "t_touchdown" in log:
        res.distance = float(mid[0] - mid0[0])
        res.landing_error = float(np.hypot(mid[0] - (mid0[0] + distance), mid[1] - mid0[1]))
    groups = {"hip_z": [0, 5], "hip_x": [1, 6], "hip_y": [2, 7], "knee": [3, 8], "ankle": [4, 9]}
    res.peak_ratio = {k: float(max(peak[i] / effort[i] for i in idx)) for k, idx in groups.items()}
    res.mpc_ms = [1e3 * x for x in sim.walker.jump.planner.mpc_times]
    if not res.landed and not res.fell:
        res.fell = sim.fallen()
    return res


def forward_apex(distance: float, apex: float, params: JumpParams | None = None,
                 gravity: float = 9.81) -> float:
    """The lowest apex [m] from ``apex`` up, in 0.02 m steps, whose ballistic flight covers
    ``distance`` [m] within the controller's ``max_speed`` (a longer jump flies higher)."""
    jp = params or JumpParams.load()
    dh = jp.takeoff_height - jp.landing_height
    while apex < jp.max_apex:
        vz = math.sqrt(2 * gravity * apex)
        t_flight = (vz + math.sqrt(vz * vz + 2 * gravity * dh)) / gravity
        if distance / t_flight <= jp.max_speed:
            break
        apex = round(apex + 0.02, 3)
    return apex


def _fmt(x: float, nd: int = 3) -> str:
    return "  nan" if not np.isfinite(x) else f"{x:.{nd}f}"


def _case(apex: float, distance: float, repeats: int) -> tuple[str, list[JumpResult]]:
    results = []
    for k in range(repeats):
        results.append(run_jump(apex, distance, t_takeoff=2.0 + 0.01 * k))
    return f"apex {apex:.2f} fwd {distance:.2f}", results


def _row(name: str, rs: list[JumpResult]) -> str:
    med = lambda xs: statistics.median(xs) if xs else math.nan  # noqa: E731
    falls = sum(r.fell for r in rs)
    peaks = {k: max(r.peak_ratio.get(k, 0.0) for r in rs) for k in ("hip_y", "knee", "ankle")}
    mpc = [x for r in rs for x in r.mpc_ms]
    return (f"{name:<22}{len(rs):>3} {_fmt(med([r.com_apex for r in rs]))} "
            f"{_fmt(med([r.com_rise for r in rs]))} {_fmt(med([r.sole_apex for r in rs]))} "
            f"{_fmt(med([r.airborne for r in rs]), 2)} {_fmt(med([r.distance for r in rs]))} "
            f"{_fmt(med([r.landing_error for r in rs]))} {falls:>3}  "
            f"{peaks['hip_y']:.2f}/{peaks['knee']:.2f}/{peaks['ankle']:.2f}  "
            f"{_fmt(med(mpc), 2)}/{_fmt(max(mpc) if mpc else math.nan, 2)} "
            f"{_fmt(med([r.rtf for r in rs]), 2)}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="pr2-drake bench jumping")
    ap.add_argument("--repeats", type=int, default=10)
    ap.add_argument("--apex", default="0.05,0.10,0.15")
    ap.add_argument("--forward", default="0.1,0.2,0.3")
    ap.add_argument("--forward-apex", type=float, default=0.08)
    ap.add_argument("--max-apex", type=float, default=0.30)
    ap.add_argument("--quick", action="store_true", help="2 repeats")
    a = ap.parse_args(argv)
    if a.repeats < 1:
        ap.error("--repeats must be >= 1")
    repeats = 2 if a.quick else a.repeats
    from pr2_drake.testbed import DEFAULT_TIME_STEP

    print(f"jumps on flat ground, physics {DEFAULT_TIME_STEP * 1e3:g} ms, whole-body QP 250 Hz; "
          f"{repeats} repeats each "
          "(take-off 2.00 s + 0.01 s x repeat); medians; falls = within 3 s of landing")
    print(f"{'case':<22}{'n':>3} {'apxC':>5} {'riseC':>5} {'sole':>5} {'air':>4} "
          f"{'dist':>5} {'land':>5} {'fall':>3}  {'peak/limit hipy/knee/ankle':<16} "
          f"{'mpc ms med/max':<14} {'rtf':>4}")
    apexes = [float(x) for x in a.apex.split(",") if x]
    best = 0.0
    k = 0
    while k < len(apexes):
        apex = apexes[k]
        name, rs = _case(apex, 0.0, repeats)
        print(_row(name, rs), flush=True)
        ok = all(not r.fell and r.com_apex >= 0.8 * apex for r in rs)
        if ok:
            best = max(best, apex)
        if k == len(apexes) - 1 and ok and apex + 0.05 <= a.max_apex + 1e-9:
            apexes.append(round(apex + 0.05, 3))
        if not ok and k >= len(apexes) - 1:
            break
        k += 1
    print(f"highest reliable vertical jump (no fall, apex >= 80 % of the request, all repeats): "
          f"requested apex {best:.2f} m")
    for d in [float(x) for x in a.forward.split(",") if x]:
        apex = forward_apex(d, a.forward_apex)
        try:
            name, rs = _case(apex, d, repeats)
        except ValueError as e:  # e.g. a horizontal speed beyond the controller's max_speed
            print(f"apex {apex:.2f} fwd {d:.2f}    rejected: {e}", flush=True)
            continue
        print(_row(name, rs), flush=True)
    print("columns: apxC = CoM rise above take-off [m]; riseC = CoM max above standing [m]; "
          "sole = max of the lower sole's lowest point [m]; air = both soles > 5 mm [s]; "
          "dist = landing travel [m]; land = landing error [m]; rtf = real-time factor, "
          "request to recovered")
    return 0


if __name__ == "__main__":
    sys.exit(main())

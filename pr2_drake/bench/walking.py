"""Walking controller benchmark: tracking, pushes, standing, and the real-time factor.

    pr2-drake bench walking [--quick] [--repeats 3] [--no-profile] [--push-force 40]
                            [--push-time 0.2] [--push-phases 4]
    python -m pr2_drake.bench.walking [--quick]

Runs the testbed (flat ground, discrete SAP at the default physics step) in closed loop with the WalkingController
and the ArmPosture block, and prints one table row per scenario: commanded and achieved mean
velocity, whether the robot fell, and the wall-clock real-time factor. Then the real-time factor
of 0.3 m/s walking (median of ``--repeats`` runs) and the split of wall time between the plant
(MultibodyPlant step) and the controller (cProfile).

:class:`pr2_drake.bench.rigs.WalkingSim` is the closed loop (a settable command, torso pushes).
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import statistics
import sys
import time
from dataclasses import dataclass

import numpy as np

from pr2_drake.bench.rigs import WalkingSim
from pr2_drake.controllers.walking import WalkingController
from pr2_drake.controllers.walking_params import WalkingParams


@dataclass
class Row:
    name: str
    command: tuple[float, float, float]
    duration: float
    achieved: tuple[float, float, float]  # mean vx, vy (heading frame) [m/s], yaw rate [rad/s]
    fell: bool
    rtf: float
    note: str = ""


def _track(sim: WalkingSim, duration: float, step: float = 0.1):
    """Run for ``duration`` s; return (ok, mean velocity in the heading frame of the start
    (vx, vy) [m/s], mean yaw rate [rad/s], from the yaw unwrapped every ``step`` s)."""
    p0, _, _, yaw0 = sim.base_pose()
    t0 = sim.time
    yaw_prev, turned, ok = yaw0, 0.0, True
    while ok and sim.time < t0 + duration - 1e-9:
        ok = sim.run(min(step, t0 + duration - sim.time), check_every=step)
        _, _, _, yaw = sim.base_pose()
        turned += (yaw - yaw_prev + np.pi) % (2 * np.pi) - np.pi
        yaw_prev = yaw
    p1, *_ = sim.base_pose()
    T = max(sim.time - t0, 1e-6)
    d = p1[:2] - p0[:2]
    # Mean direction of travel in the heading frame: rotate by the mean yaw.
    yaw_mid = yaw0 + 0.5 * turned
    c, s = np.cos(yaw_mid), np.sin(yaw_mid)
    return ok, (c * d[0] + s * d[1]) / T, (-s * d[0] + c * d[1]) / T, turned / T


def scenario_walk(name, cmd, duration, settle=1.0, measure_from=2.0) -> Row:
    """Walk with a constant command; velocity averaged after ``measure_from`` s of walking."""
    sim = WalkingSim()
    sim.run(settle)
    sim.set_command(*cmd)
    wall = time.perf_counter()
    t0 = sim.time
    ok = sim.run(min(measure_from, duration))
    vx = vy = wz = np.nan
    if ok:
        ok, vx, vy, wz = _track(sim, duration - (sim.time - t0))
    rtf = (sim.time - t0) / (time.perf_counter() - wall)
    achieved = (vx, vy, wz)
    note = ""
    if ok:
        # Stop and check it comes to rest standing.
        sim.set_command(0.0, 0.0, 0.0)
        ok = sim.run(3.0)
        phase = int(sim.status()[3])
        note = ("fell while stopping" if not ok else
                "stopped, standing" if phase == 0 else f"still stepping (phase {phase})")
    return Row(name, cmd, duration, achieved, not ok, rtf, note)


def scenario_stand(duration) -> Row:
    sim = WalkingSim()
    p0, *_ = sim.base_pose()
    wall = time.perf_counter()
    ok = sim.run(duration, check_every=1.0)
    rtf = duration / (time.perf_counter() - wall)
    p1, *_ = sim.base_pose()
    drift = float(np.linalg.norm(p1 - p0))
    return Row("stand", (0.0, 0.0, 0.0), duration, (0.0, 0.0, 0.0), not ok, rtf,
               f"base drift {drift * 100:.1f} cm")


# Push directions: where the push comes from, as the force direction in the heading frame.
PUSH_FROM = {"front": (-1.0, 0.0), "back": (1.0, 0.0), "right": (0.0, 1.0), "left": (0.0, -1.0)}


def push_once(direction: str, walking: bool, force: float = 40.0, push_time: float = 0.2,
              walk_before: float = 4.0) -> tuple[bool, float]:
    """One torso push of ``force`` N for ``push_time`` s from ``direction`` (a PUSH_FROM key),
    standing or after ``walk_before`` s of walking at 0.3 m/s; then 3 s to recover.
    Returns (fell, real-time factor of the push and recovery)."""
    sim = WalkingSim()
    sim.run(1.0)
    sim.set_command(*((0.3, 0.0, 0.0) if walking else (0.0, 0.0, 0.0)))
    ok = sim.run(walk_before if walking else 2.0)
    _, _, _, yaw = sim.base_pose()
    local = PUSH_FROM[direction]
    c, s = np.cos(yaw), np.sin(yaw)
    f_W = force * np.array([c * local[0] - s * local[1], s * local[0] + c * local[1], 0.0])
    wall = time.perf_counter()
    t0 = sim.time
    if ok:
        sim.push(f_W)
        ok = sim.run(push_time, check_every=push_time)
        sim.push(None)
    if ok:
        ok = sim.run(3.0)
    return not ok, (sim.time - t0) / (time.perf_counter() - wall)


def scenario_push(direction: str, walking: bool, force: float = 40.0, push_time: float = 0.2,
                  phases: int = 4) -> Row:
    """Push the torso from ``direction``; while walking at 0.3 m/s, once at each of ``phases``
    instants spread over one gait cycle (two steps) after 4 s of walking, so that every part
    of the gait (either stance leg, early or late, double support) is hit."""
    cycle = 2.0 * WalkingParams.load().gait.step_period
    starts = [4.0 + k * cycle / phases for k in range(phases)] if walking else [0.0]
    results = [push_once(direction, walking, force, push_time, wb) for wb in starts]
    falls = sum(f for f, _ in results)
    mode = "walking" if walking else "standing"
    cmd = (0.3, 0.0, 0.0) if walking else (0.0, 0.0, 0.0)
    note = f"fell in {falls} of {len(starts)} gait phases" if walking else ""
    return Row(f"push from {direction} {force:.0f}N {push_time}s {mode}", cmd, 3.0 + push_time,
               (np.nan,) * 3, falls > 0, float(np.median([r for _, r in results])), note)


@dataclass
class RtfRun:
    """One real-time-factor run: RTF and the wall time split (no profiler)."""

    rtf: float
    wall: float  # [s]
    controller: float  # [s] wall time inside the walking controller's discrete update
    ticks: int  # controller updates

    @property
    def controller_fraction(self) -> float:
        return self.controller / self.wall


def measure_rtf(seconds: float, repeats: int) -> list[RtfRun]:
    """Walk at 0.3 m/s for ``seconds`` of simulated time, ``repeats`` times; time the
    controller's update with perf_counter (the rest is the plant, the actuation adapter and
    the framework)."""
    runs = []
    for _ in range(repeats):
        spent = [0.0, 0]
        update = WalkingController._update

        def timed_update(self, context, discrete_state, spent=spent):
            t0 = time.perf_counter()
            update(self, context, discrete_state)
            spent[0] += time.perf_counter() - t0
            spent[1] += 1

        # The controller declares its periodic event with the bound method at construction.
        WalkingController._update = timed_update
        try:
            sim = WalkingSim()
        finally:
            WalkingController._update = update
        sim.set_command(0.3, 0.0, 0.0)
        wall = time.perf_counter()
        sim.advance(seconds)
        wall = time.perf_counter() - wall
        runs.append(RtfRun(seconds / wall, wall, spent[0], spent[1]))
    return runs


def profile_split(seconds: float) -> dict[str, float]:
    """Fractions of wall time in the plant step, the walking controller and the rest."""
    sim = WalkingSim()
    sim.set_command(0.3, 0.0, 0.0)
    prof = cProfile.Profile()
    prof.enable()
    sim.advance(seconds)
    prof.disable()
    stats = pstats.Stats(prof)
    total = sum(v[3] for v in stats.stats.values() if v[3] > 0) or 1.0
    top = max(v[3] for v in stats.stats.values())  # cumulative of the outermost call
    walker = 0.0
    adapter = 0.0
    qp = 0.0
    for (filename, _, func), v in stats.stats.items():
        if filename.endswith("controllers/walking.py") and func == "_update":
            walker += v[3]
        if filename.endswith("actuation.py") and func.startswith("_calc"):
            adapter += v[3]
        if filename.endswith("tracking/qp.py") and func == "solve":
            qp += v[3]
    del total
    rest = top - walker - adapter
    return {"total_s": top, "controller": walker / top, "qp_solve": qp / top,
            "actuation_adapter": adapter / top, "plant_and_framework": rest / top}


def _fmt(x: float) -> str:
    return "   -  " if not np.isfinite(x) else f"{x:+.3f}"


def print_table(rows: list[Row]) -> None:
    print(f"{'scenario':38s} {'cmd vx,vy,wz':18s} {'got vx':>7s} {'got vy':>7s} {'got wz':>7s}"
          f" {'fell':>5s} {'RTF':>5s}  note")
    for r in rows:
        cmd = ",".join(f"{c:g}" for c in r.command)
        print(f"{r.name:38s} {cmd:18s} {_fmt(r.achieved[0]):>7s} {_fmt(r.achieved[1]):>7s}"
              f" {_fmt(r.achieved[2]):>7s} {'YES' if r.fell else 'no':>5s} {r.rtf:5.2f}  {r.note}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="pr2-drake bench walking", description=__doc__)
    parser.add_argument("--quick", action="store_true", help="short smoke run (~1 min)")
    parser.add_argument("--repeats", type=int, default=3, help="runs for the median RTF")
    parser.add_argument("--no-profile", action="store_true", help="skip the cProfile split")
    parser.add_argument("--push-force", type=float, default=40.0, help="torso push [N]")
    parser.add_argument("--push-time", type=float, default=0.2, help="push duration [s]")
    parser.add_argument("--push-phases", type=int, default=4,
                        help="walking pushes: instants per gait cycle")
    args = parser.parse_args(argv)
    if args.push_phases < 1 or args.repeats < 1:
        parser.error("--push-phases and --repeats must be at least 1")
    q = args.quick
    rows = []
    walk_t = 8.0 if q else 20.0
    rows.append(scenario_walk("forward 0.3 m/s", (0.3, 0.0, 0.0), walk_t))
    if not q:
        rows.append(scenario_walk("backward -0.15 m/s", (-0.15, 0.0, 0.0), 10.0))
        rows.append(scenario_walk("sideways 0.1 m/s", (0.0, 0.1, 0.0), 10.0))
        rows.append(scenario_walk("turn 0.4 rad/s", (0.0, 0.0, 0.4), 10.0))
    rows.append(scenario_stand(5.0 if q else 60.0))
    pushes = [("front", False), ("right", True)] if q else [
        (d, w) for w in (False, True) for d in PUSH_FROM]
    for d, w in pushes:
        rows.append(scenario_push(d, w, args.push_force, args.push_time,
                                  1 if q else args.push_phases))
    print_table(rows)
    fwd = rows[0]
    speed_ok = (not fwd.fell) and abs(fwd.achieved[0] - 0.3) <= 0.05
    print(f"\nforward 0.3 m/s: mean speed {fwd.achieved[0]:.3f} m/s "
          f"({'within' if speed_ok else 'NOT within'} 0.05 m/s), fell: {fwd.fell}")
    rtf_seconds = 3.0 if q else 10.0
    repeats = 1 if q else args.repeats
    runs = measure_rtf(rtf_seconds, repeats)
    rates = [r.rtf for r in runs]
    med = sorted(runs, key=lambda r: r.rtf)[len(runs) // 2]
    print(f"real-time factor, 0.3 m/s walking, {rtf_seconds:g} s sim, {repeats} run(s): "
          f"median {statistics.median(rates):.2f} (runs: {', '.join(f'{r:.2f}' for r in rates)})"
          f"; target >= 1.0")
    ms_tick = 1e3 * med.controller / max(med.ticks, 1)
    from pr2_drake.testbed import DEFAULT_TIME_STEP

    ms_step = 1e3 * (med.wall - med.controller) / (rtf_seconds / DEFAULT_TIME_STEP)
    print(f"wall time split (median run, perf_counter): controller {med.controller_fraction:.0%}"
          f" ({ms_tick:.2f} ms per {med.ticks} control ticks), plant + actuation + framework"
          f" {1 - med.controller_fraction:.0%} ({ms_step:.2f} ms per {DEFAULT_TIME_STEP * 1e3:g} ms physics step)")
    if not args.no_profile:
        split = profile_split(2.0 if q else 5.0)
        print("time split under cProfile (adds overhead): "
              f"controller {split['controller']:.0%} (of which QP solve {split['qp_solve']:.0%}),"
              f" actuation adapter {split['actuation_adapter']:.0%},"
              f" plant + framework {split['plant_and_framework']:.0%}")
    failures = sum(r.fell for r in rows)
    print(f"falls: {failures} of {len(rows)} scenarios")
    return 0


if __name__ == "__main__":
    sys.exit(main())

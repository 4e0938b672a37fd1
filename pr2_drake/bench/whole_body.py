"""Whole-body controller benchmark: forces at a hand, hand tracking, reach, tick time, RTF.

    pr2-drake bench whole-body [--quick] [--repeats 3] [--baseline REF] [--no-baseline]
    python -m pr2_drake.bench.whole_body [--quick]

Flat ground, discrete SAP 1 ms, the walking controller with the arms in the QP
(``WalkingController(arms="effort")``). Rows:

- hand force: standing, the left hand held in front, a constant horizontal force of 30 N or 50 N
  (forward or sideways, outwards) at the hand sphere centre for 3 s, as a rope attached to the
  hand would pull. "held": the controller's ``pick_state`` says the hand is attached, so the QP
  carries the hand's contact force (centred on its estimate from the arm torques) and the
  standing CoM leans against it; "not held": the same force unannounced (a disturbance).
  Reported: fall, peak torso pitch and roll [deg], base drift [cm]. Each force is applied at
  once, and (held) also built up and let go over ``FORCE_RAMP`` seconds each, as a valve's or a
  rope's reaction builds and fades. A force applied at once is limited by the feet: its moment about the ground,
  f (z_H - z_ground), must be met at that instant by m g times the CoM's distance from the
  centre of pressure, at most half a sole length (0.075 m) until the CoM has moved; for this
  34.5 kg robot and hand height that is about 35 N forward. Sideways the stance width gives
  more. A ramped force is leaned against as it grows, up to what the soles allow: the CoM at
  ``gait.lean_margin`` inside the heel points and the centre of pressure at the toe points,
  m g (0.13 m - lean_margin) / (z_H - z_ground), about 52 N at 0.02 m, so 50 N forward has
  no margin left (it holds with lean_margin 0, falls with 0.01). A step does not extend
  that: KUAVO's line soles, side by side or split, span a parallelogram whose length along
  the heading is one sole's 0.13 m at every point across it. What would: longer soles or
  turning side-on to the force;
- hand tracking: targets on a grid in front of the left shoulder, one after the other (1.5 s
  each); the error at the end of each (median and max) [cm];
- reach: the hand target moved forward (and, separately, down) in 2 cm steps until the hand
  misses it by more than 2 cm or the robot falls; the farthest hand position reached, forward
  of the base and above the ground [m];
- tick time split (walking 0.3 m/s, arms in the QP): planner, tasks, QP [ms per tick];
- closed-loop real-time factor walking at 0.3 m/s, 10 s, median of ``--repeats``, this code
  against ``--baseline`` (a git ref, default the last commit before the whole-body split),
  runs interleaved (baseline, this, baseline, this, ...) in fresh processes on this machine.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from pr2_drake.bench.walking import WalkingSim
from pr2_drake.grasp import PickState

#: The last commit before the whole-body split (WalkingCore as one class): the "before".
BASELINE_REF = "c5e37f2"
HAND = 0  # left
HAND_OFFSET_B = np.array([0.26, 0.14, 0.16])  # [m] held hand, from the base (heading frame)
FORCE_RAMP = 0.5  # [s] build-up time of the ramped hand-force rows
RAMP_STEP = 0.01  # [s] the ramped force is updated this often


def _sim(held: bool = False) -> WalkingSim:
    sim = WalkingSim(arms="effort", pick_state_from_testbed=False)
    sim.walker.GetInputPort("pick_state").FixValue(
        sim.walker_context, PickState(True, "left_hand", "rope") if held else PickState())
    return sim


def hand_force_row(force: float, direction: str, held: bool, ramp: float = 0.0) -> dict:
    """Stand, hold the left hand in front, pull it with ``force`` N for 3 s: applied and let go
    at once (``ramp`` = 0), or built up and let go linearly over ``ramp`` seconds each; then
    1 s without it."""
    sim = _sim(held)
    ok = sim.run(1.0)
    p0, *_ = sim.base_pose()
    sim.set_hand_targets([p0 + HAND_OFFSET_B, None])
    ok = ok and sim.run(1.5)
    hand_body = sim.plant.GetBodyByName("l_arm_sphere")
    f = np.array([force, 0.0, 0.0]) if direction == "forward" else np.array([0.0, force, 0.0])
    peak_pitch = peak_roll = 0.0
    t0 = sim.time
    t_end = t0 + 3.0
    while ok and sim.time < t_end - 1e-9:
        ramping = sim.time < t0 + ramp - 1e-9
        dt = RAMP_STEP if ramping else 0.05
        scale = min((sim.time - t0 + dt) / ramp, 1.0) if ramping else 1.0
        sim.push(scale * f, body=hand_body, p_BQ=np.zeros(3))
        ok = sim.run(dt, check_every=dt)
        _, roll, pitch, _ = sim.base_pose()
        peak_pitch = max(peak_pitch, abs(pitch))
        peak_roll = max(peak_roll, abs(roll))
    p1, *_ = sim.base_pose()
    f_est = sim.walker.core.hand_force.f[HAND].copy()
    t1 = sim.time
    while ok and sim.time < t1 + ramp - 1e-9:  # let go as it was built up
        sim.push((1.0 - (sim.time - t1 + RAMP_STEP) / ramp) * f, body=hand_body,
                 p_BQ=np.zeros(3))
        ok = sim.run(RAMP_STEP, check_every=RAMP_STEP)
    sim.push(None)
    ok = ok and sim.run(1.0)
    how = "held" if held else "not held"
    if ramp > 0.0:
        how += f", ramp {ramp:g} s"
    return dict(name=f"{force:.0f} N {direction}, {how}", fell=not ok,
                pitch=np.degrees(peak_pitch), roll=np.degrees(peak_roll),
                drift=100 * float(np.linalg.norm(p1[:2] - p0[:2])), f_est=f_est)


def tracking_grid(quick: bool) -> dict:
    """Hand tracking error over a grid of targets in front of the left shoulder."""
    sim = _sim()
    ok = sim.run(1.0)
    core = sim.walker.core
    m = core.model
    s0 = m.shoulder_position(HAND).copy()
    xs, ys, zs = ((0.2, 0.3), (0.0,), (-0.15, 0.0)) if quick else (
        (0.15, 0.22, 0.30), (-0.10, 0.0, 0.10), (-0.25, -0.10, 0.05))
    errors = []
    for dx in xs:
        for dy in ys:
            for dz in zs:
                target = s0 + np.array([dx, dy, dz])
                sim.set_hand_targets([target, None])
                ok = ok and sim.run(1.5)
                if not ok:
                    break
                errors.append(float(np.linalg.norm(m.hand_point(HAND)[0] - target)))
    return dict(n=len(errors), fell=not ok, median=100 * statistics.median(errors),
                max=100 * max(errors))


def reach_limit(axis: str) -> dict:
    """Move the hand target ``axis`` ("forward" or "down") in 2 cm steps until it is missed."""
    sim = _sim()
    ok = sim.run(1.0)
    m = sim.walker.core.model
    p_B, *_ = sim.base_pose()
    start = m.shoulder_position(HAND) + np.array([0.20, 0.0, -0.15])
    step = np.array([0.02, 0.0, 0.0]) if axis == "forward" else np.array([0.0, 0.0, -0.02])
    best = None
    for k in range(40):
        target = start + k * step
        sim.set_hand_targets([target, None])
        ok = sim.run(1.0)
        hand = m.hand_point(HAND)[0]
        if not ok or np.linalg.norm(hand - target) > 0.02:
            break
        best = hand.copy()
    if best is None:
        return dict(axis=axis, fell=not ok, value=float("nan"))
    value = best[0] - p_B[0] if axis == "forward" else best[2]
    return dict(axis=axis, fell=not ok, value=float(value))


def tick_split(seconds: float) -> dict:
    """Planner / tasks / QP time per control tick [ms], walking at 0.3 m/s, arms in the QP."""
    sim = _sim()
    core = sim.walker.core
    sim.set_command(0.3, 0.0, 0.0)
    sim.run(1.0)
    core.timing[:] = 0.0
    core.timed = True
    ticks0 = _count_ticks(sim)
    wall = time.perf_counter()
    sim.run(seconds)
    wall = time.perf_counter() - wall
    ticks = _count_ticks(sim) - ticks0
    core.timed = False
    ms = 1e3 * core.timing / max(ticks, 1)
    return dict(planner=ms[0], tasks=ms[1], qp=ms[2], ticks=ticks,
                rtf=seconds / wall)


def _count_ticks(sim: WalkingSim) -> int:
    return int(round(sim.time / sim.walker.params.control_period))


_RTF_SNIPPET = """
import sys, time
from pr2_drake.bench.walking import WalkingSim
sim = WalkingSim()
sim.set_command(0.3, 0.0, 0.0)
c, w = time.process_time(), time.perf_counter()
sim.advance({seconds})
print("RTF", {seconds} / (time.perf_counter() - w), {seconds} / (time.process_time() - c))
"""


def _rtf_process(root: Path, seconds: float) -> tuple[float, float]:
    """(wall-clock RTF, CPU-time RTF) of one run: on a shared machine the CPU-time figure
    (simulated time over this process's CPU time) is less disturbed by other processes."""
    env = dict(os.environ, PYTHONPATH=str(root))
    out = subprocess.run([sys.executable, "-c", _RTF_SNIPPET.format(seconds=seconds)],
                         cwd=root, env=env, capture_output=True, text=True, check=True)
    wall, cpu = out.stdout.split("RTF")[-1].split()
    return float(wall), float(cpu)


def compare_rtf(baseline: str | None, seconds: float, repeats: int) -> dict:
    """RTF walking at 0.3 m/s (position-mode arms, as the walking agents run), this code and
    the baseline ref, interleaved, each in a fresh process."""
    here = Path(__file__).resolve().parents[2]
    tmp = None
    if baseline:
        tmp = Path(tempfile.mkdtemp(prefix="pr2_baseline_"))
        archive = subprocess.run(["git", "-C", str(here), "archive", baseline],
                                 capture_output=True, check=True).stdout
        subprocess.run(["tar", "-x", "-C", str(tmp)], input=archive, check=True)
    new, old = [], []
    try:
        for _ in range(repeats):
            if tmp is not None:
                old.append(_rtf_process(tmp, seconds))
            new.append(_rtf_process(here, seconds))
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
    return dict(new=new, old=old)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="pr2-drake bench whole-body", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="short smoke run")
    parser.add_argument("--repeats", type=int, default=3, help="runs for the median RTF")
    parser.add_argument("--baseline", default=BASELINE_REF,
                        help=f"git ref of the 'before' code (default {BASELINE_REF})")
    parser.add_argument("--no-baseline", action="store_true", help="skip the 'before' runs")
    args = parser.parse_args(argv)
    if args.repeats < 1:
        parser.error("--repeats must be at least 1")
    q = args.quick
    print("hand force (standing, left hand held in front, force at the hand sphere for 3 s)")
    print(f"  {'case':38s} {'fell':>5s} {'pitch':>7s} {'roll':>7s} {'drift':>7s}  estimate [N]")
    forces = (30.0,) if q else (30.0, 50.0)
    falls = 0
    for force in forces:
        for direction in ("forward", "sideways"):
            cases = ((True, 0.0),) if q else ((True, 0.0), (False, 0.0), (True, FORCE_RAMP))
            for held, ramp in cases:
                r = hand_force_row(force, direction, held, ramp)
                falls += r["fell"]
                est = ", ".join(f"{x:+.0f}" for x in r["f_est"])
                print(f"  {r['name']:38s} {'YES' if r['fell'] else 'no':>5s} "
                      f"{r['pitch']:6.1f}d {r['roll']:6.1f}d {r['drift']:5.1f}cm  ({est})",
                      flush=True)
    g = tracking_grid(q)
    print(f"hand tracking, {g['n']} targets in front of the shoulder: error median "
          f"{g['median']:.1f} cm, max {g['max']:.1f} cm, fell: {g['fell']}")
    for axis in ("forward", "down"):
        r = reach_limit(axis)
        what = "forward of the base" if axis == "forward" else "above the ground"
        print(f"reach {axis}: hand within 2 cm of its target up to {r['value']:.2f} m {what},"
              f" fell: {r['fell']}")
    s = tick_split(2.0 if q else 5.0)
    total = s["planner"] + s["tasks"] + s["qp"]
    print(f"tick time (walking 0.3 m/s, arms in the QP, {s['ticks']} ticks): planner "
          f"{s['planner']:.3f} ms, tasks {s['tasks']:.3f} ms, QP (set-up + solve) "
          f"{s['qp']:.3f} ms; total {total:.3f} ms per tick; closed-loop RTF {s['rtf']:.2f}")
    baseline = None if args.no_baseline else args.baseline
    seconds = 3.0 if q else 10.0
    repeats = 1 if q else args.repeats
    res = compare_rtf(baseline, seconds, repeats)
    print(f"closed-loop RTF, walking 0.3 m/s, {seconds:g} s, {repeats} run(s) each, "
          "interleaved (wall clock; CPU time of the process):")
    for name, runs in (("this code", res["new"]), (f"before ({baseline})", res["old"])):
        if runs:
            wall = [r[0] for r in runs]
            cpu = [r[1] for r in runs]
            print(f"  {name:22s} median {statistics.median(wall):.2f} "
                  f"({', '.join(f'{x:.2f}' for x in wall)}); CPU-time RTF median "
                  f"{statistics.median(cpu):.2f} ({', '.join(f'{x:.2f}' for x in cpu)})")
    print(f"falls in the hand-force rows: {falls}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

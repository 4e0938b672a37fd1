"""Whole-body controller benchmark: forces at a hand, hand tracking, reach, tick time, RTF.

    pr2-drake bench whole-body [--quick] [--repeats 3] [--baseline REF] [--no-baseline]
    python -m pr2_drake.bench.whole_body [--quick]

Flat ground, discrete SAP at the default physics step, the walking controller with the arms in the QP
(``WalkingController(arms="effort")``). Rows:

- hand force: standing, the left hand held in front, a constant horizontal force of 30 N or 50 N
  (forward or sideways, outwards) at the hand sphere centre for 3 s, as a rope attached to the
  hand would pull. "held": the controller's ``pick_state`` says the hand is attached, so the QP
  carries the hand's contact force (centred on its estimate from the arm torques) and the
  standing CoM leans against it; "not held": the same force unannounced (a disturbance).
  Reported: fall, peak torso pitch and roll [deg], base drift while the force acts [cm], and
  the soles' limit for that row [N] (:func:`support_limits`, from the stance and hand height
  at the time). Each force is applied at once, and (held) also built up and let go over
  ``FORCE_RAMP`` seconds each, as a valve's or a rope's reaction builds and fades. Every case
  is run twice: square-on (the robot faces the way it faced when the hand took hold), and
  turned ``TURN_DEG`` to the right first (turning in place with the velocity command, the hand
  target left where it was), so that the pull crosses the stance's diagonal.

  The limits are statics (moments about the ground, the CoM at rest): a force f at the hand's
  height h above the ground needs the centre of pressure f h / (m g) ahead of the CoM along f.
  Applied at once, the CoM has not moved yet, so f <= m g d / h, d the distance from the CoM to
  the edge of the support polygon along f. Built up slowly, the CoM leans back as far as
  ``gait.lean_margin`` inside the polygon (so that it can be brought back when the force stops),
  so f <= m g (chord - lean_margin) / h, chord the polygon's length along f through the CoM.
  KUAVO's line soles (heel and toe contact points 0.13 m apart; a 0.15 m foot in TASKS.md) make
  any square-on stance 0.13 m long along the heading, whether side by side or split: for this
  34.5 kg robot and the hand 0.73 m up, 32 N at once and 51 N built up (with the 0.02 m
  margin). So a square-on 50 N forward pull falls: at once it is over its limit, built up it is
  at 98 % of it (the centre of pressure would have to sit on the toe points). Turned 45
  degrees, the pull crosses the stance's diagonal (0.18 m): 46 N at once, 75 N built up. An
  unannounced force ("not held") is met only once the controller sees its effect, so those rows
  can fall below their limit;
- hand tracking: targets on a grid in front of the left shoulder, one after the other (1.5 s
  each); the error at the end of each (median and max) [cm];
- reach: the hand target moved forward (and, separately, down) in 2 cm steps until the hand
  misses it by more than 2 cm or the robot falls; the farthest hand position reached, forward
  of the base and above the ground [m];
- tick time split (walking 0.3 m/s, arms in the QP): planner, objectives, QP [ms per tick];
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

from pr2_drake.bench.rigs import WalkingSim
from pr2_drake.grasp import PickState

#: The last commit before the whole-body split (WalkingCore as one class): the "before".
BASELINE_REF = "c5e37f2"
HAND = 0  # left
HAND_OFFSET_B = np.array([0.26, 0.14, 0.16])  # [m] held hand, from the base (heading frame)
FORCE_RAMP = 0.5  # [s] build-up time of the ramped hand-force rows
TURN_DEG = -45.0  # [deg] the turned hand-force rows first turn in place by this (right)
TURN_RATE = 0.4  # [rad/s] ... at this yaw rate
RAMP_STEP = 0.01  # [s] the ramped force is updated this often


def _sim(held: bool = False) -> WalkingSim:
    sim = WalkingSim(arms="effort", pick_state_from_testbed=False)
    sim.walker.GetInputPort("pick_state").FixValue(
        sim.walker_context, PickState(True, "left_hand", "rope") if held else PickState())
    return sim


def support_limits(sim: WalkingSim, direction_W: np.ndarray, hand: int = HAND) -> dict:
    """The soles' statics limits [N] for a horizontal force along ``direction_W`` at a hand, in
    the robot's current stance (see the module docstring): ``at_once`` = m g d / h and
    ``built_up`` = m g (chord - lean_margin) / h, d [m] the distance from the CoM to the support
    polygon's edge along the force, chord [m] the polygon's length along it through the CoM,
    h [m] the hand's height above the ground. The polygon is the convex hull of both soles'
    contact points (the controller's model, at its last tick); also returned: ``chord``,
    ``height``, ``hull`` (k, 2) [m, W] and the CoM's ``com`` (2) [m, W]."""
    u = np.asarray(direction_W, dtype=float)[:2]
    if not np.all(np.isfinite(u)) or np.linalg.norm(u) < 1e-9:
        raise ValueError(f"direction_W must have a finite, non-zero horizontal part, got "
                         f"{direction_W!r}")
    u = u / np.linalg.norm(u)
    core = sim.walker.core
    m = core.model
    soles = [m.sole_pose(side) for side in (0, 1)]
    points = np.hstack([X.rotation().matrix() @ m.p_SC + X.translation()[:, None]
                        for X in soles])
    ground = float(np.min(points[2]))
    hull = convex_hull(points[:2].T)
    c = m.com()[0][:2]
    ahead, behind = ray_to_edge(hull, c, u), ray_to_edge(hull, c, -u)
    h = float(m.hand_point(hand)[0][2]) - ground
    weight = m.mass * m.gravity
    margin = sim.walker.params.gait.lean_margin
    return dict(at_once=weight * ahead / h,
                built_up=weight * max(ahead + behind - margin, 0.0) / h,
                chord=ahead + behind, height=h, hull=hull, com=c.copy())


def convex_hull(points: np.ndarray) -> np.ndarray:
    """Counter-clockwise convex hull (k, 2) of 2-D points (n, 2) (Andrew's monotone chain)."""
    pts = sorted(map(tuple, np.asarray(points, dtype=float)))

    def half(seq):
        out: list = []
        for p in seq:
            while len(out) >= 2 and ((out[-1][0] - out[-2][0]) * (p[1] - out[-2][1])
                                     - (out[-1][1] - out[-2][1]) * (p[0] - out[-2][0])) <= 0.0:
                out.pop()
            out.append(p)
        return out

    lower, upper = half(pts), half(reversed(pts))
    return np.array(lower[:-1] + upper[:-1])


def ray_to_edge(hull: np.ndarray, c: np.ndarray, u: np.ndarray) -> float:
    """Distance [m] from c along the unit vector u to the edge of a counter-clockwise convex
    polygon (negative if c is outside, behind that edge)."""
    best = np.inf
    for a, b in zip(hull, np.roll(hull, -1, axis=0)):
        n = np.array([b[1] - a[1], a[0] - b[0]])  # outward normal of edge a -> b
        nu = float(n @ u)
        if nu > 1e-12:
            best = min(best, float(n @ (a - c)) / nu)
    return float(best)


def turn_in_place(sim: WalkingSim, angle: float) -> bool:
    """Turn in place by ``angle`` [rad] (positive left) with the velocity command, then stand
    for 1.5 s. Returns False if the robot fell."""
    *_, yaw0 = sim.base_pose()
    # The gait stops after the step in progress: stop commanding a little short of the angle.
    stop_short = 0.5 * TURN_RATE * sim.walker.params.gait.single_support
    sim.set_command(0.0, 0.0, float(np.sign(angle)) * TURN_RATE)
    ok = True
    t_max = sim.time + abs(angle) / TURN_RATE + 3.0
    while ok and sim.time < t_max:
        ok = sim.run(0.05, check_every=0.05)
        *_, yaw = sim.base_pose()
        if abs(np.angle(np.exp(1j * (yaw - yaw0)))) >= abs(angle) - stop_short:
            break
    sim.set_command(0.0, 0.0, 0.0)
    return ok and sim.run(1.5)


def hand_force_row(force: float, direction: str, held: bool, ramp: float = 0.0,
                   turn_deg: float = 0.0, let_go: float | None = None) -> dict:
    """Stand, hold the left hand in front, pull it with ``force`` N for 3 s: applied and let go
    at once (``ramp`` = 0), or built up and let go linearly over ``ramp`` seconds each (``let_go``
    [s] to let go over another time, 0 = at once); then 1 s without it. ``turn_deg`` != 0:
    first turn in place by that angle [deg] (positive left); the hand target and the force's
    direction stay as they were."""
    let_go = ramp if let_go is None else let_go
    sim = _sim(held)
    ok = sim.run(1.0)
    p0, *_ = sim.base_pose()
    if turn_deg:
        ok = ok and turn_in_place(sim, np.radians(turn_deg))
    sim.set_hand_targets([p0 + HAND_OFFSET_B, None])
    ok = ok and sim.run(1.5)
    p_start, *_ = sim.base_pose()
    hand_body = sim.plant.GetBodyByName("l_arm_sphere")
    f = np.array([force, 0.0, 0.0]) if direction == "forward" else np.array([0.0, force, 0.0])
    limits = support_limits(sim, f)
    limit = limits["built_up"] if held and ramp > 0.0 else limits["at_once"]
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
    while ok and sim.time < t1 + let_go - 1e-9:  # let go (as it was built up)
        sim.push((1.0 - (sim.time - t1 + RAMP_STEP) / let_go) * f, body=hand_body,
                 p_BQ=np.zeros(3))
        ok = sim.run(RAMP_STEP, check_every=RAMP_STEP)
    sim.push(None)
    ok = ok and sim.run(1.0)
    how = "held" if held else "not held"
    if ramp > 0.0:
        how += f", ramp {ramp:g} s"
    if let_go != ramp:
        how += f", let go over {let_go:g} s" if let_go > 0.0 else ", let go at once"
    if turn_deg:
        how += f", turned {abs(turn_deg):g}d {'left' if turn_deg > 0 else 'right'}"
    return dict(name=f"{force:.0f} N {direction}, {how}", fell=not ok,
                pitch=np.degrees(peak_pitch), roll=np.degrees(peak_roll),
                drift=100 * float(np.linalg.norm(p1[:2] - p_start[:2])), f_est=f_est,
                limit=limit, over_limit=force > limit)


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
    """Planner / objectives / QP time per control tick [ms], walking at 0.3 m/s, arms in the QP."""
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
    return dict(planner=ms[0], objectives=ms[1], qp=ms[2], ticks=ticks,
                rtf=seconds / wall)


def _count_ticks(sim: WalkingSim) -> int:
    return int(round(sim.time / sim.walker.params.control_period))


_RTF_SNIPPET = """
import sys, time
try:
    from pr2_drake.bench.rigs import WalkingSim
except ImportError:  # a commit before the rigs module
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
    print("hand force (standing, left hand held in front, force at the hand sphere for 3 s; "
          "limit: the soles' statics, see --help)")
    print(f"  {'case':52s} {'fell':>5s} {'pitch':>7s} {'roll':>7s} {'drift':>7s} "
          f"{'limit':>6s}  estimate [N]")
    forces = (30.0,) if q else (30.0, 50.0)
    falls = over = falls_within = held_within = held_within_falls = 0
    for turn in (0.0, TURN_DEG):
        for force in forces:
            for direction in ("forward", "sideways"):
                cases = ((True, 0.0),) if q else ((True, 0.0), (False, 0.0), (True, FORCE_RAMP))
                for held, ramp in cases:
                    r = hand_force_row(force, direction, held, ramp, turn)
                    falls += r["fell"]
                    over += r["over_limit"]
                    falls_within += r["fell"] and not r["over_limit"]
                    held_within += held and not r["over_limit"]
                    held_within_falls += held and r["fell"] and not r["over_limit"]
                    est = ", ".join(f"{x:+.0f}" for x in r["f_est"])
                    print(f"  {r['name']:52s} {'YES' if r['fell'] else 'no':>5s} "
                          f"{r['pitch']:6.1f}d {r['roll']:6.1f}d {r['drift']:5.1f}cm "
                          f"{r['limit']:5.0f}{'<' if r['over_limit'] else ' '}  ({est})",
                          flush=True)
    print(f"  falls: {falls}; rows whose force is above the soles' limit ('<'): {over}; "
          f"falls within the limit: {falls_within}, of which held: {held_within_falls} "
          f"(of {held_within} held rows within their limit)")
    g = tracking_grid(q)
    print(f"hand tracking, {g['n']} targets in front of the shoulder: error median "
          f"{g['median']:.1f} cm, max {g['max']:.1f} cm, fell: {g['fell']}")
    for axis in ("forward", "down"):
        r = reach_limit(axis)
        what = "forward of the base" if axis == "forward" else "above the ground"
        print(f"reach {axis}: hand within 2 cm of its target up to {r['value']:.2f} m {what},"
              f" fell: {r['fell']}")
    s = tick_split(2.0 if q else 5.0)
    total = s["planner"] + s["objectives"] + s["qp"]
    print(f"tick time (walking 0.3 m/s, arms in the QP, {s['ticks']} ticks): planner "
          f"{s['planner']:.3f} ms, objectives {s['objectives']:.3f} ms, QP (set-up + solve) "
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
    print(f"hand-force rows: {falls} falls, {falls_within} of them within the soles' limit")
    return 0


if __name__ == "__main__":
    sys.exit(main())

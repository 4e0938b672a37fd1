"""Stairs benchmark: up then down a staircase, per riser height and step count.

    pr2-drake bench stairs [--quick] [--repeats 5] [--heights 0.05 0.10 0.12 0.15]
                           [--counts 2 4]
    python -m pr2_drake.bench.stairs [--quick]

Builds its own scene (the testbed's ``scene_builder``): flat ground, ``count`` steps of one riser
height and 0.40 m treads up along +x, a 1.2 m floor, the same steps down. The robot starts
in front of the first step (``repeats`` starts, slightly shifted in x, y and yaw, seeded) and
walks with the walking controller, :class:`pr2_drake.controllers.planning.tread_steps.
TreadFootstepPlanner` and the staircase's :class:`PatchTerrain` (params/controllers/walking_stairs.yaml)
at a constant forward command with heading hold, until its base is past the last step.

The walk holds the start's y (``--lane-gain``, 0.8 1/s as StepsButtonAgent; 0 = off): without
it the robot drifts 0.1-0.2 m sideways at each riser (the pelvis rolls while the swing leg
lifts fast over the riser) and walks off the side of 2 m wide stairs. ``--overrides`` applies a
YAML of walking parameters after walking_stairs.yaml (tuning).

Prints one row per (riser, count): falls out of the repeats, mean simulated time to cross, the
wall-clock real-time factor while climbing; for each fall where it happened (going up / top
floor / going down, which riser, sim time) and the first sign of trouble in the last second
(:func:`pr2_drake.bench.stair_falls.diagnose`: a knee at its limit, a swing toe caught on a riser's nosing, heel
or toe off an edge, a sole off the side, the DCM outside the support); then the highest riser
climbed up and down without a fall in all repeats.

What limits step height now: the planner refuses risers over 0.12 m
(params/controllers/tread_planner.yaml ``max_step_height``), the highest measured without a fall:
``pr2-drake bench stairs`` (5 repeats, up then down, 4 ms physics): 0.05, 0.10 and 0.12 m, 2
and 4 steps, 0/5 falls each; ``--max-step-height 0.15 --heights 0.15``: 2 and 4 steps, 5/5
falls each, all going up (the swing toe caught on the nosing, the stance knee at its limit,
the DCM outside the support). 0.12 m holds with the arms swung by the QP (going up; held in
position mode it fell x 2 3/5 and x 4 5/5) and with the step-down swing that moves early and
lowers once its heel is past the edge (going down; gait ``swing_down_*``). The closed loop
on a staircase is :class:`pr2_drake.bench.rigs.StairsSim`.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import dataclass, replace

import numpy as np

from pr2_drake.bench.rigs import STAIRS_WALKING, StairsSim
from pr2_drake.bench.stair_falls import TREAD, Fall
from pr2_drake.controllers.planning.terrain import stairs_terrain
from pr2_drake.controllers.planning.tread_steps import TreadPlannerParams
from pr2_drake.controllers.walking_params import WalkingParams
from pr2_drake.scene import StartPose

FLOOR_LENGTH = 1.2  # [m] level top between the way up and the way down
START_X = 1.0  # [m] first riser; the robot starts at x = 0
#: [1/s] the bench walk holds the start's y like StepsButtonAgent (lateral_gain 0.8 1/s,
#: max 0.08 m/s): without it the robot drifts 0.1-0.2 m sideways per riser crossing.
LANE_GAIN = 0.8


@dataclass
class Row:
    height: float
    count: int
    falls: int
    repeats: int
    time: float  # mean simulated time to cross [s] (runs without a fall)
    rtf: float  # wall-clock real-time factor while walking


def starts(repeats: int, seed: int = 0) -> list[StartPose]:
    """Slightly different starts: x in [-0.05, 0.05], y in [-0.05, 0.05] m, yaw +-3 deg."""
    rng = np.random.default_rng(seed)
    return [StartPose(float(rng.uniform(-0.05, 0.05)), float(rng.uniform(-0.05, 0.05)),
                      float(np.radians(rng.uniform(-3.0, 3.0)))) for _ in range(repeats)]


def run_stairs(height: float, count: int, start: StartPose, speed: float = 0.25,
               meshcat=None, lane_gain: float = LANE_GAIN, overrides: str | None = None,
               max_step_height: float | None = None) -> tuple[bool, float, float, Fall | None]:
    """Up then down one staircase: (no fall, simulated time [s], real-time factor, where and
    why it failed or None). ``overrides``: a YAML file of walking parameters applied after
    params/controllers/walking_stairs.yaml (tuning); ``max_step_height`` [m]: the planner's limit in
    place of params/controllers/tread_planner.yaml's (to measure beyond it).

    Raises:
        ValueError: a riser taller than the planner's limit (the planner refuses it)."""
    terrain = stairs_terrain(START_X, count, height, TREAD, 2.0, floor_length=FLOOR_LENGTH,
                             down=True)
    params = WalkingParams.load().with_overrides(STAIRS_WALKING)
    if overrides:
        params = params.with_overrides(overrides)
    planner = TreadPlannerParams.load()
    if max_step_height is not None:
        planner = replace(planner, max_step_height=float(max_step_height))
    sim = StairsSim(terrain, start, params=params, planner_params=planner, meshcat=meshcat)
    x_end = START_X + 2 * count * TREAD + FLOOR_LENGTH - TREAD + 0.4
    wall = time.perf_counter()
    ok = sim.walk(speed, x_end, timeout=20.0 + 8.0 * count, lane_gain=lane_gain)
    rtf = sim.time / max(time.perf_counter() - wall, 1e-9)
    return ok, sim.time, rtf, sim.fall


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="pr2-drake bench stairs", description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="0.10 m, 2 steps, 1 repeat")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--heights", type=float, nargs="+", default=[0.05, 0.10, 0.12, 0.15])
    ap.add_argument("--counts", type=int, nargs="+", default=[2, 4])
    ap.add_argument("--lane-gain", type=float, default=LANE_GAIN,
                    help="[1/s] sideways command per m of drift from the start's y (0: none)")
    ap.add_argument("--overrides", default=None,
                    help="YAML of walking parameters applied after walking_stairs.yaml")
    ap.add_argument("--max-step-height", type=float, default=None,
                    help="[m] the planner's riser limit in place of tread_planner.yaml's "
                         "(taller risers are refused; raise it to measure beyond)")
    args = ap.parse_args(argv)
    if args.repeats < 1:
        ap.error("--repeats must be at least 1")
    heights, counts, repeats = args.heights, args.counts, args.repeats
    if args.quick:
        heights, counts, repeats = [0.10], [2], 1
    rows: list[Row] = []
    falls: list[str] = []
    refused: set[float] = set()
    print(f"{'riser [m]':>9} {'steps':>5} {'falls':>7} {'time [s]':>9} {'RTF':>6}")
    for h in heights:
        for n in counts:
            results = []
            try:
                for k, s in enumerate(starts(repeats)):
                    results.append(run_stairs(h, n, s, lane_gain=args.lane_gain,
                                              overrides=args.overrides,
                                              max_step_height=args.max_step_height))
                    if results[-1][3] is not None:
                        falls.append(f"  {h:.2f} m x {n}, repeat {k} (start x {s.x:+.3f} m, "
                                     f"y {s.y:+.3f} m, yaw {math.degrees(s.yaw):+.1f} deg): "
                                     f"{results[-1][3]}")
                        print(falls[-1], flush=True)
            except ValueError as e:  # the planner refuses the riser
                print(f"{h:9.2f} {n:5d} refused: {e}", flush=True)
                refused.add(h)
                continue
            ok = [r for r in results if r[0]]
            row = Row(h, n, len(results) - len(ok), len(results),
                      float(np.mean([r[1] for r in ok])) if ok else float("nan"),
                      float(np.median([r[2] for r in results])))
            rows.append(row)
            print(f"{h:9.2f} {n:5d} {row.falls:3d}/{row.repeats:<3d} {row.time:9.1f} "
                  f"{row.rtf:6.3f}", flush=True)
    safe = [h for h in heights
            if h not in refused and all(r.falls == 0 for r in rows if r.height == h)]
    best = max(safe) if safe else None
    if falls:
        print("falls (where, and the first sign of trouble in the last second):")
        print("\n".join(falls))
    print("highest riser climbed up and down without a fall in all repeats: "
          + ("none" if best is None else f"{best:.2f} m"))
    return 0


if __name__ == "__main__":
    sys.exit(main())

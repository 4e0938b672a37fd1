"""``pr2-drake bench``: speed benchmarks. Figures in docs come from these commands.

    pr2-drake bench sim [--seconds 10] [--repeats 3] [--task N] [--profile]
        real-time factor of the standing robot in closed loop (median of repeats), and the
        split of wall time between the plant step and the Python controller blocks.
    pr2-drake bench camera [--resolutions 640x480,1280x720] [--task N] [--quality medium]
        colour+depth frames per wall-clock second of the head camera.
    pr2-drake bench startup [--repeats 3]
        wall time of ``pr2-drake run --seconds 0.001`` in a fresh process: an upper bound on
        the time from invoking the command to its first simulated step.
    pr2-drake bench walking [...]
        the walking controller's benchmark (pr2_drake.bench.walking).
    pr2-drake bench perception [--views 100] [--qualities low,medium,high]
        the task-6 object detector on rendered head-camera views (pr2_drake.bench.perception).
    pr2-drake bench whole-body [...]
        the whole-body controller: hand reach, held force, real-time factor
        (pr2_drake.bench.whole_body).
    pr2-drake bench jumping [...]
        vertical jumps of the jump controller (pr2_drake.bench.jumping).
    pr2-drake bench stairs [--quick] [--repeats 5]
        up then down staircases per riser height: falls, time, real-time factor
        (pr2_drake.bench.stairs).
"""

from __future__ import annotations

import argparse
import cProfile
import math
import pstats
import statistics
import subprocess
import sys
import time


def _standing_diagram(task, seed: int = 0, camera=None):
    """The standing controller's episode of ``task``; returns (simulator, testbed)."""
    from pr2_drake.controllers.standing import StandingController
    from pr2_drake.episode import Episode, wire_system
    from pr2_drake.scenario import Scenario

    episode = Episode(Scenario(task=task, seed=seed, camera=camera, seconds=math.inf),
                      wire_system(StandingController()))
    episode.simulator.Initialize()
    return episode.simulator, episode.testbed


def bench_sim(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="pr2-drake bench sim")
    p.add_argument("--seconds", type=float, default=10.0)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--task", default=None)
    p.add_argument("--profile", action="store_true", help="also print the time split")
    a = p.parse_args(argv)
    rates = []
    for _ in range(a.repeats):
        simulator, _ = _standing_diagram(a.task)
        start = time.perf_counter()
        simulator.AdvanceTo(a.seconds)
        rates.append(a.seconds / (time.perf_counter() - start))
    where = f"task {a.task}" if a.task else "flat ground"
    print(f"standing controller on {where}, {a.seconds:g} s simulated, physics step 1 ms")
    print(f"  real-time factor: median {statistics.median(rates):.2f} "
          f"(runs: {', '.join(f'{r:.2f}' for r in rates)})")
    if a.profile:
        simulator, _ = _standing_diagram(a.task)
        prof = cProfile.Profile()
        prof.enable()
        simulator.AdvanceTo(min(a.seconds, 3.0))
        prof.disable()
        _print_split(prof)
    return 0


def _print_split(prof: cProfile.Profile) -> None:
    """Wall-time split: Python callbacks by module vs the rest (the C++ plant step)."""
    stats = pstats.Stats(prof)
    total = stats.total_tt
    by_file: dict[str, float] = {}
    for (filename, _, _), (_, _, tt, _, _) in stats.stats.items():
        key = filename.split("/pr2_drake/")[-1] if "/pr2_drake/" in filename else "other Python"
        if filename.startswith("~"):
            key = "Drake C++ (plant step, geometry, events)"
        by_file[key] = by_file.get(key, 0.0) + tt
    print("  time split (cProfile, own time):")
    for key, tt in sorted(by_file.items(), key=lambda kv: -kv[1])[:8]:
        print(f"    {100 * tt / total:5.1f} %  {key}")


def bench_camera(argv: list[str]) -> int:
    from pr2_drake.camera import CameraSettings

    p = argparse.ArgumentParser(prog="pr2-drake bench camera")
    p.add_argument("--resolutions", default="640x480,1280x720")
    p.add_argument("--task", default=None)
    p.add_argument("--quality", default="low", choices=("low", "medium", "high"))
    p.add_argument("--frames", type=int, default=30)
    a = p.parse_args(argv)
    where = f"task {a.task}" if a.task else "flat ground"
    print(f"head camera, colour + depth, {where}, quality {a.quality}")
    print(f"  {'resolution':<12}{'frames/s':>10}")
    for res in a.resolutions.split(","):
        w, h = (int(v) for v in res.lower().split("x"))
        cam = CameraSettings(enabled=True, width=w, height=h, fps=100.0, quality=a.quality)
        simulator, testbed = _standing_diagram(a.task, camera=cam)
        ctx = testbed.GetMyContextFromRoot(simulator.get_context())
        port = testbed.GetOutputPort("rgbd")
        port.Eval(ctx)  # warm up the renderer
        start = time.perf_counter()
        for k in range(a.frames):
            # One frame per step of 10 ms: the sensor renders once per new sample time.
            simulator.AdvanceTo((k + 1) * 0.01)
            frame = port.Eval(ctx)
        wall = time.perf_counter() - start
        physics = _physics_only(a.task, a.frames * 0.01)
        fps = a.frames / max(wall - physics, 1e-9)
        print(f"  {res:<12}{fps:>10.1f}   (rendering only; with physics {a.frames / wall:.1f})")
        assert frame.color.shape == (h, w, 3)
    return 0


def _physics_only(task, seconds: float) -> float:
    simulator, _ = _standing_diagram(task)
    start = time.perf_counter()
    simulator.AdvanceTo(seconds)
    return time.perf_counter() - start


def bench_startup(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="pr2-drake bench startup")
    p.add_argument("--repeats", type=int, default=3)
    a = p.parse_args(argv)
    times = []
    for _ in range(a.repeats):
        start = time.perf_counter()
        subprocess.run([sys.executable, "-m", "pr2_drake.cli", "run", "--seconds", "0.001",
                        "--quiet"], check=True, stdout=subprocess.DEVNULL)
        times.append(time.perf_counter() - start)
    print("`pr2-drake run --seconds 0.001` in a fresh process (import, build, 1 step, exit)")
    print(f"  wall time: median {statistics.median(times):.2f} s "
          f"(runs: {', '.join(f'{t:.2f}' for t in times)})")
    return 0


def _module_benchmark(module: str):
    """A benchmark whose ``main(argv)`` lives in ``pr2_drake.bench.<module>`` (imported late)."""

    def run(argv: list[str]) -> int:
        import importlib

        return importlib.import_module(f"pr2_drake.bench.{module}").main(argv)

    return run


BENCHMARKS = {"sim": bench_sim, "camera": bench_camera, "startup": bench_startup,
              "walking": _module_benchmark("walking"),
              "whole-body": _module_benchmark("whole_body"),
              "perception": _module_benchmark("perception"),
              "jumping": _module_benchmark("jumping"),
              "stairs": _module_benchmark("stairs"),
              "sandbox": _module_benchmark("sandbox")}
"""Every ``pr2-drake bench`` command by name; the CLI's choices come from here."""


def run_benchmark(what: str, argv: list[str]) -> int:
    if what == "all":
        for name in ("startup", "sim", "camera", "walking"):
            print(f"== {name}")
            code = BENCHMARKS[name]([])
            if code:
                return code
        return 0
    return BENCHMARKS[what](argv)

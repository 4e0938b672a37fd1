"""``pr2-drake bench``: speed benchmarks. Figures in docs come from these commands.

    pr2-drake bench sim [--seconds 10] [--repeats 3] [--task N] [--sleep on|off|both]
                        [--capture on|off|both] [--no-camera] [--profile]
        real-time factor and CPU seconds per simulated second of the standing robot in
        closed loop (median of repeats), with object sleeping on, off or both (alternating
        runs), the head camera capturing at every sample or never (``camera_capture`` False:
        only the initialization frame renders; what an agent that asks for no frame costs),
        and the split of wall time between the plant step and the Python blocks.
    pr2-drake bench camera [--resolutions paper|640x480,...] [--task 6,1] [--quality low,high]
        colour+depth renders per wall-clock second of the head camera, per task, preset and
        resolution, beside the paper's figures (``paper``: its eight resolutions).
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
    pr2-drake bench render [--sizes ...] [--samples 1,4,16,64] [--quick]
        the path tracer: seconds per frame and noise against samples (pr2_drake.bench.render).
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


def _standing_episode(task, seed: int = 0, camera=None, sleep: bool = True,
                      capture: bool = True):
    """The standing controller's episode of ``task``, initialized (object sleeping on or
    off; :mod:`pr2_drake.sleep`; ``capture`` False: the camera, if on, renders no sample)."""
    from pr2_drake.controllers.standing import StandingController
    from pr2_drake.episode import Episode, wire_system
    from pr2_drake.scenario import Scenario
    from pr2_drake.sleep import SleepSettings

    episode = Episode(Scenario(task=task, seed=seed, camera=camera, seconds=math.inf,
                               sleep=SleepSettings(enabled=sleep)),
                      wire_system(StandingController()))
    if not capture and episode.testbed.HasInputPort("camera_capture"):
        episode.testbed.GetInputPort("camera_capture").FixValue(episode.tb_context, False)
    episode.initialize()
    return episode


def _standing_diagram(task, seed: int = 0, camera=None):
    """The standing controller's episode of ``task``; returns (simulator, testbed)."""
    episode = _standing_episode(task, seed, camera)
    return episode.simulator, episode.testbed


def bench_sim(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="pr2-drake bench sim")
    p.add_argument("--seconds", type=float, default=10.0)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--task", default=None)
    p.add_argument("--sleep", choices=("on", "off", "both"), default="on",
                   help="object sleeping (pr2_drake.sleep); both: alternating runs of each")
    p.add_argument("--capture", choices=("on", "off", "both"), default="on",
                   help="head camera renders at every sample (on) or never (off: its "
                        "camera_capture input False); both: alternating runs of each")
    p.add_argument("--no-camera", action="store_true", help="head camera off (task 6)")
    p.add_argument("--profile", action="store_true", help="also print the time split")
    a = p.parse_args(argv)
    from pr2_drake.camera import CameraSettings

    camera = CameraSettings(enabled=False) if a.no_camera else None
    sleeps = ["on", "off"] if a.sleep == "both" else [a.sleep]
    captures = ["on", "off"] if a.capture == "both" else [a.capture]
    modes = [(s, c) for s in sleeps for c in captures]
    rates: dict[tuple, list[float]] = {m: [] for m in modes}
    cpus: dict[tuple, list[float]] = {m: [] for m in modes}
    for _ in range(a.repeats):
        for m in modes:  # alternating: a change of the machine's load hits both alike
            episode = _standing_episode(a.task, camera=camera, sleep=m[0] == "on",
                                        capture=m[1] == "on")
            start, cpu = time.perf_counter(), time.process_time()
            episode.advance_to(a.seconds)
            rates[m].append(a.seconds / (time.perf_counter() - start))
            cpus[m].append((time.process_time() - cpu) / a.seconds)
    where = f"task {a.task}" if a.task else "flat ground"
    cam = ", camera off" if a.no_camera else ""
    print(f"standing controller on {where}, {a.seconds:g} s simulated, physics step "
          f"{episode.testbed.config.time_step * 1e3:g} ms{cam}")
    for m in modes:
        label = f"sleeping {m[0]:<3}" + (f", capture {m[1]:<3}" if a.capture != "on" else "")
        print(f"  {label}  real-time factor: median {statistics.median(rates[m]):.2f} "
              f"(runs: {', '.join(f'{r:.2f}' for r in rates[m])}); CPU s per simulated s: "
              f"median {statistics.median(cpus[m]):.3f} "
              f"(runs: {', '.join(f'{c:.3f}' for c in cpus[m])})")
    if a.profile:
        episode = _standing_episode(a.task, camera=camera, sleep=modes[0][0] == "on",
                                    capture=modes[0][1] == "on")
        prof = cProfile.Profile()
        prof.enable()
        episode.advance_to(min(a.seconds, 3.0))
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


# The paper's head-camera rates (i9-13900KF + RTX 4090, Isaac Sim, physics step 1 ms) [frames/s].
PAPER_CAMERA_FPS = {"640x480": 17.363, "1024x768": 17.683, "1280x720": 17.361,
                    "1600x1200": 16.263, "1920x1080": 14.918, "2560x1440": 15.033,
                    "3440x1440": 13.973, "3840x2160": 13.697}


def _resolutions(text: str) -> list[tuple[int, int]]:
    """``paper`` (the paper's eight) or a comma list of WIDTHxHEIGHT."""
    names = list(PAPER_CAMERA_FPS) if text == "paper" else text.split(",")
    try:
        return [tuple(int(v) for v in r.lower().split("x")) for r in names]
    except ValueError:
        raise SystemExit(f"--resolutions: expected 'paper' or WIDTHxHEIGHT,..., got {text!r}")


def _render_rate(task, quality: str, sizes, frames: int, budget: float):
    """(colour + depth renders per wall-clock second, CPU seconds per render) of the head
    camera, one pair per size (CPU time: of every thread of this process, llvmpipe's too).

    The testbed of ``task`` is built once per quality (robot at its start); each frame is one
    ``RenderColorImage`` plus one ``RenderDepthImage`` of the head camera's renderer at the
    head camera's pose: what the RgbdSensor does per sample, without the physics. At most
    ``frames`` frames or ``budget`` [s] per size (after one warm-up frame)."""
    from pydrake.geometry import (ClippingRange, ColorRenderCamera, DepthRange,
                                  DepthRenderCamera, RenderCameraCore)
    from pydrake.math import RigidTransform
    from pydrake.systems.sensors import CameraInfo

    from pr2_drake.camera import RENDERER_NAME, CameraSettings

    cam = CameraSettings(enabled=True, width=64, height=48, quality=quality)
    simulator, testbed = _standing_diagram(task, camera=cam)
    sensor = testbed.GetSubsystemByName("head_camera")
    camera_sg = testbed.camera_scene_graph
    query = camera_sg.get_query_output_port().Eval(
        camera_sg.GetMyContextFromRoot(simulator.get_context()))
    parent, X_PB = sensor.default_parent_frame_id(), sensor.default_X_PB()
    rates = []
    for w, h in sizes:
        core = RenderCameraCore(RENDERER_NAME, CameraInfo(w, h, math.radians(cam.fov_y_deg)),
                                ClippingRange(0.5 * cam.z_near, 2 * cam.z_far),
                                RigidTransform())
        color = ColorRenderCamera(core, False)
        depth = DepthRenderCamera(core, DepthRange(cam.z_near, cam.z_far))

        def render():
            query.RenderColorImage(color, parent, X_PB)
            query.RenderDepthImage(depth, parent, X_PB)

        render()  # warm-up: buffers of this size, shadow map
        n, start, cpu = 0, time.perf_counter(), time.process_time()
        while n < frames and (n < 2 or time.perf_counter() - start < budget):
            render()
            n += 1
        rates.append((n / (time.perf_counter() - start), (time.process_time() - cpu) / n))
    return rates


def bench_camera(argv: list[str]) -> int:
    p = argparse.ArgumentParser(
        prog="pr2-drake bench camera",
        description="head-camera colour + depth renders per wall-clock second (no physics)")
    p.add_argument("--resolutions", default="640x480,1280x720",
                   help="'paper' (its eight, 640x480 to 3840x2160) or WIDTHxHEIGHT,...")
    p.add_argument("--task", default=None, help="task id, or a comma list (e.g. 6,1)")
    p.add_argument("--quality", default="low",
                   help="render preset, or a comma list: low,medium,high")
    p.add_argument("--frames", type=int, default=30, help="frames per case at most")
    p.add_argument("--budget", type=float, default=10.0,
                   help="[s] of rendering per case at most (at least 2 frames)")
    a = p.parse_args(argv)
    sizes = _resolutions(a.resolutions)
    tasks = a.task.split(",") if a.task else [None]
    qualities = a.quality.split(",")
    for q in qualities:
        if q not in ("low", "medium", "high"):
            raise SystemExit(f"--quality: expected low, medium or high, got {q!r}")
    print("head camera, colour + depth renders per second (RenderEngineVtk, no physics); "
          "CPU ms: CPU time per render, all threads (steadier than wall time on a shared "
          "machine)")
    head = (f"  {'task':<6}{'quality':<9}{'resolution':<12}{'frames/s':>9}{'Mpx/s':>8}"
            f"{'CPU ms':>8}{'paper':>8}")
    print(head)
    for task in tasks:
        for q in qualities:
            rates = _render_rate(task, q, sizes, a.frames, a.budget)
            for (w, h), (fps, cpu) in zip(sizes, rates):
                res = f"{w}x{h}"
                paper = PAPER_CAMERA_FPS.get(res)
                print(f"  {task or 'flat':<6}{q:<9}{res:<12}{fps:>9.1f}{fps * w * h / 1e6:>8.1f}"
                      f"{1e3 * cpu:>8.0f}{'' if paper is None else f'{paper:.1f}':>8}", flush=True)
    return 0


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
              "sandbox": _module_benchmark("sandbox"),
              "render": _module_benchmark("render")}
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

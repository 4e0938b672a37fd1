"""``pr2-drake bench sim``: real-time factor of the standing robot in closed loop.

    pr2-drake bench sim [--seconds 10] [--repeats 3] [--task N] [--sleep on|off|both]
                        [--capture on|off|both] [--no-camera] [--profile]

Real-time factor and CPU seconds per simulated second of the standing robot in closed loop
(median of repeats), with object sleeping on, off or both (alternating runs), the head camera
capturing at every sample or never (``camera_capture`` False: only the initialization frame
renders; what an agent that asks for no frame costs), and the split of wall time between the
plant step and the Python blocks.
"""

from __future__ import annotations

import argparse
import cProfile
import math
import pstats
import statistics
import time


def standing_episode(task, seed: int = 0, camera=None, sleep: bool = True,
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


def main(argv: list[str]) -> int:
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
            episode = standing_episode(a.task, camera=camera, sleep=m[0] == "on",
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
        episode = standing_episode(a.task, camera=camera, sleep=modes[0][0] == "on",
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

"""``pr2-drake bench``: every benchmark, one module each. Figures in docs come from these commands.

    pr2-drake bench sim          the standing robot in closed loop: real-time factor, CPU time
                                 per simulated second, object sleeping and camera capture on/off
    pr2-drake bench camera       head-camera colour + depth renders per second, per resolution
    pr2-drake bench startup      wall time from the command to its first simulated step
    pr2-drake bench scene-step   the plant step of each task scene, no Python in the loop
    pr2-drake bench walking      the walking controller: tracking, pushes, real-time factor
    pr2-drake bench whole-body   hand reach, held force, real-time factor
    pr2-drake bench jumping      vertical and forward jumps of the jump controller
    pr2-drake bench stairs       up then down staircases per riser height
    pr2-drake bench perception   the task-6 object detector on rendered head-camera views
    pr2-drake bench parser       the task-6 instruction parser's accuracy
    pr2-drake bench sandbox      what the competition's process boundary costs per tick
    pr2-drake bench fidelity     one episode per task at two physics steps: outcomes, contact
                                 force peaks, CoM and sole deviations
    pr2-drake bench speed        walking and every task's default agent: real-time factor of
                                 this code against a baseline commit, CPU time, the split
    pr2-drake bench render       the path tracer: seconds per frame and noise against samples
    pr2-drake bench learning     the learning envs: steps/s per level, reset time, SB3 PPO

Each module has ``main(argv) -> exit status`` and its options (``pr2-drake bench NAME
--help``). The rigs the benchmarks, tests and notebooks share are in
:mod:`pr2_drake.bench.rigs`; the figures are written down in docs/benchmarks.md.
"""

from __future__ import annotations

import importlib

#: Every ``pr2-drake bench`` command by name -> its module in this package; the CLI's choices
#: come from here. Modules are imported only when their command runs.
BENCHMARKS = {"sim": "sim", "camera": "camera", "startup": "startup",
              "scene-step": "scene_step", "walking": "walking", "whole-body": "whole_body",
              "jumping": "jumping", "stairs": "stairs", "perception": "perception",
              "parser": "parser", "sandbox": "sandbox", "render": "render",
              "learning": "learning", "speed": "speed", "fidelity": "fidelity"}
ALL = ("startup", "sim", "camera", "walking")  # ``pr2-drake bench all``


def run_benchmark(what: str, argv: list[str]) -> int:
    """Run benchmark ``what`` (a key of :data:`BENCHMARKS`, or "all") with options ``argv``."""
    if what == "all":
        for name in ALL:
            print(f"== {name}")
            code = run_benchmark(name, [])
            if code:
                return code
        return 0
    return importlib.import_module(f"pr2_drake.bench.{BENCHMARKS[what]}").main(argv)

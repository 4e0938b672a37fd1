"""One run of ``pr2-drake bench speed`` in a fresh process, of whichever ``pr2_drake`` the
import path gives: this code, or a baseline commit checked out elsewhere. Only the standard
library is imported at module level, and the run reaches the package through names every
layout since e4c1cc1 has (``Scenario``, ``run_episode``, ``WalkingSim``), so the same file
drives old trees too. :mod:`pr2_drake.bench.speed` runs it as::

    python -c 'import runpy, sys; sys.argv = ["w", *ARGS]; runpy.run_path(PATH, run_name="__main__")'

with the tree's root as working folder and ``PYTHONPATH``. ARGS: ``WORKLOAD [--seed N]
[--seconds S] [--profile]``; WORKLOAD is ``walking`` (flat ground, WalkingController at
0.3 m/s, arms in position mode: ``--seconds``, default 10) or a task id (its default agent's
episode, ``run_episode``, until it ends or ``--seconds``). It prints one line, ``SPEED`` and a
JSON object: ``sim_time`` [s], ``wall`` [s] and ``cpu`` [s] of the simulation loop (no build;
CPU time of every thread of the process), ``rtf`` (sim_time / wall), ``cpu_per_sim``,
``score``, ``max_score``, ``termination`` (tasks), and with ``--profile`` (cProfile: slower,
so not timed) ``split``: profiled seconds per simulated second by part (:data:`PARTS`).
``--callgrind`` (the worker runs under ``valgrind --tool=callgrind --instr-atstart=no``)
switches the instrumentation on for the simulation loop only (``callgrind_control``), so the
instruction count of the callgrind output is that of the loop.
"""

from __future__ import annotations

import argparse
import cProfile
import json
import os
import pstats
import subprocess
import time

#: The parts of the split, in print order.
PARTS = ("plant", "planner", "rows", "qp", "controller", "agent", "testbed", "camera", "other")
PART_NAMES = {
    "plant": "plant and Drake's C++ framework (AdvanceTo's own time)",
    "planner": "controller: gait/footstep/swing/jump planning",
    "rows": "controller: tracking rows (objectives, model Jacobians)",
    "qp": "controller: the QP (assembly and DAQP)",
    "controller": "controller: glue (LeafSystems, ports)",
    "agent": "agent (sequencers, perception)",
    "testbed": "testbed Python (actuation, grasp, sleep, referee, loop)",
    "camera": "camera (render and copy)",
    "other": "unattributed",
}
_PLANNER = ("planning/", "plan.py", "gait.py", "footsteps.py", "swing.py", "step_adjust.py",
            "com_plan.py", "step_over.py", "tread_steps.py", "jump_planner.py",
            "centroidal_mpc.py", "terrain_model.py", "walking_params.py", "jump_params.py")
_QP = ("tracking/qp.py", "wbqp.py")
_ROWS = ("tracking/", "tasks.py", "jump_tasks.py", "hand_force.py", "wb_model.py", "model.py",
         "frames.py", "posture.py")
_LOOP = ("episode.py", "drive.py", "env.py", "gym_env.py", "run.py", "bench/")


def _part_of_file(filename: str) -> str | None:
    """The part a Python source file belongs to ("loop": the episode driver), or None
    outside pr2_drake (numpy, pydrake's Python, builtins: they inherit from their callers)."""
    if "/pr2_drake/" not in filename:
        return None
    rel = filename.rsplit("/pr2_drake/", 1)[1]
    if rel.startswith("controllers/"):
        sub = rel[len("controllers/"):]
        for part, keys in (("planner", _PLANNER), ("qp", _QP), ("rows", _ROWS)):
            if any(sub.startswith(k) or sub == k for k in keys):
                return part
        return "controller"
    if rel.startswith("agents/"):
        return "agent"
    if rel == "camera.py":
        return "camera"
    if rel.startswith(_LOOP):
        return "loop"
    return "testbed"


def split_profile(stats: pstats.Stats) -> dict[str, float]:
    """Profiled own time [s] by part. A function outside pr2_drake takes the parts of its
    callers, weighted by the time spent through each call edge; C++ (builtin) calls made by
    the episode loop (``AdvanceTo``) are the plant."""
    raw = stats.stats  # func -> (cc, nc, tt, ct, callers{func: (cc, nc, tt, ct)})
    memo: dict = {}

    def weights(func, depth=0) -> dict[str, float]:
        if func in memo:
            return memo[func]
        part = _part_of_file(func[0])
        if part is not None:
            memo[func] = {"testbed" if part == "loop" else part: 1.0}
            return memo[func]
        memo[func] = {"other": 1.0}  # cycle guard
        callers = raw[func][4] if func in raw else {}
        field = 3 if sum(edge[3] for edge in callers.values()) > 0 else 1  # time, else calls
        total = sum(edge[field] for edge in callers.values())
        if total <= 0 or depth > 50:
            return memo[func]
        mix: dict[str, float] = {}
        builtin = func[0] == "~"
        for caller, edge in callers.items():
            share = edge[field] / total
            if builtin and _part_of_file(caller[0]) == "loop":
                sub = {"plant": 1.0}
            else:
                sub = weights(caller, depth + 1)
            for k, w in sub.items():
                mix[k] = mix.get(k, 0.0) + share * w
        memo[func] = mix
        return mix

    out = dict.fromkeys(PARTS, 0.0)
    for func, (_, _, tt, _, _) in raw.items():
        for part, w in weights(func).items():
            out[part] += tt * w
    return out


class _Clock:
    """Wall and CPU time of the simulation loop, and the profiler (if any) or callgrind's
    instrumentation (``callgrind``) running only inside it."""

    def __init__(self, prof: cProfile.Profile | None, callgrind: bool = False):
        self.prof, self.callgrind, self.marks = prof, callgrind, {}

    def _instrument(self, state: str) -> None:
        if self.callgrind:
            subprocess.run(["callgrind_control", "-i", state, str(os.getpid())], check=True,
                           capture_output=True)

    def start(self) -> None:
        self._instrument("on")
        self.marks["cpu0"], self.marks["wall0"] = time.process_time(), time.perf_counter()
        if self.prof is not None:
            self.prof.enable()

    def stop(self) -> None:
        if self.prof is not None:
            self.prof.disable()
        self.marks["cpu1"], self.marks["wall1"] = time.process_time(), time.perf_counter()
        self._instrument("off")

    def times(self) -> dict[str, float]:
        m = self.marks
        return dict(wall=m["wall1"] - m["wall0"], cpu=m["cpu1"] - m["cpu0"])


def _walking(seconds: float, clock: _Clock) -> dict:
    try:
        from pr2_drake.bench.rigs import WalkingSim
    except ImportError:  # a layout before bench/rigs.py
        from pr2_drake.bench.walking import WalkingSim
    sim = WalkingSim()
    sim.set_command(0.3, 0.0, 0.0)
    clock.start()
    sim.advance(seconds)
    clock.stop()
    return dict(sim_time=seconds, **clock.times())


def _episode(task: int, seed: int, seconds: float | None, clock: _Clock) -> dict:
    """The default agent's episode, timed from the loop's start to its end: the run module's
    ``Progress`` is made just before the loop and called with ``force`` just after it."""
    from pr2_drake.scenario import Scenario

    try:
        from pr2_drake import run as module
    except ImportError:  # a layout before pr2_drake/run.py
        from pr2_drake import episode as module

    class TimedProgress(module.Progress):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            clock.start()

        def __call__(self, t, status, force=False):
            if force:
                clock.stop()
            return super().__call__(t, status, force)

    module.Progress = TimedProgress
    report = module.run_episode(Scenario(task=task, seed=seed, seconds=seconds))
    return dict(sim_time=report["sim_time"], **clock.times(), score=report["score"],
                max_score=report["max_score"], termination=report["termination"])


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="speed_worker")
    p.add_argument("workload")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--seconds", type=float, default=None)
    p.add_argument("--profile", action="store_true")
    p.add_argument("--callgrind", action="store_true")
    a = p.parse_args(argv)
    prof = cProfile.Profile() if a.profile else None
    clock = _Clock(prof, a.callgrind)
    if a.workload == "walking":
        result = _walking(a.seconds or 10.0, clock)
    else:
        result = _episode(int(a.workload), a.seed, a.seconds, clock)
    if prof is not None:
        parts = split_profile(pstats.Stats(prof))
        result["split"] = {k: v / result["sim_time"] for k, v in parts.items()}
    result["rtf"] = result["sim_time"] / result["wall"]
    result["cpu_per_sim"] = result["cpu"] / result["sim_time"]
    print("SPEED " + json.dumps(result), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

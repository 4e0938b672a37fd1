"""``pr2-drake bench speed``: closed-loop speed of this code against a baseline commit.

    pr2-drake bench speed [--baseline REF | --no-baseline] [--repeats 3]
                          [--workloads walking,1,2,3,4,5,6] [--seed 0] [--seconds S]
                          [--split] [--instructions] [--json PATH]

Workloads: ``walking`` (flat ground, the WalkingController at 0.3 m/s with the arm posture,
10 s, or ``--seconds``) and task ids (the task's default agent, ``run_episode`` on
``--seed``, until the episode ends or ``--seconds``). Each workload runs ``--repeats`` times
for this code and for the baseline, interleaved (baseline first in odd rounds, this code first
in even ones) and each run in a fresh process (:mod:`pr2_drake.bench.speed_worker`). The
baseline (default :data:`BASELINE_REF`, the code before issue 27) is ``git archive``\\ d from
this checkout into a temporary folder and run with that folder as working folder and
``PYTHONPATH``, with the same interpreter and packages; it needs only a clone with that
commit in its history. Each side's process starts as that tree's ``pr2-drake`` starts: with
the allocator setting of :mod:`pr2_drake.malloc_tuning` where the tree has that module, without
it where it does not.

Printed per workload: the real-time factor (simulated time over the wall time of the
simulation loop; building excluded), median and every run, for this code and the baseline,
their ratio, the CPU seconds per simulated second (every thread of the process), the episode's
outcome (score, termination, simulated time) of each side, and the load average
(``/proc/loadavg``, 1 min) before and after the workload's runs. ``--split`` adds one
profiled run per side and workload (cProfile, not timed) and prints the profiled seconds per
simulated second of each part: plant (AdvanceTo's own C++ time: the plant step, contact,
Drake's framework), controller planner, tracking rows, QP, controller glue, agent, testbed
Python (actuation, grasp, sleep, referee, loop), camera (:data:`speed_worker.PARTS`);
cProfile inflates the Python parts, so compare splits with splits. ``--json`` writes every run.

``--instructions`` counts instead of timing: each side runs once per workload under valgrind's
callgrind, instrumented only inside the simulation loop, and the table gives the instructions
per simulated second and their ratio (baseline over this code). The count does not change
with the machine's load, so it compares two versions on a shared or noisy machine where
wall-clock ratios move by tens of percent between rounds; it does not weigh memory stalls
(a cache miss counts as one instruction), so state speed-ups in time where the machine allows.
Callgrind runs the code some 50 times slower: the first ``--seconds`` (default
:data:`INSTRUCTION_SECONDS`) of each workload. Needs ``valgrind`` (Debian package).

The interface (options, printed columns, JSON keys ``runs``, ``summary``) is what other
branches report their figures with; keep it stable.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from pr2_drake import malloc_tuning
from pr2_drake.bench import speed_worker
from pr2_drake.bench.speed_worker import PART_NAMES, PARTS

#: The code before issue 27's speed work: the default "before".
BASELINE_REF = "e4c1cc1"
WORKLOADS = ("walking", "1", "2", "3", "4", "5", "6")
#: [s] simulated per workload with ``--instructions`` unless ``--seconds`` says otherwise
#: (callgrind runs the code some 50 times slower).
INSTRUCTION_SECONDS = 4.0
ROOT = Path(__file__).resolve().parents[2]


class BenchError(Exception):
    """A bad option or a baseline that cannot be checked out (one line)."""


def checkout(ref: str, into: Path) -> None:
    """Extract commit ``ref`` of this repository into the folder ``into``."""
    try:
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", ref],
                                 capture_output=True, check=True).stdout
    except FileNotFoundError:
        raise BenchError("git is not installed: --baseline needs it") from None
    except subprocess.CalledProcessError as e:
        msg = " ".join(e.stderr.decode(errors="replace").split()) or f"exit {e.returncode}"
        raise BenchError(f"--baseline {ref}: cannot check it out of {ROOT}: {msg}") from None
    subprocess.run(["tar", "-x", "-C", str(into)], input=archive, check=True)


def run_worker(root: Path, workload: str, seed: int, seconds: float | None,
               profile: bool = False, instructions: bool = False) -> dict:
    """One fresh process running ``workload`` on the package under ``root``; with
    ``instructions``, under callgrind, adding ``instructions`` (of the simulation loop)."""
    args = [workload, "--seed", str(seed)]
    if seconds is not None:
        args += ["--seconds", repr(seconds)]
    if profile:
        args.append("--profile")
    code = ("import runpy, sys; sys.argv = ['speed_worker', *sys.argv[1:]]; "
            f"runpy.run_path({str(Path(speed_worker.__file__))!r}, run_name='__main__')")
    env = dict(malloc_tuning.plain_env(os.environ), PYTHONPATH=str(root))
    if (root / "pr2_drake" / "malloc_tuning.py").exists():  # started as that tree's CLI starts
        env = malloc_tuning.tuned_env(env)
    cmd = [sys.executable, "-c", code, *args]
    with tempfile.TemporaryDirectory(prefix="pr2_speed_cg_") as tmp:
        counts = Path(tmp) / "callgrind.out"
        if instructions:
            cmd = ["valgrind", "--tool=callgrind", "--instr-atstart=no",
                   f"--callgrind-out-file={counts}", *cmd, "--callgrind"]
        out = subprocess.run(cmd, cwd=root, env=env, capture_output=True, text=True)
        lines = [ln for ln in out.stdout.splitlines() if ln.startswith("SPEED ")]
        if out.returncode or not lines:
            tail = " | ".join(out.stderr.strip().splitlines()[-3:])
            raise BenchError(f"{workload} under {root} failed (exit {out.returncode}): {tail}")
        result = json.loads(lines[-1][len("SPEED "):])
        if instructions:
            result["instructions"] = callgrind_total(counts)
    return result


def callgrind_total(path: Path) -> int:
    """The instruction count (Ir) of a callgrind output file: its ``totals:`` line (with
    the instrumentation switched on and off, ``summary:`` counts only the last span)."""
    try:
        for line in path.read_text(errors="replace").splitlines():
            if line.startswith("totals:"):
                return int(line.split()[1])
    except (OSError, ValueError, IndexError):
        pass
    raise BenchError(f"no instruction count in {path}")


def check_valgrind() -> None:
    """BenchError unless valgrind and callgrind_control are on the PATH."""
    missing = [t for t in ("valgrind", "callgrind_control") if shutil.which(t) is None]
    if missing:
        raise BenchError(f"--instructions needs {' and '.join(missing)} (Debian: apt-get "
                         "install valgrind)")


def load1() -> float:
    """The 1-minute load average."""
    try:
        return float(Path("/proc/loadavg").read_text().split()[0])
    except OSError:
        return float("nan")


def describe_here() -> str:
    try:
        out = subprocess.run(["git", "-C", str(ROOT), "describe", "--always", "--dirty"],
                             capture_output=True, text=True, check=True)
        return out.stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "this code"


def machine() -> str:
    model = "unknown CPU"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{model}, {os.cpu_count()} cores"


def measure(sides: dict[str, Path], workloads: list[str], a) -> dict:
    """Every timed run: {workload: {side: [result, ...]}}, plus load averages."""
    runs = {w: {s: [] for s in sides} for w in workloads}
    loads = {w: [] for w in workloads}
    names = list(sides)
    for r in range(a.repeats):
        order = names if r % 2 == 0 else names[::-1]
        for w in workloads:
            loads[w].append(load1())
            for side in order:
                runs[w][side].append(run_worker(sides[side], w, a.seed, a.seconds))
            loads[w].append(load1())
            print(f"  round {r + 1}/{a.repeats} {w}: " + ", ".join(
                f"{s} {runs[w][s][-1]['rtf']:.2f}" for s in order), flush=True)
    return dict(runs=runs, loads=loads)


def measure_instructions(sides: dict[str, Path], workloads: list[str], a) -> dict:
    """One run per side and workload under callgrind: {workload: {side: result}}."""
    out = {}
    for w in workloads:
        out[w] = {}
        for side, root in sides.items():
            out[w][side] = run_worker(root, w, a.seed, a.seconds, instructions=True)
            r = out[w][side]
            print(f"  {w}: {side} {r['instructions'] / r['sim_time'] / 1e9:.3f} G "
                  f"instructions per simulated s", flush=True)
    return out


def print_instructions(runs: dict, sides: list[str], a) -> dict:
    """The table of instruction counts per simulated second; returns the summary."""
    two = len(sides) == 2
    print(f"{'workload':18s} " + " ".join(f"{s + ' [G/sim s]':>22s}" for s in sides)
          + ("   ratio" if two else "") + "   outcome " + " | ".join(sides))
    summary = {}
    for w, by_side in runs.items():
        per = {s: by_side[s]["instructions"] / by_side[s]["sim_time"] for s in sides}
        row = {s: dict(instructions_per_sim=per[s], outcome=_outcome(by_side[s]))
               for s in sides}
        line = f"{_label(w, a):18s} " + " ".join(f"{per[s] / 1e9:22.3f}" for s in sides)
        if two:
            row["ratio"] = per[sides[1]] / per[sides[0]]
            line += f"  {row['ratio']:5.2f}x"
        print(line + "   " + " | ".join(row[s]["outcome"] for s in sides))
        summary[w] = row
    return summary


def summarize(runs: dict, loads: dict, sides: list[str]) -> dict:
    out = {}
    for w, by_side in runs.items():
        row = {"load": [min(loads[w]), max(loads[w])]}
        for s in sides:
            rs = by_side[s]
            row[s] = dict(rtf=statistics.median(r["rtf"] for r in rs),
                          cpu_per_sim=statistics.median(r["cpu_per_sim"] for r in rs),
                          outcome=_outcome(rs[0]))
        if len(sides) == 2:
            row["ratio"] = row[sides[0]]["rtf"] / row[sides[1]]["rtf"]
        out[w] = row
    return out


def _outcome(r: dict) -> str:
    if "score" not in r:
        return f"{r['sim_time']:g} s"
    return f"{r['score']:g}/{r['max_score']:g} {r['termination']} {r['sim_time']:.2f} s"


def _label(w: str, a) -> str:
    return "walking 0.3 m/s" if w == "walking" else f"task {w} seed {a.seed}"


def print_table(summary: dict, runs: dict, sides: list[str], a) -> None:
    two = len(sides) == 2
    print(f"{'workload':18s} " + " ".join(f"{s + ' RTF (runs)':>30s}" for s in sides)
          + ("   ratio" if two else "") + "   CPU s/sim s " + " / ".join(sides)
          + "   load 1 min")
    for w, row in summary.items():
        cells = []
        for s in sides:
            each = ", ".join(f"{r['rtf']:.2f}" for r in runs[w][s])
            cells.append(f"{row[s]['rtf']:6.2f} ({each})".rjust(30))
        cpu = " / ".join(f"{row[s]['cpu_per_sim']:.3f}" for s in sides)
        ratio = f"  {row['ratio']:5.2f}x" if two else ""
        print(f"{_label(w, a):18s} " + " ".join(cells) + ratio + f"   {cpu:>20s}"
              f"   {row['load'][0]:.2f}-{row['load'][1]:.2f}")
    print("outcomes: " + "; ".join(
        f"{w}: " + " | ".join(f"{s} {row[s]['outcome']}" for s in sides)
        for w, row in summary.items()))


def print_split(splits: dict, sides: list[str], a) -> None:
    print("split (cProfile, one run per side, not timed): profiled s per simulated s")
    for p in PARTS:
        print(f"  {p:10s} {PART_NAMES[p]}")
    print(f"  {'workload':18s} {'side':>12s} " + " ".join(f"{p:>10s}" for p in PARTS)
          + f" {'total':>8s}")
    for w, by_side in splits.items():
        for s in sides:
            sp = by_side[s]
            print(f"  {_label(w, a):18s} {s:>12s} " + " ".join(f"{sp[p]:10.3f}" for p in PARTS)
                  + f" {sum(sp.values()):8.3f}")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="pr2-drake bench speed", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--baseline", default=BASELINE_REF,
                   help=f"git ref of the 'before' code (default {BASELINE_REF})")
    p.add_argument("--no-baseline", action="store_true", help="time this code only")
    p.add_argument("--repeats", type=int, default=3, help="runs per side for the median")
    p.add_argument("--workloads", default=",".join(WORKLOADS),
                   help="comma list of 'walking' and task ids (default: all)")
    p.add_argument("--seed", type=int, default=0, help="the tasks' seed (default 0)")
    p.add_argument("--seconds", type=float, default=None,
                   help="simulated seconds (default: walking 10, tasks until they end)")
    p.add_argument("--split", action="store_true", help="add the profiled time split")
    p.add_argument("--instructions", action="store_true",
                   help="count instructions under callgrind instead of timing (one run per "
                        f"side; --seconds default {INSTRUCTION_SECONDS:g}): the same on a busy "
                        "machine")
    p.add_argument("--json", default=None, help="write every run and the summary here")
    a = p.parse_args(argv)
    try:
        return _run(a)
    except BenchError as e:
        print(f"pr2-drake: error: {e}", file=sys.stderr)
        return 2


def _run(a) -> int:
    workloads = [w.strip() for w in a.workloads.split(",") if w.strip()]
    bad = [w for w in workloads if w not in WORKLOADS]
    if bad or not workloads:
        raise BenchError(f"--workloads: unknown {bad or a.workloads!r}; choose from "
                         f"{', '.join(WORKLOADS)}")
    if a.repeats < 1:
        raise BenchError(f"--repeats must be at least 1, got {a.repeats}")
    if a.seconds is not None and not a.seconds > 0:
        raise BenchError(f"--seconds must be positive, got {a.seconds}")
    if a.instructions:
        check_valgrind()
        if a.seconds is None:
            a.seconds = INSTRUCTION_SECONDS
    tmp = None if a.no_baseline else Path(tempfile.mkdtemp(prefix="pr2_speed_baseline_"))
    try:
        sides = {"this": ROOT}
        if tmp is not None:
            checkout(a.baseline, tmp)
            sides[a.baseline] = tmp
        names = list(sides)
        if a.instructions:
            print(f"bench speed --instructions: this code ({describe_here()}, {ROOT})"
                  + (f" against {a.baseline}" if tmp is not None else "")
                  + f"; the first {a.seconds:g} s simulated, under callgrind; {machine()}",
                  flush=True)
            runs = measure_instructions(sides, workloads, a)
            summary = print_instructions(runs, names, a)
            if a.json:
                Path(a.json).write_text(json.dumps(dict(sides=names, runs=runs,
                                                        summary=summary), indent=1))
            return 0
        print(f"bench speed: this code ({describe_here()}, {ROOT})"
              + (f" against {a.baseline}" if tmp is not None else "")
              + f"; {a.repeats} run(s) each, interleaved, fresh processes; {machine()}",
              flush=True)
        m = measure(sides, workloads, a)
        summary = summarize(m["runs"], m["loads"], names)
        print_table(summary, m["runs"], names, a)
        splits = None
        if a.split:
            splits = {w: {s: run_worker(sides[s], w, a.seed, a.seconds, profile=True)["split"]
                          for s in names} for w in workloads}
            print_split(splits, names, a)
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
    if a.json:
        Path(a.json).write_text(json.dumps(dict(sides=names, runs=m["runs"], loads=m["loads"],
                                                summary=summary, split=splits), indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""``pr2-drake bench startup``: wall time from the command to its first simulated step.

    pr2-drake bench startup [--repeats 3]

The wall time of ``pr2-drake run --seconds 0.001`` in a fresh process: an upper bound on the
time from invoking the command to its first simulated step.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time


def main(argv: list[str]) -> int:
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

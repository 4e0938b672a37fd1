"""Learning benchmark: env steps per second, reset time, SB3 PPO steps per second.

    pr2-drake bench learning [--tasks 1,3,6] [--seconds 2] [--resets 5] [--baseline REF]
                             [--no-baseline] [--no-sb3]

Rows, for each task of ``--tasks``:

- env steps/s, joint level (100 Hz, the zero action: the mid-range pose in position mode; the
  old env: zero leg torques, reset, untimed, when it falls) and command level (10 Hz, the
  zero command: stand), over ``--seconds`` of simulated time after a reset: in one process,
  and over 2 processes (``gymnasium.vector.AsyncVectorEnv``, the figure counts both envs'
  steps; vector envs reset themselves when an episode ends);
- reset to a new seed [s]: the mean of ``--resets`` resets, each to an unseen seed, in place
  (the built diagram reused: tasks 1-5) and rebuilding (``reuse=False``);
- SB3 PPO steps/s (stable-baselines3 installed): ``PPO.learn`` over 256 steps of the slope's
  command level (2 updates of 128 steps), against the env's own steps/s.

``--baseline`` (a git ref, default the last commit before this benchmark's code: the joint-level
``Pr2GymEnv`` of ``pr2_drake/gym_env.py``, leg torques at 10 ms) runs the rows the old code had
(joint level in 1 and 2 processes, reset to a new seed, PPO steps/s) in a fresh process on
an extracted copy, interleaved with this code's. Timings on a shared machine are noisy: the
load average is printed with each.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

BASELINE_REF = "e4c1cc1"

# Run in a fresh process, on this code or the baseline's (PYTHONPATH). Prints one JSON line.
_SNIPPET = r"""
import json, sys, time
import numpy as np
import gymnasium as gym
what, task, seconds, resets = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4])
old = what.startswith("old")
def make(level, **kw):
    if old:
        from pr2_drake.gym_env import Pr2GymEnv
        return Pr2GymEnv(task=task, control_dt=0.01, time_limit=1e9)
    import pr2_drake
    from pr2_drake.learning.ids import env_id
    from pr2_drake.tasks import task_entry
    return gym.make(env_id(task_entry(task).name, level), **kw).unwrapped
def steps_per_s(env, dt):
    env.reset(seed=1)
    action = np.zeros(env.action_space.shape, np.float32)
    n = int(round(seconds / dt)); spent = 0.0
    for _ in range(n):  # (the old env's zero torques fall: reset, not timed)
        t = time.perf_counter(); _, _, term, trunc, _ = env.step(action)
        spent += time.perf_counter() - t
        if term or trunc:
            env.reset(seed=1)
    return n / spent
out = {}
level = what.split(":")[1]
dt = 0.01 if level == "joint" else 0.1
if what.endswith("steps1"):
    out["value"] = steps_per_s(make(level), dt)
elif what.endswith("steps2"):
    envs = gym.vector.AsyncVectorEnv([lambda: make(level)] * 2)
    envs.reset(seed=[1, 2])
    action = np.zeros(envs.action_space.shape, np.float32)
    n = int(round(seconds / dt)); t = time.perf_counter()
    for _ in range(n):
        envs.step(action)
    out["value"] = 2 * n / (time.perf_counter() - t)
    envs.close()
elif what.endswith("reset") or what.endswith("rebuild"):
    env = make(level) if old else make(level, reuse=not what.endswith("rebuild"))
    env.reset(seed=1)
    times = []
    for k in range(resets):
        t = time.perf_counter(); env.reset(seed=1000 + k); times.append(time.perf_counter() - t)
    out["value"] = float(np.mean(times))
elif what.endswith("sb3"):
    from stable_baselines3 import PPO
    env = make(level)
    model = PPO("MlpPolicy", env if old else gym.wrappers.FlattenObservation(env),
                n_steps=128, batch_size=64, n_epochs=4, device="cpu", seed=0)
    t = time.perf_counter(); model.learn(total_timesteps=256)
    out["value"] = 256 / (time.perf_counter() - t)
print("RESULT " + json.dumps(out))
"""


def _run(root: Path, what: str, task: int, seconds: float, resets: int) -> float | None:
    env = dict(os.environ, PYTHONPATH=str(root))
    proc = subprocess.run([sys.executable, "-c", _SNIPPET, what, str(task), str(seconds),
                           str(resets)], cwd=root, env=env, capture_output=True, text=True)
    lines = [x for x in proc.stdout.splitlines() if x.startswith("RESULT ")]
    if proc.returncode or not lines:
        print(f"    ({what} task {task} failed: {proc.stderr.strip().splitlines()[-1:]})")
        return None
    return json.loads(lines[-1][7:])["value"]


def _load() -> str:
    return open("/proc/loadavg").read().split()[0] if Path("/proc/loadavg").exists() else "?"


def _row(label: str, new, old=None, unit: str = "") -> None:
    fmt = (lambda v: "-" if v is None else f"{v:.3g}")
    ratio = f"  x{new / old:.2f}" if new and old else ""
    print(f"  {label:<44} {fmt(new):>8} {unit:<8} before {fmt(old):>8}{ratio}   "
          f"(load {_load()})", flush=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="pr2-drake bench learning", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--tasks", default="1,3,6", help="task ids (default 1,3,6)")
    parser.add_argument("--seconds", type=float, default=2.0,
                        help="simulated seconds per steps/s figure")
    parser.add_argument("--resets", type=int, default=5, help="resets per reset figure")
    parser.add_argument("--baseline", default=BASELINE_REF,
                        help=f"git ref of the 'before' code (default {BASELINE_REF})")
    parser.add_argument("--no-baseline", action="store_true", help="skip the 'before' runs")
    parser.add_argument("--no-sb3", action="store_true", help="skip the PPO row")
    args = parser.parse_args(argv)
    here = Path(__file__).resolve().parents[2]
    old_root = None
    if not args.no_baseline:
        old_root = Path(tempfile.mkdtemp(prefix="pr2_baseline_"))
        archive = subprocess.run(["git", "-C", str(here), "archive", args.baseline],
                                 capture_output=True, check=True).stdout
        subprocess.run(["tar", "-x", "-C", str(old_root)], input=archive, check=True)
    try:
        for task in (int(t) for t in args.tasks.split(",")):
            print(f"task {task}")
            for level, unit in (("joint", "steps/s"), ("command", "steps/s")):
                for procs in (1, 2):
                    new = _run(here, f"new:{level}:steps{procs}", task, args.seconds, 0)
                    old = (_run(old_root, f"old:{level}:steps{procs}", task, args.seconds, 0)
                           if old_root and level == "joint" else None)
                    _row(f"{level} level, {procs} process{'es' if procs > 1 else ''}", new,
                         old, unit)
            new = _run(here, "new:command:reset", task, 0, args.resets)
            old = (_run(old_root, "old:joint:reset", task, 0, args.resets)
                   if old_root else None)
            _row("reset to a new seed (in place where it can)", new, old, "s")
            _row("reset to a new seed, rebuilding",
                 _run(here, "new:command:rebuild", task, 0, args.resets), None, "s")
        if not args.no_sb3:
            try:
                import stable_baselines3  # noqa: F401
            except ImportError:
                print("SB3 PPO: stable-baselines3 is not installed (pip install -e '.[rl]')")
                return 0
            print("SB3 PPO, 256 steps (task 4 command level; before: task 4 joint level)")
            new = _run(here, "new:command:sb3", 4, 0, 0)
            old = _run(old_root, "old:joint:sb3", 4, 0, 0) if old_root else None
            _row("PPO steps/s", new, old, "steps/s")
            _row("PPO steps/s, joint level", _run(here, "new:joint:sb3", 4, 0, 0), old,
                 "steps/s")
    finally:
        if old_root is not None:
            shutil.rmtree(old_root, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""The launcher of an original solver folder that has no ``task_launcher.py`` of its own.

    python -m pr2.launcher FOLDER N

It does what the original's launcher did: builds ``pr2.env.Env(task_num=N)``, imports
``TaskSolver`` from ``FOLDER/task_N_solver/task_solver.py`` as a package module (so that the
solver's relative files and imports work), resets, then steps once per physics step, starting
with the empty action, until the episode ends, and prints "Task passed" or "Task failed".
The seed is ``pr2-drake pr2-launch --seed`` (default 0).
"""

from __future__ import annotations

import importlib
import sys

import pr2
from pr2.env import Env


def play(env: Env, solver) -> bool | None:
    """Step ``env`` with ``solver``'s actions until the episode ends (its success) or the
    run is stopped (None)."""
    action: dict = {}  # the first step only observes
    while not pr2.sim.is_stopped():
        if pr2.sim.is_playing():
            done, success, obs = env.step(action)
            if done:
                return success
            action = solver.next_action(obs)
        else:
            pr2.sim.render()
    return None


def run(folder: str, task: int) -> None:
    sys.path.insert(0, folder)
    env = Env(task_num=task, seed=0)
    solver = importlib.import_module(f"task_{task}_solver.task_solver").TaskSolver()
    env.reset()
    success = play(env, solver)
    if success is not None:
        print("Task passed" if success else "Task failed", flush=True)
    pr2.shutdown()


if __name__ == "__main__":
    if len(sys.argv) != 3 or not sys.argv[2].isdigit():
        sys.exit("usage: python -m pr2.launcher FOLDER N")
    run(sys.argv[1], int(sys.argv[2]))

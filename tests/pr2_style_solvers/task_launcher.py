"""A launcher in the original PR2 platform's shape (tests/test_pr2_compat.py runs it through
``pr2-drake pr2-launch``): build the environment, import the task's solver, reset, then step
once per physics step until the episode ends."""

import importlib
import sys

import pr2  # noqa: I001  (first, as in the original's launchers)
from pr2.env import Env

SEEDS = {1: 3, 5: 4}


def main(task: int) -> None:
    env = Env(task_num=task, seed=SEEDS[task])
    solver = importlib.import_module(f"task_{task}_solver.task_solver").TaskSolver()
    env.reset()
    action = {}  # the first step applies no command: it only observes
    while not pr2.sim.is_stopped():
        if not pr2.sim.is_playing():
            pr2.sim.render()
            continue
        done, success, obs = env.step(action)
        if done:
            print("Task passed" if success else "Task failed")
            break
        action = solver.next_action(obs)
    pr2.shutdown()


if __name__ == "__main__":
    main(int(sys.argv[1]))

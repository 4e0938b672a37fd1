"""Every reference agent class earns its task's first rubric item under randomised physics.

One episode per agent class on a fixed seed (per task) with ``randomize.enabled=true`` (every kind at its
default range: friction, masses, motors, joints, objects, latency, sensor noise, pushes), cut
a little after the time the first item takes at nominal physics. The full evaluation over
seeds 0..19 is a benchmark (``pr2-drake eval --task N --seeds 0:20 --set
randomize.enabled=true``, docs/benchmarks.md), not a test.
"""

from __future__ import annotations

import pytest

from pr2_drake.run import run_episode
from pr2_drake.scenario import load_scenario

# task: (agent class, seed, its first rubric item, simulated seconds to run). Each seed is one
# whose whole randomised episode earns full marks (docs/benchmarks.md, "Randomised physics"):
# the test guards that the agent class still copes with that seed's physics.
FIRST_ITEMS = {
    1: ("RockyRoadAgent", 1, "task_region", 6.0),
    2: ("ValveAgent", 0, "task_region", 6.0),
    3: ("MovingBarAgent", 0, "jump_over", 5.0),
    4: ("SlopeAgent", 0, "task_region", 7.0),
    5: ("StepsButtonAgent", 3, "onto_step", 8.0),
    6: ("ObjectSearchAgent", 7, "pick_region", 26.0),
}


@pytest.mark.parametrize("task", sorted(FIRST_ITEMS))
def test_first_rubric_item_under_randomised_physics(task):
    agent, seed, item, seconds = FIRST_ITEMS[task]
    scenario = load_scenario(None, [f"task={task}", f"seed={seed}", f"seconds={seconds}",
                                    "randomize.enabled=true"])
    report = run_episode(scenario)
    assert {"friction", "latency", "noise", "pushes"} <= set(report["physics"])  # randomised
    assert agent in report["agent"], report["agent"]
    earned = {i["item"] for i in report["items"] if i["points"] > 0}
    assert item in earned, (report["termination"], report["items"])
    assert report["termination"] in ("timeout", "completed"), report["termination"]  # no fall

"""Test helper: a task-6 episode with the full ObjectSearchAgent, the robot started before
the desk on seed 0 (the walk from the study's door skipped)."""

from __future__ import annotations

import math


def desk_episode(seconds: float):
    """(episode, agent): task 6, seed 0 (the book on the desk), ``seconds`` long, the robot
    at (2.0, 2.0) facing the desk."""
    from pr2_drake.agents.search.agent import ObjectSearchAgent
    from pr2_drake.episode import Episode, wire_system
    from pr2_drake.scenario import Scenario
    from pr2_drake.scene import StartPose
    from pr2_drake.tasks import task_entry

    held = {}

    def wire(b, tb):
        held["agent"] = ObjectSearchAgent(dict(tb.scene.priors), **task_entry(6).agent_params)
        return wire_system(held["agent"])(b, tb)

    ep = Episode(Scenario(task=6, seed=0, seconds=seconds,
                          start=StartPose(2.0, 2.0, math.pi / 2)), wire)
    return ep, held["agent"]

"""Test helper: a task-6 episode with the full ObjectSearchAgent, the robot started before
the desk on seed 0 (the walk from the study's door skipped)."""

from __future__ import annotations

import math


def desk_episode(seconds: float, params: str | None = None):
    """(episode, agent): task 6, seed 0 (the book on the desk), ``seconds`` long, the robot
    at (2.0, 2.0) facing the desk; ``params``: the agent's parameter file instead of its
    registry row's (e.g. a short scan)."""
    from pr2_drake.agents.search.agent import ObjectSearchAgent
    from pr2_drake.episode import Episode, wire_system
    from pr2_drake.scenario import Scenario
    from pr2_drake.scene import StartPose
    from pr2_drake.tasks import task_entry

    held = {}
    kwargs = dict(task_entry(6).agent_params)
    if params is not None:
        kwargs["params"] = params

    def wire(b, tb):
        held["agent"] = ObjectSearchAgent(dict(tb.scene.priors), **kwargs)
        return wire_system(held["agent"])(b, tb)

    ep = Episode(Scenario(task=6, seed=0, seconds=seconds,
                          start=StartPose(2.0, 2.0, math.pi / 2)), wire)
    return ep, held["agent"]


def scene_map(scene: dict, resolution: float = 0.05):
    """A :class:`HeightMap` of a task-6 scene block as if the camera had seen all of it: the
    floor free, walls, tables and decor occupied, the tables' tops as surfaces."""
    import numpy as np

    from pr2_drake.agents.search.mapping import HeightMap
    from pr2_drake.agents.search.navigation import house_obstacles

    lo, hi = scene.get("arena", {}).get("min", (-4.0, -4.0)), scene.get(
        "arena", {}).get("max", (4.0, 4.0))
    m = HeightMap.empty(lo, hi, resolution).with_free_disc((0.0, 0.0), 20.0)
    heights = {k: float(f["height"]) for k, f in scene["furniture"].items()}
    heights.update({d["name"]: float(d["size"][2]) for d in scene.get("decor", [])})
    for box in house_obstacles(scene):
        m = m.with_box(np.asarray(box.center), np.asarray(box.size), heights.get(box.name, 1.4))
    return m

"""Task 1 - uneven terrain walking: cross a rocky road into the green finish circle.

Scene (``tasks/1_rocky_road.yaml``): flat ground, then a road 4.96 m long along +x made of
``cells[0] x cells[1]`` stones (convex boxes of random height and tilt) and, after it, the finish
circle. The road is generated from ``scene.road.seed`` in the YAML, not from the episode seed, so
every episode of a release walks the same road; the episode seed draws only the start pose (start
region, heading nominal +- 30 deg).

Rubric (points in the YAML), judged on the horizontal position of the base ``base_link``:
- ``task_region`` (+5): the base is inside the task region (the road's footprint);
- ``half_road`` (+5): the base is inside the task region at or beyond the halfway line
  (x >= ``scene.halfway_x``);
- ``finish`` (+5): the base is within 0.4 m (horizontal) of the goal centre.
The episode is complete when all three are earned. Figures not in TASKS.md (road width, stone
grid, heights 0.5-2.5 cm, tilts up to 3 deg, regions, arena) are our choices and live in the YAML.

Prior: ``goal_center`` [x, y, z] (world, m).

Scene variation (``scene.variation``): the road's seed drawn from the episode seed (YAML
``scene.variation``), so every episode walks a rock field of its own with the same figures.
"""

from __future__ import annotations

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import ModelInstanceIndex

from pr2_drake.scene import Scene, add_flat_ground
from pr2_drake.tasks.base import EpisodeStatus, Referee, TaskDefinition, TaskSpec
from pr2_drake.tasks.regions import Rect, add_line_marker, add_marker, region_from_yaml, rgba
from pr2_drake.tasks.ground import RockyRoad


def make_road(spec: TaskSpec) -> RockyRoad:
    """The task's rocky road (depends only on the YAML)."""
    return RockyRoad(**spec.scene["road"])


class RockyRoadReferee(Referee):
    """Awards ``task_region``, ``half_road`` and ``finish`` from the base position."""

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    def __init__(self, spec: TaskSpec, plant: MultibodyPlant, robot: ModelInstanceIndex,
                 scene: Scene):
        super().__init__(spec, plant, robot, scene)
        s = spec.scene
        self.task_region = region_from_yaml(s["task_region"])
        self.halfway_x = float(s["halfway_x"])
        self.finish = region_from_yaml(s["finish"])

    def judge(self, context, status: EpisodeStatus) -> None:
        p = self.X_WB().translation()
        t = context.get_time()
        if self.task_region.contains(p):
            self.award(status, "task_region", t)
            if p[0] >= self.halfway_x:
                self.award(status, "half_road", t)
        if self.finish.contains(p):
            self.award(status, "finish", t)

    def instruction(self) -> str:
        return "Walk over the rocky road into the green finish circle."


class Task(TaskDefinition):
    SEED_DRAWS_START_ONLY = True  # the seed draws the start pose alone

    def build_scene(self, plant: MultibodyPlant, rng: np.random.Generator) -> Scene:
        s = self.spec.scene
        colors = s["colors"]
        add_flat_ground(plant, color=rgba(colors["ground"]))
        road = make_road(self.spec)
        road.add_to(plant)
        start = Rect(tuple(self.spec.start_region["center"]), tuple(self.spec.start_region["size"]))
        add_marker(plant, "start_region", start, 0.001, colors["start"])
        finish = region_from_yaml(s["finish"])
        add_marker(plant, "finish_region", finish, 0.001, colors["finish"])
        fp = road.footprint
        # The halfway line floats just above the highest stone (visual only).
        z_line = road.height_range[1] + 0.01
        add_line_marker(plant, "halfway_line", (s["halfway_x"], fp.min[1]),
                        (s["halfway_x"], fp.max[1]), z_line, colors["halfway"])

        def ground_height(x: float, y: float) -> float:
            h = road.height(x, y)
            return 0.0 if h is None else max(h, 0.0)

        goal = [finish.center[0], finish.center[1], ground_height(*finish.center)]
        return Scene(
            name=self.name,
            start=self.spec.sample_start(rng),
            ground_height=ground_height,
            priors={"goal_center": np.array(goal)},
            data={"road": road},
        )

    def vary_scene(self, scene: dict, rng: np.random.Generator) -> dict:
        """A rock field of its own: the road's seed from ``rng``."""
        seed = int(rng.integers(int(scene["variation"]["road_seed_max"])))
        scene["road"]["seed"] = seed
        return {"road_seed": seed}

    def make_referee(self, plant: MultibodyPlant, robot: ModelInstanceIndex,
                     scene: Scene) -> Referee:
        return RockyRoadReferee(self.spec, plant, robot, scene)

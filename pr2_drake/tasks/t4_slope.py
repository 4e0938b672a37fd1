"""Task 4 - slope climbing: walk up a 7 deg incline into the finish circle on the plateau.

Scene (``tasks/4_slope.yaml``): level ground, a ramp rising at 7 deg along +x over a 2.5 m run
(0.307 m rise), then a level plateau 2 m long with the finish circle on it. The ramp is one
tilted box and the plateau one box, both 2 m wide; the arena's sides are their edges.

Rubric (points in the YAML), judged on the horizontal position of the base ``base_link``:
- ``task_region`` (+5): the base is inside the task region (the ramp's footprint);
- ``finish`` (+5): the base is within 0.4 m (horizontal) of the goal centre on the plateau.
Figures not in TASKS.md (ramp run and width, plateau length, regions, the 0.4 m finish radius
taken from task 1's tolerance, arena) are our choices and live in the YAML.

Priors: ``goal_center`` [x, y, z] (world, m) and ``slope_angle_deg``.

Scene variation (``scene.variation``): the incline drawn uniformly from the YAML's
``scene.variation.angle_deg`` range (5-9 deg); the priors give the angle and the goal drawn.
"""

from __future__ import annotations

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import ModelInstanceIndex

from pr2_drake.scene import Scene, add_flat_ground
from pr2_drake.tasks.base import EpisodeStatus, Referee, TaskDefinition, TaskSpec
from pr2_drake.tasks.regions import Rect, add_marker, region_from_yaml, rgba
from pr2_drake.tasks.ground import Slope


class SlopeReferee(Referee):
    """Awards ``task_region`` and ``finish`` from the base position."""

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    def __init__(self, spec: TaskSpec, plant: MultibodyPlant, robot: ModelInstanceIndex,
                 scene: Scene):
        super().__init__(spec, plant, robot, scene)
        self.task_region = region_from_yaml(spec.scene["task_region"])
        self.finish = region_from_yaml(spec.scene["finish"])

    def judge(self, context, status: EpisodeStatus) -> None:
        p = self.X_WB().translation()
        t = context.get_time()
        if self.task_region.contains(p):
            self.award(status, "task_region", t)
        if self.finish.contains(p):
            self.award(status, "finish", t)

    def instruction(self) -> str:
        return "Walk up the slope into the green finish circle."


class Task(TaskDefinition):
    SEED_DRAWS_START_ONLY = True  # the seed draws the start pose alone

    def build_scene(self, plant: MultibodyPlant, rng: np.random.Generator) -> Scene:
        s = self.spec.scene
        colors = s["colors"]
        add_flat_ground(plant, color=rgba(colors["ground"]))
        slope = Slope(**s["slope"])
        slope.add_to(plant)
        start = Rect(tuple(self.spec.start_region["center"]), tuple(self.spec.start_region["size"]))
        add_marker(plant, "start_region", start, 0.001, colors["start"])

        def ground_height(x: float, y: float) -> float:
            h = slope.height(x, y)
            return 0.0 if h is None else h

        finish = region_from_yaml(s["finish"])
        add_marker(plant, "finish_region", finish, ground_height(*finish.center) + 0.001,
                   colors["finish"])
        goal = [finish.center[0], finish.center[1], ground_height(*finish.center)]
        return Scene(
            name=self.name,
            start=self.spec.sample_start(rng),
            ground_height=ground_height,
            priors={"goal_center": np.array(goal), "slope_angle_deg": float(slope.angle_deg)},
            data={"slope": slope},
        )

    def vary_scene(self, scene: dict, rng: np.random.Generator) -> dict:
        """The incline [deg] drawn from ``rng`` within ``scene.variation.angle_deg``."""
        lo, hi = scene["variation"]["angle_deg"]
        angle = float(rng.uniform(lo, hi))
        scene["slope"]["angle_deg"] = angle
        return {"slope_angle_deg": angle}

    def make_referee(self, plant: MultibodyPlant, robot: ModelInstanceIndex,
                     scene: Scene) -> Referee:
        return SlopeReferee(self.spec, plant, robot, scene)

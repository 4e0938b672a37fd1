"""Task 5 - step climbing and button pressing.

Scene (``tasks/5_steps_button.yaml``): level ground, then ``count`` (2) steps up along +x, each
0.10 m high, 0.40 m deep and 2 m wide, then a level floor at the top (0.20 m) and, on it, a grey
post with a red button (a short cylinder) on its front face, 0.80 m above the floor. The steps
and floor are boxes on the world body; the button is its own body welded to the world, so
contacts with it are told apart from contacts with the post or the floor. No heading noise.

Rubric (points in the YAML), judged every 10 ms from the sole frames and the contact results:
- ``onto_step`` (+5): both feet are in contact with something and both soles are over the
  staircase (level >= 1) at a height >= h - tol (h = 0.10 m, tol = 0.03 m);
- ``over_steps`` (+5): both feet are in contact and both soles are over the floor beyond the last
  step at a height >= count * h - tol;
- ``touch_button`` (+5): some robot body has touched the button for ``press_time`` (0.2 s)
  without interruption;
- ``touch_button_arm`` (+5): an arm body (shoulder pitch/roll links, upper arm, forearm, hand
  sphere, either side) has touched the button for ``press_time`` without interruption. An arm
  press is also a press, so it earns both button items.
The episode is complete when all four are earned. Figures not in TASKS.md (step depth, two steps
going up to a raised floor, floor length, post and button size and height, tolerances, arena) are
our choices and live in the YAML.

Priors: ``button_center`` [x, y, z] (world, m; centre of the button's front face),
``step_height``, ``step_depth``, ``step_width`` (m), ``step_count`` and ``step_start_x`` (m,
where the first riser stands; the steps rise along +x, centred on y = 0). The robot has no
camera in this task, so the staircase's position is a prior, like its dimensions.

Scene variation (``scene.variation``): riser height and tread depth drawn uniformly from the
YAML's ``scene.variation`` ranges (0.08-0.12 m, 0.32-0.48 m); the top floor keeps its far end,
so the post and the button stand where they do (raised with the floor); the priors give the
figures drawn.
"""

from __future__ import annotations

import numpy as np
from pydrake.geometry import Box, Cylinder
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import ModelInstanceIndex, SpatialInertia

from pr2_drake.scene import GROUND_FRICTION, Scene, add_flat_ground
from pr2_drake.tasks.base import EpisodeStatus, Referee, TaskDefinition, TaskSpec
from pr2_drake.tasks.regions import (
    ARM_BODY_NAMES,
    FOOT_BODY_NAMES,
    SOLE_FRAME_NAMES,
    Rect,
    add_marker,
    bodies_touching,
    body_indices,
    contact_pairs,
    held_for,
    rgba,
    touching,
)
from pr2_drake.tasks.ground import Staircase


class StepsButtonReferee(Referee):
    """Awards the step items from the feet and the button items from sustained contact."""

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    def __init__(self, spec: TaskSpec, plant: MultibodyPlant, robot: ModelInstanceIndex,
                 scene: Scene):
        super().__init__(spec, plant, robot, scene)
        s = spec.scene
        self.stairs: Staircase = scene.data["stairs"]
        self.press_time = float(s["press_time"])
        self.tol = float(s["foot_height_tolerance"])
        self.robot_bodies = frozenset(plant.GetBodyIndices(robot))
        self.arm_bodies = body_indices(plant, robot, ARM_BODY_NAMES)
        self.feet = [plant.GetBodyByName(n, robot).index() for n in FOOT_BODY_NAMES]
        self._sole_indices = [plant.GetFrameByName(n, robot).index() for n in SOLE_FRAME_NAMES]
        self.button = frozenset([plant.GetBodyByName(s["button"]["name"]).index()])

    # Multibody elements (bodies, joints, frames) are kept as indices: a stored element holds its
    # plant through a reference the garbage collector cannot see (pr2_drake.lifetime).
    @property
    def soles(self):
        return [self.plant.get_frame(i) for i in self._sole_indices]

    def _feet_on(self, supported: set, level: int) -> bool:
        """Both feet in contact, over level >= ``level``, soles high enough for that level."""
        st = self.stairs
        for foot, sole in zip(self.feet, self.soles):
            p = sole.CalcPoseInWorld(self.ctx).translation()
            if foot not in supported or st.level(p[0], p[1]) < level:
                return False
            if p[2] < min(level, st.count) * st.height - self.tol:
                return False
        return True

    def judge(self, context, status: EpisodeStatus) -> None:
        t = context.get_time()
        pairs = contact_pairs(self.contact_results(context))
        supported = bodies_touching(pairs, self.robot_bodies)
        if self._feet_on(supported, 1):
            self.award(status, "onto_step", t)
        if self._feet_on(supported, self.stairs.count + 1):
            self.award(status, "over_steps", t)
        m = status.memo
        eps = 1e-9
        if held_for(m, "touch_since", touching(pairs, self.robot_bodies, self.button), t) \
                >= self.press_time - eps:
            self.award(status, "touch_button", t)
        if held_for(m, "arm_touch_since", touching(pairs, self.arm_bodies, self.button), t) \
                >= self.press_time - eps:
            self.award(status, "touch_button_arm", t)

    def instruction(self) -> str:
        return "Climb the steps, cross the floor and press the red button with a hand."


class Task(TaskDefinition):
    SEED_DRAWS_START_ONLY = True  # the seed draws the start pose alone

    def build_scene(self, plant: MultibodyPlant, rng: np.random.Generator) -> Scene:
        s = self.spec.scene
        colors = s["colors"]
        add_flat_ground(plant, color=rgba(colors["ground"]))
        stairs = Staircase(**s["steps"])
        stairs.add_to(plant)
        start = Rect(tuple(self.spec.start_region["center"]), tuple(self.spec.start_region["size"]))
        add_marker(plant, "start_region", start, 0.001, colors["start"])

        post = s["post"]
        px, py = post["center"]
        sx, sy = post["size"]
        floor = stairs.top
        X_post = RigidTransform([px, py, floor + post["height"] / 2])
        plant.RegisterCollisionGeometry(plant.world_body(), X_post,
                                        Box(sx, sy, post["height"]), "button_post",
                                        GROUND_FRICTION)
        plant.RegisterVisualGeometry(plant.world_body(), X_post, Box(sx, sy, post["height"]),
                                     "button_post", rgba(colors["post"]))

        b = s["button"]
        r, th = float(b["radius"]), float(b["thickness"])
        instance = plant.AddModelInstance(b["name"])
        button = plant.AddRigidBody(b["name"], instance,
                                    SpatialInertia.SolidCylinderWithMass(0.1, r, th, [1, 0, 0]))
        p_button = np.array([px - sx / 2 - th / 2, py, floor + float(b["height"])])
        plant.WeldFrames(plant.world_frame(), button.body_frame(), RigidTransform(p_button))
        X_BG = RigidTransform(RollPitchYaw(0, np.pi / 2, 0), [0, 0, 0])  # cylinder axis along x
        plant.RegisterCollisionGeometry(button, X_BG, Cylinder(r, th), b["name"],
                                        GROUND_FRICTION)
        plant.RegisterVisualGeometry(button, X_BG, Cylinder(r, th), b["name"],
                                     rgba(colors["button"]))

        st = s["steps"]
        return Scene(
            name=self.name,
            start=self.spec.sample_start(rng),
            ground_height=stairs.height_at,
            priors={
                "button_center": p_button - np.array([th / 2, 0.0, 0.0]),
                "step_height": float(st["height"]),
                "step_depth": float(st["depth"]),
                "step_width": float(st["width"]),
                "step_count": int(st["count"]),
                "step_start_x": float(st["start_x"]),
            },
            data={"stairs": stairs},
        )

    def vary_scene(self, scene: dict, rng: np.random.Generator) -> dict:
        """Riser height and tread depth [m] drawn from ``rng`` within ``scene.variation``."""
        st, v = scene["steps"], scene["variation"]
        floor_end = st["start_x"] + st["count"] * st["depth"] + st["floor_length"]
        st["height"] = float(rng.uniform(*v["height"]))
        st["depth"] = float(rng.uniform(*v["depth"]))
        st["floor_length"] = floor_end - st["start_x"] - st["count"] * st["depth"]
        return {"step_height": st["height"], "step_depth": st["depth"]}

    def make_referee(self, plant: MultibodyPlant, robot: ModelInstanceIndex,
                     scene: Scene) -> Referee:
        return StepsButtonReferee(self.spec, plant, robot, scene)

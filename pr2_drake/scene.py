"""What a task scene hands to the testbed, and the plain flat-ground scene."""


from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np
from pydrake.geometry import Box
from pydrake.math import RigidTransform
from pydrake.multibody.plant import CoulombFriction, MultibodyPlant

from pr2_drake.grasp import Graspable
from pr2_drake.materials import add_textured_box

GROUND_FRICTION = CoulombFriction(1.0, 1.0)


@dataclass
class StartPose:
    """Robot start: base position over the ground (x, y) [m] in world and heading yaw [rad]."""

    x: float = 0.0
    y: float = 0.0
    yaw: float = 0.0


@dataclass
class Scene:
    """A built scene.

    Attributes:
        name: scene name.
        start: the robot's start pose (already sampled from the episode seed).
        ground_height: terrain height z [m] at world (x, y), used to place the robot and to
            detect falls.
        graspables: objects a ``pick`` may attach.
        priors: task priors handed to the agent (goal positions, dimensions, ...).
        data: anything the task's referee needs (body indices, regions, ...).
        add_systems: callables ``f(builder, plant)`` the testbed calls after
            ``plant.Finalize()`` to add and wire scene systems (e.g. the source driving a
            prescribed-motion body through ``plant.get_desired_state_input_port``).
    """

    name: str
    start: StartPose = field(default_factory=StartPose)
    ground_height: Callable[[float, float], float] = lambda x, y: 0.0
    graspables: list[Graspable] = field(default_factory=list)
    priors: dict[str, Any] = field(default_factory=dict)
    data: dict[str, Any] = field(default_factory=dict)
    add_systems: list[Callable[[Any, MultibodyPlant], None]] = field(default_factory=list)


GROUND_VISUAL_SIZE = 24.0  # [m] side of the drawn ground; beyond it the sky's horizon shows


def add_flat_ground(plant: MultibodyPlant, color=(0.55, 0.58, 0.55, 1.0), size: float = 60.0,
                    material: str = "ground", visual_size: float = GROUND_VISUAL_SIZE) -> None:
    """A large box (``size`` [m] square, collision) whose top face is the plane z = 0, drawn as a
    thin textured slab ``visual_size`` [m] square. The drawn ground is kept small and thin:
    the sun's shadow map spans the scene's bounds, so a 60 m, 1 m thick slab would blur the
    shadows and shadow its own sides into a black band."""
    X = RigidTransform([0, 0, -0.5])
    plant.RegisterCollisionGeometry(plant.world_body(), X, Box(size, size, 1.0), "ground",
                                    GROUND_FRICTION)
    add_textured_box(plant, "ground", RigidTransform([0, 0, -0.01]),
                     (visual_size, visual_size, 0.02), color, material)


def build_flat_scene(plant: MultibodyPlant, rng: np.random.Generator) -> Scene:
    """Flat ground only; the robot starts at the origin facing +x."""
    add_flat_ground(plant)
    return Scene(name="flat")


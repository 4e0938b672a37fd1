"""What a task scene hands to the testbed, and the plain flat-ground scene."""


from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np
from pydrake.geometry import Box
from pydrake.math import RigidTransform
from pydrake.multibody.plant import CoulombFriction, MultibodyPlant

from pr2_drake.grasp import Graspable

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


def add_flat_ground(plant: MultibodyPlant, color=(0.55, 0.58, 0.55, 1.0), size: float = 60.0) -> None:
    """A large box whose top face is the plane z = 0."""
    X = RigidTransform([0, 0, -0.5])
    plant.RegisterCollisionGeometry(plant.world_body(), X, Box(size, size, 1.0), "ground",
                                    GROUND_FRICTION)
    plant.RegisterVisualGeometry(plant.world_body(), X, Box(size, size, 1.0), "ground",
                                 np.asarray(color))


def build_flat_scene(plant: MultibodyPlant, rng: np.random.Generator) -> Scene:
    """Flat ground only; the robot starts at the origin facing +x."""
    add_flat_ground(plant)
    return Scene(name="flat")


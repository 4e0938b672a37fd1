"""Task 2 - valve turning (15 points, 4 min); scene and numbers in ``tasks/2_valve.yaml``.

Scene: a red hand wheel (0.54 m across, horizontal, axis vertical) on a revolute joint to the
world, on a grey stem, at hand height for KUAVO. The rim (a ring of short cylinders), spokes and
hub collide with the robot, so pushing the wheel with the arm's distal end turns it. Resistance
is the joint's viscous damping (Drake joint damping) plus a Coulomb-like torque
``-friction_torque * tanh(w / friction_speed)`` (:class:`ValveFriction`; the torque a Context
parameter, which the domain randomisation draws) on the plant's applied generalized force input (our choice: Drake's discrete solver
has no joint Coulomb friction; the smoothed torque is explicit but its slope is far below what
destabilises the wheel's inertia at the 4 ms step: 12 Nm s/rad against I/dt = 45).

Pick: ``pick`` with a hand latches while the hand sphere centre is inside the enlarged valve
volume (``scene.pick_volume``: 0.30 m horizontal radius about the axis, within a height band);
the grasp system then holds the hand's point on the wheel, rotation free ("ball"), so the wheel
turns with the robot's motion and its reaction acts on the robot.

Rubric: base inside ``task_region`` +5; |valve angle| > ``turn_threshold_deg`` (5 deg, our
choice) +5; |valve angle| > ``turn_goal_deg`` (45 deg) +5. The angle is the joint angle from the
start, either direction. Priors: valve centre, dimensions, id. Feedback: the arm pick state.

Scene variation (``scene.variation``): the wheel's centre height and outer diameter drawn
uniformly from the YAML's ``scene.variation`` ranges; the pick volume grows or shrinks with the
rim (its margin beyond the rim kept); the priors give the figures drawn.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pydrake.geometry import Box, Cylinder
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.plant import CoulombFriction, MultibodyPlant
from pydrake.multibody.tree import (
    FixedOffsetFrame,
    ModelInstanceIndex,
    RevoluteJoint,
    SpatialInertia,
    UnitInertia,
)
from pydrake.systems.framework import BasicVector, DiagramBuilder, LeafSystem

from pr2_drake.grasp import Graspable
from pr2_drake.lifetime import weak_calc
from pr2_drake.scene import Scene, add_flat_ground
from pr2_drake.tasks.base import EpisodeStatus, Referee, TaskDefinition
from pr2_drake.tasks.regions import add_marker, region_from_yaml, rgba

VALVE_FRICTION = CoulombFriction(0.8, 0.6)


class ValveFriction(LeafSystem):
    """Coulomb-like joint friction: tau = -tau_c tanh(w / w_s) on one velocity index.

    Input ``plant_state`` (full [q; v]); output ``generalized_force`` (nv) for the plant's
    applied generalized force input.
    """

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    def __init__(self, plant: MultibodyPlant, v_index: int, torque: float, speed: float):
        super().__init__()
        if torque < 0 or speed <= 0:
            raise ValueError(f"valve friction needs torque >= 0 and speed > 0, got {torque}, "
                             f"{speed}")
        self._nq, self._nv = plant.num_positions(), plant.num_velocities()
        self._iv, self._speed = v_index, float(speed)
        self.nominal_torque = float(torque)
        self._tau = self.DeclareNumericParameter(BasicVector([self.nominal_torque]))
        self._x = self.DeclareVectorInputPort("plant_state", self._nq + self._nv)
        self.DeclareVectorOutputPort("generalized_force", self._nv, weak_calc(self._calc))

    def set_torque(self, context, torque: float) -> None:
        """The Coulomb torque tau_c [Nm] in ``context`` (this system's; a parameter, so a
        domain randomisation sets it per episode)."""
        context.get_mutable_numeric_parameter(self._tau).SetAtIndex(0, float(torque))

    def _calc(self, context, output) -> None:
        w = self._x.Eval(context)[self._nq + self._iv]
        f = np.zeros(self._nv)
        tau = context.get_numeric_parameter(self._tau).GetAtIndex(0)
        f[self._iv] = -tau * np.tanh(w / self._speed)
        output.SetFromVector(f)


def in_pick_volume(p_WH: np.ndarray, center: np.ndarray, volume: dict) -> bool:
    """Whether the hand centre p_WH [m] lies in the enlarged valve cylinder about ``center``."""
    d = np.asarray(p_WH, float) - np.asarray(center, float)
    return bool(np.hypot(d[0], d[1]) <= volume["radius"]
                and volume["z_min"] <= d[2] <= volume["z_max"])


def add_valve(plant: MultibodyPlant, v: dict) -> tuple[ModelInstanceIndex, RevoluteJoint]:
    """The wheel body on a revolute joint about world z through ``v["center"]``, plus its stem."""
    instance = plant.AddModelInstance("valve")
    c = np.asarray(v["center"], float)
    r_out = v["diameter"] / 2
    tube = v["rim_tube_radius"]
    R = r_out - tube  # rim centreline radius
    m = float(v["mass"])
    wheel = plant.AddRigidBody(
        "valve_wheel", instance,
        SpatialInertia(m, np.zeros(3), UnitInertia(R * R / 2, R * R / 2, R * R)))
    color = rgba(v["color"])
    n = int(v["rim_segments"])
    seg = 2 * R * np.sin(np.pi / n) + tube  # overlap the segments so the ring looks closed
    for i in range(n):
        a = 2 * np.pi * (i + 0.5) / n
        X = RigidTransform(RollPitchYaw(0, 0, a).ToRotationMatrix()
                           @ RollPitchYaw(np.pi / 2, 0, 0).ToRotationMatrix(),
                           [R * np.cos(a), R * np.sin(a), 0])
        shape = Cylinder(tube, seg)
        plant.RegisterVisualGeometry(wheel, X, shape, f"rim_{i}", color)
        plant.RegisterCollisionGeometry(wheel, X, shape, f"rim_{i}", VALVE_FRICTION)
    w = v["spoke_width"]
    hub_r = v["hub_radius"]
    length = R - hub_r + 0.01
    for k in range(int(v["spokes"])):
        a = 2 * np.pi * k / int(v["spokes"])
        mid = (hub_r + R) / 2
        X = RigidTransform(RollPitchYaw(0, 0, a), [mid * np.cos(a), mid * np.sin(a), 0])
        plant.RegisterVisualGeometry(wheel, X, Box(length, w, w), f"spoke_{k}", color)
        plant.RegisterCollisionGeometry(wheel, X, Box(length, w, w), f"spoke_{k}", VALVE_FRICTION)
    hub = Cylinder(hub_r, v["hub_length"])
    plant.RegisterVisualGeometry(wheel, RigidTransform(), hub, "hub", rgba([0.6, 0.05, 0.05, 1]))
    plant.RegisterCollisionGeometry(wheel, RigidTransform(), hub, "hub", VALVE_FRICTION)
    # A spinner handle standing up from the rim: it shows the wheel's rotation to the camera
    # and gives a hand something to push sideways.
    a = np.radians(v["handle_angle_deg"])
    h = v["handle_height"]
    knob = RigidTransform([R * np.cos(a), R * np.sin(a), tube + h / 2])
    handle = Cylinder(v["handle_radius"], h)
    plant.RegisterVisualGeometry(wheel, knob, handle, "handle", rgba(v["handle_color"]))
    plant.RegisterCollisionGeometry(wheel, knob, handle, "handle", VALVE_FRICTION)
    joint = plant.AddJoint(RevoluteJoint(
        "valve_joint",
        plant.AddFrame(_fixed_frame(plant, "valve_axis_frame", c)),
        wheel.body_frame(),
        [0.0, 0.0, 1.0],
        float(v["damping"]),
    ))
    # The fixed stem from the floor to the hub (welded to the world).
    stem_len = c[2] - v["hub_length"] / 2
    X_stem = RigidTransform([c[0], c[1], stem_len / 2])
    stem = Cylinder(v["pedestal_radius"], stem_len)
    grey = rgba(v["pedestal_color"])
    plant.RegisterVisualGeometry(plant.world_body(), X_stem, stem, "valve_stem", grey)
    plant.RegisterCollisionGeometry(plant.world_body(), X_stem, stem, "valve_stem",
                                    VALVE_FRICTION)
    base = Cylinder(0.12, 0.03)
    X_base = RigidTransform([c[0], c[1], 0.015])
    plant.RegisterVisualGeometry(plant.world_body(), X_base, base, "valve_stem_base", grey)
    return instance, joint


def _fixed_frame(plant: MultibodyPlant, name: str, p_WF) -> FixedOffsetFrame:
    return FixedOffsetFrame(name, plant.world_frame(), RigidTransform(np.asarray(p_WF, float)))


class ValveReferee(Referee):
    """Scores task 2 from the base position and the valve joint angle."""

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    def __init__(self, spec, plant, robot, scene: Scene):
        super().__init__(spec, plant, robot, scene)
        s = spec.scene
        self._joint_index = plant.GetJointByName("valve_joint").index()
        self._region = region_from_yaml(s["task_region"])
        self._turn = np.radians(s["turn_threshold_deg"])
        self._goal = np.radians(s["turn_goal_deg"])

    def valve_angle(self) -> float:
        """Valve joint angle [rad] from its start (self.ctx holds the plant state)."""
        return float(self.plant.get_joint(self._joint_index).get_angle(self.ctx))

    def judge(self, context, status: EpisodeStatus) -> None:
        t = context.get_time()
        if self._region.contains(self.X_WB().translation()):
            self.award(status, "task_region", t)
        angle = abs(self.valve_angle())
        status.memo["max_valve_angle_deg"] = max(status.memo.get("max_valve_angle_deg", 0.0),
                                                 float(np.degrees(angle)))
        if angle > self._turn:
            self.award(status, "turn_valve", t)
        if angle > self._goal:
            self.award(status, "turn_valve_45", t)

    def feedback(self, context) -> dict[str, Any]:
        p = self.pick_state(context)
        return {"pick_state": {"attached": p.attached, "hand": p.hand, "object": p.object}}


class Task(TaskDefinition):
    SEED_DRAWS_START_ONLY = True  # the seed draws the start pose alone

    def build_scene(self, plant: MultibodyPlant, rng: np.random.Generator) -> Scene:
        s = self.spec.scene
        v = s["valve"]
        add_flat_ground(plant, color=tuple(s["floor_color"]))
        instance, joint = add_valve(plant, v)
        center = np.asarray(v["center"], float)
        volume = dict(s["pick_volume"])
        add_marker(plant, "task_region", region_from_yaml(s["task_region"]), 0.002,
                   s["task_region_color"])
        add_marker(plant, "start_region", region_from_yaml(self.spec.start_region), 0.003,
                   s["start_region_color"])
        wheel = plant.GetBodyByName("valve_wheel", instance)
        graspable = Graspable(
            name=v["id"], body=wheel.index(), mode="ball",
            can_pick=lambda p_WH, X_WO: in_pick_volume(p_WH, center, volume))

        # Capture the index, not the joint: the scene keeps this closure, and a joint holds
        # its plant through a reference the garbage collector cannot see (pr2_drake.lifetime).
        joint_index = joint.index()

        def add_friction(builder: DiagramBuilder, plant_: MultibodyPlant) -> None:
            friction = builder.AddNamedSystem(
                "valve_friction",
                ValveFriction(plant_, plant_.get_joint(joint_index).velocity_start(),
                              v["friction_torque"],
                              v["friction_speed"]))
            builder.Connect(plant_.get_state_output_port(), friction.GetInputPort("plant_state"))
            builder.Connect(friction.GetOutputPort("generalized_force"),
                            plant_.get_applied_generalized_force_input_port())

        priors = {
            "valve_id": v["id"],
            "valve_center": center.tolist(),
            "valve_dimensions": {
                "diameter": float(v["diameter"]),
                "rim_tube_radius": float(v["rim_tube_radius"]),
                "spokes": int(v["spokes"]),
                "axis": [0.0, 0.0, 1.0],
                "pick_volume": volume,
            },
        }
        return Scene(
            name="valve",
            start=self.spec.sample_start(rng),
            graspables=[graspable],
            priors=priors,
            data={"valve_joint": joint.index(), "valve_center": center},
            add_systems=[add_friction],
        )

    def vary_scene(self, scene: dict, rng: np.random.Generator) -> dict:
        """Centre height and diameter [m] drawn from ``rng`` within ``scene.variation``."""
        v, var = scene["valve"], scene["variation"]
        height = float(rng.uniform(*var["height"]))
        diameter = float(rng.uniform(*var["diameter"]))
        volume = scene["pick_volume"]
        volume["radius"] = float(volume["radius"]) + 0.5 * (diameter - float(v["diameter"]))
        v["center"] = [float(v["center"][0]), float(v["center"][1]), height]
        v["diameter"] = diameter
        return {"valve_height": height, "valve_diameter": diameter}

    def make_referee(self, plant, robot, scene) -> ValveReferee:
        return ValveReferee(self.spec, plant, robot, scene)

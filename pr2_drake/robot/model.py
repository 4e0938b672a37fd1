"""Load KUAVO into a MultibodyPlant and map its joints to the original platform's order."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import ModelInstanceIndex

from pr2_drake.paths import data_path
from pr2_drake.robot.params import ARM_JOINTS, LEG_JOINTS, RobotParams, load_robot_params

BASE_BODY = "base_link"


def add_kuavo(plant: MultibodyPlant, name: str = "kuavo") -> ModelInstanceIndex:
    """Parse the generated KUAVO URDF into ``plant`` (before Finalize) as model ``name``."""
    parser = Parser(plant, name)
    (robot,) = parser.AddModels(str(data_path("models", "kuavo", "kuavo.urdf")))
    return robot


@dataclass(frozen=True)
class KuavoMaps:
    """Index maps between the robot instance's vectors and the original joint order.

    Indices are local to the robot model instance: they index the vectors returned by
    ``plant.GetPositions(context, robot)``, ``plant.GetVelocities(context, robot)`` and the
    robot's actuation input port (``plant.get_actuation_input_port(robot)``), so they hold
    whatever else the plant contains. ``q_joints[i]`` is the position index of joint i of
    ``ARM_JOINTS + LEG_JOINTS``.
    """

    robot: ModelInstanceIndex
    nq: int
    nv: int
    q_joints: np.ndarray
    v_joints: np.ndarray
    actuators: np.ndarray  # actuation-port index per joint, original order
    q_base: np.ndarray  # [qw, qx, qy, qz, x, y, z]
    v_base: np.ndarray  # [wx, wy, wz, vx, vy, vz], expressed in world

    @staticmethod
    def from_plant(plant: MultibodyPlant, robot: ModelInstanceIndex) -> "KuavoMaps":
        q_full = plant.GetPositionsFromArray(robot, np.arange(plant.num_positions()))
        v_full = plant.GetVelocitiesFromArray(robot, np.arange(plant.num_velocities()))
        q_local = {int(full): k for k, full in enumerate(q_full)}
        v_local = {int(full): k for k, full in enumerate(v_full)}
        instance_actuators = list(plant.GetJointActuatorIndices(robot))
        q_idx, v_idx, act_idx = [], [], []
        for n in ARM_JOINTS + LEG_JOINTS:
            joint = plant.GetJointByName(n, robot)
            q_idx.append(q_local[joint.position_start()])
            v_idx.append(v_local[joint.velocity_start()])
            act_idx.append(instance_actuators.index(plant.GetJointActuatorByName(n, robot).index()))
        base = plant.GetBodyByName(BASE_BODY, robot)
        q0 = q_local[base.floating_positions_start()]
        v0 = v_local[base.floating_velocities_start_in_v()]
        return KuavoMaps(
            robot=robot,
            nq=len(q_full),
            nv=len(v_full),
            q_joints=np.array(q_idx),
            v_joints=np.array(v_idx),
            actuators=np.array(act_idx),
            q_base=np.arange(q0, q0 + 7),
            v_base=np.arange(v0, v0 + 6),
        )


def default_joint_positions(params: RobotParams | None = None) -> np.ndarray:
    """Nominal standing pose, 18 values in the original order [rad]."""
    params = params or load_robot_params()
    return np.concatenate([params.default_positions("arms"), params.default_positions("legs")])


def standing_base_pose(
    plant: MultibodyPlant,
    robot: ModelInstanceIndex,
    joints: np.ndarray,
    xy=(0.0, 0.0),
    yaw: float = 0.0,
    ground_z: float = 0.0,
) -> RigidTransform:
    """X_WB that puts the lower sole of the robot on ``ground_z`` for the given joint pose."""
    maps = KuavoMaps.from_plant(plant, robot)
    ctx = plant.CreateDefaultContext()
    q = plant.GetPositions(ctx, robot)
    q[maps.q_joints] = joints
    plant.SetPositions(ctx, robot, q)
    base = plant.GetBodyByName(BASE_BODY, robot)
    plant.SetFreeBodyPose(ctx, base, RigidTransform())
    sole_z = min(
        plant.GetFrameByName(f"{s}_sole", robot).CalcPoseInWorld(ctx).translation()[2]
        for s in ("l", "r")
    )
    return RigidTransform(RollPitchYaw(0, 0, yaw), [xy[0], xy[1], ground_z - sole_z])

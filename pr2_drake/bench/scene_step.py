"""``pr2-drake bench scene-step``: plant step time of a task scene with KUAVO standing on it,
against flat ground.

The robot is held by the plant's implicit joint PD (position targets = the nominal standing pose),
so the measured time is the MultibodyPlant step alone (no Python systems in the loop):

    pr2-drake bench scene-step [--seconds 1.0] [--time-step S] [--approximation A]
                               none 1 1@2.0,0.0 3 4 5

An argument is a task id ("none" = flat ground), optionally with "@x,y" for the start position.
Prints the mean wall time per physics step (default: the testbed's step and contact
approximation), the collision geometries, the candidate pairs SceneGraph tests (robot with
robot, robot with the rest, the rest with itself: what the collision filters leave) and the
number of point contacts at the end.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from pydrake.multibody.plant import AddMultibodyPlant, MultibodyPlantConfig
from pydrake.multibody.tree import PdControllerGains
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from pr2_drake.controllers.standing import StandingPolicy
from pr2_drake.robot.model import BASE_BODY, KuavoMaps, add_kuavo, default_joint_positions, \
    standing_base_pose
from pr2_drake.scene import StartPose, build_flat_scene
from pr2_drake.testbed import (CONTACT_APPROXIMATIONS, DEFAULT_CONTACT_APPROXIMATION,
                               DEFAULT_TIME_STEP)


def measure(task: str, seconds: float, time_step: float = DEFAULT_TIME_STEP,
            approximation: str = DEFAULT_CONTACT_APPROXIMATION) -> str:
    name, _, at = task.partition("@")
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlant(MultibodyPlantConfig(
        time_step=time_step, discrete_contact_approximation=approximation,
        penetration_allowance=0.001), builder)
    robot = add_kuavo(plant)
    for i in plant.GetJointActuatorIndices(robot):
        plant.get_joint_actuator(i).set_controller_gains(PdControllerGains(p=400.0, d=8.0))
    rng = np.random.default_rng(0)
    if name == "none":
        scene = build_flat_scene(plant, rng)
    else:
        from pr2_drake.tasks import get_task
        scene = get_task(int(name)).build_scene(plant, rng)
    plant.Finalize()
    for add in scene.add_systems:
        add(builder, plant)
    start = scene.start
    if at:
        x, y = map(float, at.split(","))
        start = StartPose(x, y, 0.0)
    maps = KuavoMaps.from_plant(plant, robot)
    q_j = default_joint_positions()
    X_WB = standing_base_pose(plant, robot, q_j, (start.x, start.y), start.yaw,
                              float(scene.ground_height(start.x, start.y)))
    diagram = builder.Build()
    sim = Simulator(diagram)
    ctx = plant.GetMyMutableContextFromRoot(sim.get_mutable_context())
    q = plant.GetPositions(ctx, robot)
    q[maps.q_joints] = q_j
    plant.SetPositions(ctx, robot, q)
    plant.SetFreeBodyPose(ctx, plant.GetBodyByName(BASE_BODY, robot), X_WB)
    # Desired state of the actuated joints, in actuator order.
    n_u = plant.num_actuated_dofs(robot)
    xd = np.zeros(2 * n_u)
    for k, i in enumerate(plant.GetJointActuatorIndices(robot)):
        xd[k] = q[_local_q(plant, robot, plant.get_joint_actuator(i).joint())]
    plant.get_desired_state_input_port(robot).FixValue(ctx, xd)
    # Gravity feed-forward: the torques that hold the nominal pose with the weight on both soles.
    body_state = np.concatenate([X_WB.translation(), X_WB.rotation().ToQuaternion().wxyz(),
                                 np.zeros(6)])
    joint_state = np.concatenate([q_j, np.zeros(36)])
    u = np.zeros(n_u)
    u[maps.actuators] = StandingPolicy().static_torques(joint_state, body_state)
    plant.get_actuation_input_port(robot).FixValue(ctx, u)
    sim.Initialize()
    sim.AdvanceTo(0.05)
    t0 = time.perf_counter()
    sim.AdvanceTo(0.05 + seconds)
    wall = time.perf_counter() - t0
    steps = round(seconds / time_step)
    z = plant.EvalBodyPoseInWorld(ctx, plant.GetBodyByName(BASE_BODY, robot)).translation()[2]
    n_c = plant.get_contact_results_output_port().Eval(ctx).num_point_pair_contacts()
    n_geo = plant.num_collision_geometries()
    pairs = candidate_pairs(plant, scene_graph, robot)
    return (f"{task:>12}: {wall / steps * 1e3:.3f} ms/step ({seconds / wall:.1f}x real time), "
            f"{n_geo} collision geometries, candidate pairs {sum(pairs.values())} (robot-robot "
            f"{pairs['robot-robot']}, robot-other {pairs['robot-other']}, other-other "
            f"{pairs['other-other']}), {n_c} contacts at the end, base z {z:.3f} m")


def candidate_pairs(plant, scene_graph, robot) -> dict[str, int]:
    """SceneGraph's collision candidates (pairs its filters leave), by whose they are."""
    inspector = scene_graph.model_inspector()
    counts = dict.fromkeys(("robot-robot", "robot-other", "other-other"), 0)
    for a, b in inspector.GetCollisionCandidates():
        n = sum(plant.GetBodyFromFrameId(inspector.GetFrameId(g)).model_instance() == robot
                for g in (a, b))
        counts[("other-other", "robot-other", "robot-robot")[n]] += 1
    return counts


def _local_q(plant, robot, joint) -> int:
    """Index of ``joint``'s position inside the robot instance's position vector."""
    full = plant.GetPositionsFromArray(robot, np.arange(plant.num_positions()))
    return int(list(full).index(joint.position_start()))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="pr2-drake bench scene-step",
                                 description=__doc__.splitlines()[0])
    ap.add_argument("tasks", nargs="+")
    ap.add_argument("--seconds", type=float, default=1.0)
    ap.add_argument("--time-step", type=float, default=DEFAULT_TIME_STEP, help="[s]")
    ap.add_argument("--approximation", default=DEFAULT_CONTACT_APPROXIMATION,
                    choices=CONTACT_APPROXIMATIONS)
    args = ap.parse_args(argv)
    print(f"physics step {args.time_step * 1e3:g} ms, contact approximation "
          f"{args.approximation}")
    for t in args.tasks:
        print(measure(t, args.seconds, args.time_step, args.approximation), flush=True)
    return 0

"""The KUAVO model against its parameter file and the published figures."""

import numpy as np
import pytest
from pydrake.math import RigidTransform
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph, MultibodyPlant
from pydrake.systems.framework import DiagramBuilder

from pr2_drake.robot import generate
from pr2_drake.robot.model import KuavoMaps, add_kuavo, default_joint_positions
from pr2_drake.robot.params import ARM_JOINTS, LEG_JOINTS, load_robot_params


@pytest.fixture(scope="module")
def model():
    plant = MultibodyPlant(0.001)
    robot = add_kuavo(plant)
    plant.Finalize()
    ctx = plant.CreateDefaultContext()
    plant.SetFreeBodyPose(ctx, plant.GetBodyByName("base_link"), RigidTransform())
    return plant, robot, ctx, load_robot_params()


def _p(plant, ctx, frame):
    return plant.GetFrameByName(frame).CalcPoseInWorld(ctx).translation()


def test_published_figures_in_parameter_file(model):
    *_, params = model
    assert params.total_mass == pytest.approx(34.5)
    assert params.height == pytest.approx(1.20)
    assert params.raw["torso"]["pelvis_width"] == pytest.approx(0.22)
    legs, arms = params.raw["legs"], params.raw["arms"]
    assert legs["thigh"]["length"] == pytest.approx(0.23)
    assert legs["calf"]["length"] == pytest.approx(0.26)
    assert legs["foot"]["length"] == pytest.approx(0.15)
    assert arms["upper_arm"]["length"] == pytest.approx(0.24)
    assert arms["forearm"]["length"] == pytest.approx(0.20)


def test_total_mass(model):
    plant, robot, ctx, params = model
    assert plant.CalcTotalMass(ctx, [robot]) == pytest.approx(params.total_mass, abs=1e-9)


def test_standing_height_with_straight_legs(model):
    plant, robot, ctx, params = model
    torso = params.raw["torso"]
    head_top = torso["head_center"][2] + torso["head_radius"]  # base frame at the origin
    sole = _p(plant, ctx, "l_sole")[2]
    assert head_top - sole == pytest.approx(params.height, abs=1e-6)
    assert _p(plant, ctx, "r_sole")[2] == pytest.approx(sole)


def test_segment_lengths(model):
    plant, robot, ctx, params = model

    def joint_origin(name):
        j = plant.GetJointByName(name)
        return j.frame_on_child().CalcPoseInWorld(ctx).translation()

    for s in "lr":
        assert np.linalg.norm(joint_origin(f"{s}_hip_y") - joint_origin(f"{s}_knee")) == pytest.approx(0.23)
        assert np.linalg.norm(joint_origin(f"{s}_knee") - joint_origin(f"{s}_ankle")) == pytest.approx(0.26)
        assert np.linalg.norm(joint_origin(f"{s}_shoulder_y") - joint_origin(f"{s}_elbow")) == pytest.approx(0.24)
        assert np.linalg.norm(joint_origin(f"{s}_elbow") - _p(plant, ctx, f"{s}_arm_sphere")) == pytest.approx(0.20)
    assert np.linalg.norm(joint_origin("l_hip_z") - joint_origin("r_hip_z")) == pytest.approx(0.22)
    # Foot length: the corner spheres span the sole from heel to toe.
    r = params.raw["legs"]["foot"]["contact_sphere_radius"]
    x = _foot_contact_x("l_foot")
    assert len(x) >= 2
    assert max(x) - min(x) + 2 * r == pytest.approx(0.15)


def _foot_contact_x(foot: str) -> list[float]:
    """x of the foot's contact spheres in the foot frame (needs a SceneGraph to inspect)."""
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, 0.001)
    add_kuavo(plant)
    plant.Finalize()
    inspector = scene_graph.model_inspector()
    body = plant.GetBodyByName(foot)
    return [inspector.GetPoseInFrame(g).translation()[0]
            for g in plant.GetCollisionGeometriesForBody(body)
            if "foot_contact" in inspector.GetName(g)]


def test_joint_names_order_limits_and_efforts(model):
    plant, robot, ctx, params = model
    assert tuple(j.name for j in params.joints) == ARM_JOINTS + LEG_JOINTS
    assert plant.num_actuators() == 18
    assert plant.num_velocities() == 24  # 6 floating + 18 joints
    for spec in params.joints:
        joint = plant.GetJointByName(spec.name)
        assert joint.position_lower_limits()[0] == pytest.approx(spec.lower, abs=1e-5)
        assert joint.position_upper_limits()[0] == pytest.approx(spec.upper, abs=1e-5)
        assert plant.GetJointActuatorByName(spec.name).effort_limit() == pytest.approx(spec.effort)
    spans = {"hip_z": 150, "hip_x": 105, "hip_y": 150, "knee": 130, "ankle": 110}
    peaks = {"hip_z": 48, "hip_x": 110, "hip_y": 110, "knee": 110, "ankle": 48}
    for s in "lr":
        for name, span in spans.items():
            spec = params.joint(f"{s}_{name}")
            assert np.degrees(spec.upper - spec.lower) == pytest.approx(span)
            assert spec.effort == peaks[name]


def test_maps_follow_original_order(model):
    plant, robot, ctx, params = model
    maps = KuavoMaps.from_plant(plant, robot)
    q = np.zeros(plant.num_positions())
    q[maps.q_joints] = np.arange(18) * 0.01
    plant.SetPositions(ctx, q)
    for i, name in enumerate(ARM_JOINTS + LEG_JOINTS):
        assert plant.GetJointByName(name).get_angle(ctx) == pytest.approx(0.01 * i)
    plant.SetPositions(ctx, np.zeros(plant.num_positions()))
    plant.SetFreeBodyPose(ctx, plant.GetBodyByName("base_link"), RigidTransform())


def test_default_pose_within_limits(model):
    *_, params = model
    q = default_joint_positions(params)
    for spec, value in zip(params.joints, q):
        assert spec.lower <= value <= spec.upper, spec.name


def test_generated_urdf_matches_parameter_file():
    assert generate.main(["--check"]) == 0


def test_parameter_file_errors_name_the_problem(tmp_path):
    text = (load_robot_params().path).read_text().replace("name: l_knee", "name: l_knee_typo")
    bad = tmp_path / "params.yaml"
    bad.write_text(text)
    with pytest.raises(ValueError, match="original order"):
        load_robot_params(bad)

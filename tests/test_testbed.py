"""The testbed diagram: ports, torque-driven legs, actuation modes, bad commands, camera."""

import math

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator

from conftest import standing_simulator
from pr2_drake.camera import CameraSettings
from pr2_drake.ports import (
    EFFORT_ARMS,
    EFFORT_LEGS,
    JOINT_STATE_SIZE,
    P_WB,
    Q_ARMS,
    Q_LEGS,
    QUAT_WB,
    V_ARMS,
    JointGroupCommand,
)
from pr2_drake.robot.params import load_robot_params
from pr2_drake.scenario import Scenario
from pr2_drake.testbed import DEFAULT_TIME_STEP, TestbedConfig, build_testbed


def _simulator(config=None):
    testbed = build_testbed(config or TestbedConfig())
    simulator = Simulator(testbed)
    ctx = simulator.get_mutable_context()
    return simulator, testbed, ctx


def test_ports_are_named_and_sized():
    testbed = build_testbed()
    for name in ("arms_command", "legs_command", "pick", "release"):
        assert testbed.HasInputPort(name)
    assert testbed.GetOutputPort("joint_state").size() == JOINT_STATE_SIZE
    assert testbed.GetOutputPort("body_state").size() == 13
    assert not testbed.HasOutputPort("rgbd")  # camera off by default


def test_body_state_matches_plant_pose():
    simulator, testbed, ctx = _simulator()
    body = testbed.GetOutputPort("body_state").Eval(ctx)
    X_WB = testbed.plant.EvalBodyPoseInWorld(
        testbed.plant.GetMyContextFromRoot(ctx), testbed.plant.GetBodyByName("base_link")
    )
    np.testing.assert_allclose(body[P_WB], X_WB.translation())
    np.testing.assert_allclose(body[QUAT_WB], X_WB.rotation().ToQuaternion().wxyz())
    # The soles start on the ground.
    plant_ctx = testbed.plant.GetMyContextFromRoot(ctx)
    for s in "lr":
        z = testbed.plant.GetFrameByName(f"{s}_sole").CalcPoseInWorld(plant_ctx).translation()[2]
        assert z == pytest.approx(0.0, abs=1e-9)


def test_standing_controller_holds_height_for_10_s():
    simulator, testbed, ctx = standing_simulator()
    z0 = testbed.GetOutputPort("body_state").Eval(ctx)[2]
    heights = []
    for t in np.arange(0.5, 10.01, 0.5):
        simulator.AdvanceTo(t)
        heights.append(testbed.GetOutputPort("body_state").Eval(ctx)[2])
    assert np.max(np.abs(np.array(heights) - z0)) < 0.02


def test_zero_leg_effort_collapses():
    """Legs are truly torque-driven: with zero effort nothing holds the robot up but the
    knees' and ankles' hard stops, where it ends in a deep squat (base ~0.29 m lower)."""
    simulator, testbed, ctx = _simulator()
    testbed.GetInputPort("legs_command").FixValue(ctx, JointGroupCommand.effort(np.zeros(10)))
    z0 = testbed.GetOutputPort("body_state").Eval(ctx)[2]
    simulator.AdvanceTo(2.0)
    state = testbed.GetOutputPort("joint_state").Eval(ctx)
    assert z0 - testbed.GetOutputPort("body_state").Eval(ctx)[2] > 0.25
    params = load_robot_params()
    knees = [state[Q_LEGS][3], state[Q_LEGS][8]]
    assert knees == pytest.approx([params.joint("l_knee").lower] * 2, abs=0.02)
    np.testing.assert_allclose(state[EFFORT_LEGS], 0.0)


def test_effort_is_clamped_to_peak_torque_and_reported():
    simulator, testbed, ctx = _simulator()
    tau = np.full(10, 1000.0)
    testbed.GetInputPort("legs_command").FixValue(ctx, JointGroupCommand.effort(tau))
    simulator.AdvanceTo(DEFAULT_TIME_STEP)
    applied = testbed.GetOutputPort("joint_state").Eval(ctx)[EFFORT_LEGS]
    np.testing.assert_allclose(applied, load_robot_params().effort_limits("legs"))


def test_effort_limits_are_a_context_parameter_of_both_paths():
    from pr2_drake.actuation import EFFORT_SOURCE, SPRING_SOURCE

    simulator, testbed, ctx = _simulator()
    adapter = testbed.GetSubsystemByName("actuation")
    a_ctx = adapter.GetMyMutableContextFromRoot(ctx)
    peak = np.concatenate([load_robot_params().effort_limits(g) for g in ("arms", "legs")])
    np.testing.assert_array_equal(adapter.effort_limits(a_ctx), peak)
    adapter.set_effort_limits(a_ctx, 0.5 * peak)  # e.g. a weaker motor, per episode
    testbed.GetInputPort("legs_command").FixValue(ctx, JointGroupCommand.effort(np.full(10, 1e3)))
    source = adapter.GetOutputPort("actuation_source")
    assert source.Eval(a_ctx) == EFFORT_SOURCE  # efforts only: no Python at the physics step
    simulator.AdvanceTo(DEFAULT_TIME_STEP)
    applied = testbed.GetOutputPort("joint_state").Eval(ctx)[EFFORT_LEGS]
    np.testing.assert_allclose(applied, 0.5 * peak[8:])
    # A position command far from the state saturates at the same halved limits.
    testbed.GetInputPort("arms_command").FixValue(
        ctx, JointGroupCommand.position(np.full(8, 3.0), np.full(8, 1e3), np.zeros(8)))
    assert source.Eval(a_ctx) == SPRING_SOURCE
    simulator.AdvanceTo(0.004)
    applied = testbed.GetOutputPort("joint_state").Eval(ctx)[EFFORT_ARMS]
    np.testing.assert_allclose(np.abs(applied), 0.5 * peak[:8])
    with pytest.raises(ValueError, match="effort limits must be 18 positive"):
        adapter.set_effort_limits(a_ctx, -peak)


def test_position_mode_tracks_an_arm_step():
    simulator, testbed, ctx = standing_simulator()
    target = load_robot_params().default_positions("arms")
    target[0] += 0.5  # l_shoulder_y forward
    # Override the controller's arm command with a fixed one.
    testbed.GetInputPort("arms_command").FixValue(
        ctx, JointGroupCommand.position(target, np.full(8, 200.0), np.full(8, 8.0))
    )
    simulator.AdvanceTo(1.5)
    q = testbed.GetOutputPort("joint_state").Eval(ctx)[Q_ARMS]
    assert q[0] == pytest.approx(target[0], abs=0.03)
    np.testing.assert_allclose(q[1:4], target[1:4], atol=0.05)


def test_velocity_mode_moves_the_joint():
    simulator, testbed, ctx = standing_simulator()
    values = np.zeros(8)
    values[4] = 1.0  # r_shoulder_y at 1 rad/s
    damping = np.minimum(80.0, testbed.stable_gain_limits()["arms"][1])  # stable at the step
    testbed.GetInputPort("arms_command").FixValue(
        ctx, JointGroupCommand.velocity(values, damping)
    )
    q0 = testbed.GetOutputPort("joint_state").Eval(ctx)[Q_ARMS][4]
    simulator.AdvanceTo(0.5)
    v = testbed.GetOutputPort("joint_state").Eval(ctx)[V_ARMS][4]
    q1 = testbed.GetOutputPort("joint_state").Eval(ctx)[Q_ARMS][4]
    # Damping-only drive: gravity on the raised arm leaves it somewhat below the command.
    assert q1 - q0 > 0.3
    assert 0.6 < v < 1.05


@pytest.mark.parametrize(
    "command, message",
    [
        (JointGroupCommand("effort", np.zeros(9)), "legs_command: values must have 10 entries"),
        (JointGroupCommand("torque", np.zeros(10)), "legs_command: unknown mode 'torque'"),
        (JointGroupCommand("effort", np.array([np.nan] + [0.0] * 9)), "legs_command: values contains NaN"),
        (JointGroupCommand("position", np.zeros(10), -np.ones(10)), "legs_command: stiffness must be non-negative"),
        ("effort", "legs_command: expected a JointGroupCommand"),
    ],
)
def test_bad_commands_raise_value_error_naming_the_port(command, message):
    simulator, testbed, ctx = _simulator()
    testbed.GetInputPort("legs_command").FixValue(ctx, command)
    with pytest.raises(ValueError, match=message.replace("(", r"\(")):
        simulator.AdvanceTo(0.01)


def test_excessive_gains_are_capped_not_unstable():
    simulator, testbed, ctx = standing_simulator()
    limits = testbed.stable_gain_limits()["arms"]
    target = load_robot_params().default_positions("arms")
    target[4] += 0.3
    testbed.GetInputPort("arms_command").FixValue(
        ctx, JointGroupCommand.position(target, np.full(8, 1e7), np.full(8, 1e5))
    )
    with pytest.warns(UserWarning, match="arms_command: (stiffness|damping) .* capped"):
        simulator.AdvanceTo(1.0)
    q = testbed.GetOutputPort("joint_state").Eval(ctx)[Q_ARMS]
    np.testing.assert_allclose(q, target, atol=0.02)
    assert np.all(limits[0] > 1e3) and np.all(limits[1] > 5)


def test_bad_config_is_rejected():
    with pytest.raises(ValueError, match="time_step"):
        build_testbed(TestbedConfig(time_step=-1))
    with pytest.raises(ValueError, match="camera.quality"):
        build_testbed(TestbedConfig(camera=CameraSettings(enabled=True, quality="ultra")))


def test_tamsi_is_refused_where_a_scene_drives_a_joint_by_pd():
    """Task 3's bar runs on a PD-controlled actuator, which Drake simulates with SAP only:
    under TAMSI the bar would stand still, so the testbed refuses the pair by name; a scene
    without such actuators still builds with it."""
    with pytest.raises(ValueError, match=r"'tamsi' cannot drive .*moving_bar_drive"):
        build_testbed(TestbedConfig(task=3, contact_approximation="tamsi"))
    tb = build_testbed(TestbedConfig(contact_approximation="tamsi"))
    assert not any(tb.plant.get_joint_actuator(i).has_controller()
                   for i in tb.plant.GetJointActuatorIndices())


def test_physics_step_is_the_tasks_unless_the_scenario_sets_one(tmp_path, monkeypatch):
    from pr2_drake.scenario import load_scenario
    from pr2_drake.tasks import get_task
    from pr2_drake.tasks.base import TaskSpec

    monkeypatch.setattr(get_task(5).spec, "time_step", 0.004)  # a task YAML's time_step
    assert TestbedConfig(task=5).time_step == 0.004
    assert load_scenario(None, ["task=5", "plant.time_step=0.001"]).testbed_config(
    ).time_step == 0.001
    monkeypatch.undo()

    assert TestbedConfig().time_step == DEFAULT_TIME_STEP == 0.004  # flat ground
    assert TestbedConfig(task=1).time_step == 0.004
    assert TestbedConfig(task="object_search").time_step == 0.002  # tasks/6_*.yaml
    assert load_scenario(None, ["task=6"]).testbed_config().time_step == 0.002
    assert load_scenario(None, ["task=1", "plant.time_step=0.001"]).testbed_config(
    ).time_step == 0.001
    bad = tmp_path / "9_bad.yaml"
    bad.write_text("id: 9\nname: bad\ntitle: Bad\ntime_limit: 5.0\ntime_step: 0.5\n"
                   "rubric: []\nstart_region: {center: [0, 0], size: [1, 1]}\n")
    with pytest.raises(ValueError, match=r"9_bad.yaml: time_step must be in \(0, 0.02\]"):
        TaskSpec.load(bad)


def test_camera_images_and_rate():
    cam = CameraSettings(enabled=True, width=64, height=48, fps=10.0, quality="low")
    simulator, testbed, ctx = standing_simulator(Scenario(camera=cam, seconds=math.inf))
    port = testbed.GetOutputPort("rgbd")
    simulator.AdvanceTo(0.02)
    frame = port.Eval(ctx)
    assert frame.color.shape == (48, 64, 3) and frame.color.dtype == np.uint8
    assert frame.depth.shape == (48, 64) and frame.depth.dtype == np.float32
    # The camera is pitched down: the ground fills the lower rows at a finite distance.
    bottom = frame.depth[-5:, :]
    assert np.all(np.isfinite(bottom)) and 0.3 < float(np.median(bottom)) < 5.0
    # Sampled at 10 Hz: the image is held between samples, even as the robot moves its arms.
    testbed.GetInputPort("arms_command").FixValue(
        ctx, JointGroupCommand.position(np.array([1.5, 0, 0.1, -0.3] * 2), np.full(8, 200.0))
    )
    simulator.AdvanceTo(0.09)
    np.testing.assert_array_equal(port.Eval(ctx).color, frame.color)

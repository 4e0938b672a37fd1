"""Task 2 (valve turning): rubric, pick volume, ball-mode and push turning, starts, falls."""

import numpy as np
import pytest
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
from pydrake.systems.framework import DiagramBuilder, LeafSystem
from pydrake.systems.primitives import ConstantValueSource

from conftest import wire_standing_legs
from pr2_drake.controllers.standing import StandingController
from pr2_drake.ports import JointGroupCommand
from pr2_drake.robot.params import ARM_JOINTS
from pr2_drake.scene import StartPose
from pr2_drake.tasks import get_task
from pr2_drake.tasks.t2_valve import in_pick_volume
from pr2_drake.episode import Episode
from pr2_drake.scenario import Scenario
from pr2_drake.testbed import Testbed, TestbedConfig

SPEC = get_task(2).spec
CENTER = np.asarray(SPEC.scene["valve"]["center"])
VOLUME = SPEC.scene["pick_volume"]


class ArmRamp(LeafSystem):
    """Arms in position mode: ``q0`` until t0, then a linear ramp to ``q1`` at t1."""

    __slots__ = ()  # keeps the diagram collectable (pr2_drake.lifetime)

    def __init__(self, q0, q1, t0, t1):
        super().__init__()
        self.q0, self.q1, self.t0, self.t1 = np.asarray(q0), np.asarray(q1), t0, t1
        self.DeclareAbstractOutputPort(
            "arms_command", lambda: AbstractValue.Make(JointGroupCommand()), self._calc)

    def _calc(self, context, output):
        s = np.clip((context.get_time() - self.t0) / (self.t1 - self.t0), 0.0, 1.0)
        output.set_value(JointGroupCommand.position(self.q0 + s * (self.q1 - self.q0),
                                                    [60.0] * 8, [3.0] * 8))


def rig(start: StartPose, arm0: dict | None = None, arm1: dict | None = None,
        pick: str = "", seed: int = 0):
    """Standing robot (legs), arms ramping from arm0 to arm1 between 0.5 and 2.0 s, a constant
    pick command. Returns (simulator, testbed, testbed context, plant context)."""
    st = StandingController()
    q_nom = dict(zip(ARM_JOINTS, st.policy.q_arms_d))
    q0 = {**q_nom, **(arm0 or {})}
    q1 = {**q0, **(arm1 or {})}
    arms = ArmRamp([q0[k] for k in ARM_JOINTS], [q1[k] for k in ARM_JOINTS], 0.5, 2.0)

    def wire(b, tb):
        wire_standing_legs(b, tb, st)
        b.AddSystem(arms)
        b.Connect(arms.get_output_port(), tb.GetInputPort("arms_command"))
        src = b.AddSystem(ConstantValueSource(AbstractValue.Make(pick)))
        b.Connect(src.get_output_port(), tb.GetInputPort("pick"))

    ep = Episode(Scenario(task=2, seed=seed, start=start), wire)
    tb, pc = ep.testbed, ep.plant_context
    for k, v in q0.items():  # start the arms at their first target (no transient)
        tb.plant.GetJointByName(k).set_angle(pc, v)
    ep.simulator.Initialize()
    return ep.simulator, tb, ep.tb_context, pc


def new_plant():
    plant, _ = AddMultibodyPlantSceneGraph(DiagramBuilder(), 0.001)
    return plant


def episode(tb, ctx):
    return tb.GetOutputPort("episode").Eval(ctx)


def valve_deg(tb, pc) -> float:
    return float(np.degrees(tb.plant.GetJointByName("valve_joint").get_angle(pc)))


# Right hand 0.20 m from the axis, 0.07 m above the wheel plane (inside the pick volume).
BALL_START = StartPose(-0.584, 0.315, 0.0)
ARM_IN_VOLUME = {"r_shoulder_y": 0.9, "r_elbow": -0.8}
ARM_ABOVE_VOLUME = {"r_shoulder_y": 1.2, "r_elbow": -1.2}  # same place, 0.25 m above the plane


# -- rubric ------------------------------------------------------------------------------------
def test_walk_into_task_region_awards_5():
    sim, tb, ctx, pc = rig(StartPose(-1.6, 0.0, 0.0))
    sim.AdvanceTo(0.05)
    assert episode(tb, ctx).score == 0.0  # the start region is outside the task region
    base = tb.plant.GetBodyByName("base_link")
    X = tb.plant.EvalBodyPoseInWorld(pc, base)
    tb.plant.SetFreeBodyPose(pc, base, RigidTransform(X.rotation(), [-0.7, 0.0,
                                                                      X.translation()[2]]))
    sim.AdvanceTo(0.1)
    ep = episode(tb, ctx)
    assert ep.earned("task_region") and ep.score == 5.0


def test_valve_angle_thresholds():
    sim, tb, ctx, pc = rig(StartPose(-1.6, 0.0, 0.0))
    joint = tb.plant.GetJointByName("valve_joint")
    joint.set_angle(pc, np.radians(3.0))  # below the 5 deg threshold: nothing
    joint.set_angular_rate(pc, 0.0)
    sim.AdvanceTo(0.03)
    assert episode(tb, ctx).score == 0.0
    joint.set_angle(pc, np.radians(-10.0))  # either direction counts
    sim.AdvanceTo(0.06)
    ep = episode(tb, ctx)
    assert ep.earned("turn_valve") and not ep.earned("turn_valve_45") and ep.score == 5.0
    joint.set_angle(pc, np.radians(50.0))
    sim.AdvanceTo(0.09)
    ep = episode(tb, ctx)
    assert ep.earned("turn_valve_45") and ep.score == 10.0
    assert not ep.done


def test_pick_volume_predicate():
    c = CENTER
    assert in_pick_volume(c + [0.29, 0.0, 0.0], c, VOLUME)
    assert in_pick_volume(c + [0.2, -0.2, 0.14], c, VOLUME)  # horizontal 0.283
    assert not in_pick_volume(c + [0.25, 0.2, 0.0], c, VOLUME)  # horizontal 0.32
    assert not in_pick_volume(c + [0.1, 0.0, 0.16], c, VOLUME)  # above the band
    assert not in_pick_volume(c + [0.1, 0.0, -0.11], c, VOLUME)  # below the band


def test_pick_outside_volume_does_not_latch():
    # Same stance as the latching test, hand 0.25 m above the wheel plane.
    sim, tb, ctx, pc = rig(BALL_START, ARM_ABOVE_VOLUME, pick="right_hand")
    p_WH = tb.plant.GetBodyByName("r_arm_sphere").EvalPoseInWorld(pc).translation()
    assert np.hypot(*(p_WH - CENTER)[:2]) < VOLUME["radius"]
    sim.AdvanceTo(0.2)
    assert not tb.GetOutputPort("pick_state").Eval(ctx).attached
    # Far away (the seeded start): no latch either.
    sim, tb, ctx, pc = rig(StartPose(-1.6, 0.0, 0.0), pick="left_hand")
    sim.AdvanceTo(0.1)
    assert not tb.GetOutputPort("pick_state").Eval(ctx).attached


# -- grasp physics -----------------------------------------------------------------------------
def test_ball_pick_turns_valve_with_the_hand():
    # Pick inside the volume, then abduct the right arm: the hand moves along the rim.
    sim, tb, ctx, pc = rig(BALL_START, ARM_IN_VOLUME, {"r_shoulder_x": 0.5}, pick="right_hand")
    sim.AdvanceTo(0.1)
    p = tb.GetOutputPort("pick_state").Eval(ctx)
    assert p.attached and p.object == "valve" and p.hand == "right_hand"
    assert tb.GetOutputPort("task_feedback").Eval(ctx)["pick_state"]["object"] == "valve"
    hand = tb.plant.GetBodyByName("r_arm_sphere")
    wheel = tb.plant.GetBodyByName("valve_wheel")
    X_WO = wheel.EvalPoseInWorld(pc)
    p_OA = X_WO.inverse().multiply(hand.EvalPoseInWorld(pc).translation())
    sim.AdvanceTo(2.5)
    angle = valve_deg(tb, pc)
    assert angle > 15.0  # the hand moved -y at the wheel's -x side: positive about +z
    # The held point of the wheel stays at the hand (rotation free, position held).
    p_WA = wheel.EvalPoseInWorld(pc).multiply(p_OA)
    assert np.linalg.norm(p_WA - hand.EvalPoseInWorld(pc).translation()) < 0.02
    ep = episode(tb, ctx)
    assert ep.earned("turn_valve") and not ep.done


def test_push_with_the_hand_turns_valve_without_pick():
    # The hand sits beside the spinner handle; abducting the arm sweeps it into the handle.
    sim, tb, ctx, pc = rig(StartPose(-0.636, 0.285, 0.0), ARM_IN_VOLUME, {"r_shoulder_x": 0.6})
    sim.AdvanceTo(0.4)
    assert abs(valve_deg(tb, pc)) < 0.5  # not touching yet
    sim.AdvanceTo(2.5)
    assert valve_deg(tb, pc) > 10.0
    assert not tb.GetOutputPort("pick_state").Eval(ctx).attached
    assert episode(tb, ctx).earned("turn_valve")


def test_valve_friction_stops_a_spinning_wheel():
    sim, tb, ctx, pc = rig(StartPose(-1.6, 0.0, 0.0))
    joint = tb.plant.GetJointByName("valve_joint")
    joint.set_angular_rate(pc, 2.0)
    sim.AdvanceTo(1.5)
    assert abs(joint.get_angular_rate(pc)) < 0.05
    # Damping + Coulomb torque (0.4 * w + 0.6 Nm) on ~0.16 kg m^2: the wheel coasts < 1 rad.
    assert 0.1 < joint.get_angle(pc) < 1.0


# -- start, priors, termination ----------------------------------------------------------------
def test_start_poses_over_100_seeds():
    task = get_task(2)
    (cx, cy), (dx, dy) = SPEC.start_region["center"], SPEC.start_region["size"]
    starts = []
    for seed in range(100):
        scene = task.build_scene(new_plant(), np.random.default_rng(seed))
        s = scene.start
        assert abs(s.x - cx) <= dx / 2 and abs(s.y - cy) <= dy / 2
        assert abs(np.degrees(s.yaw) - SPEC.nominal_heading_deg) <= SPEC.heading_noise_deg
        starts.append((s.x, s.y, s.yaw))
    assert len(set(starts)) == 100  # different seeds differ
    again = task.build_scene(new_plant(), np.random.default_rng(7)).start
    assert (again.x, again.y, again.yaw) == starts[7]  # same seed, same start


def test_priors_describe_the_valve():
    tb = Testbed(TestbedConfig(task=2, seed=3))
    pri = tb.scene.priors
    assert pri["valve_id"] == "valve"
    assert np.allclose(pri["valve_center"], CENTER)
    assert pri["valve_dimensions"]["diameter"] == pytest.approx(0.54)
    wheel = tb.plant.GetBodyByName("valve_wheel")
    ctx = tb.plant.CreateDefaultContext()
    assert np.allclose(wheel.EvalPoseInWorld(ctx).translation(), CENTER)


def test_fall_ends_episode_with_fell_and_keeps_score():
    sim, tb, ctx, pc = rig(StartPose(-0.7, 0.0, 0.0))  # inside the task region
    sim.AdvanceTo(0.05)
    assert episode(tb, ctx).score == 5.0
    base = tb.plant.GetBodyByName("base_link")
    tb.plant.SetFreeBodyPose(pc, base, RigidTransform(RollPitchYaw(np.pi / 2, 0, 0),
                                                      [-0.9, 0.0, 0.15]))
    sim.AdvanceTo(0.1)
    ep = episode(tb, ctx)
    assert ep.done and ep.termination == "fell" and not ep.success
    assert ep.score == 5.0

"""Task 6 (object search): rubric, 0.20 m pick rule, carrying and dropping, layout draws."""

import numpy as np
import pytest
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform, RollPitchYaw
from pathlib import Path

from pydrake.multibody.math import SpatialVelocity
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
from pydrake.systems.framework import DiagramBuilder, LeafSystem

from pr2_drake.camera import CameraSettings
from conftest import wire_standing_legs
from pr2_drake.controllers.standing import StandingController
from pr2_drake.ports import JointGroupCommand
from pr2_drake.robot.params import ARM_JOINTS
from pr2_drake.scene import StartPose
from pr2_drake.tasks import get_task
from pr2_drake.tasks.house import add_house
from pr2_drake.tasks.regions import region_from_yaml
from pr2_drake.tasks.t6_object_search import model_extent
from pr2_drake.episode import Episode
from pr2_drake.scenario import Scenario
from pr2_drake.testbed import Testbed, TestbedConfig

TASK = get_task(6)
SPEC = TASK.spec
SCENE = SPEC.scene
NO_CAMERA = CameraSettings(enabled=False)  # the user's choice overrides the task's camera
NEAR_TABLE = StartPose(-2.0, -1.3, -np.pi / 2)  # in the coffee table region, facing it
AWAY = StartPose(-2.0, -0.6, 0.0)  # living room, outside the table region


class Commands(LeafSystem):
    """Arms ramp q0 -> q1 over [t0, t1]; pick with the right hand until t_release, then
    release."""

    __slots__ = ()  # keeps the diagram collectable (pr2_drake.lifetime)

    def __init__(self, q0, q1, t0=0.3, t1=1.0, t_release=np.inf, hand="right_hand"):
        super().__init__()
        self.q0, self.q1, self.t0, self.t1 = np.asarray(q0), np.asarray(q1), t0, t1
        self.t_release, self.hand = t_release, hand
        self.DeclareAbstractOutputPort(
            "arms_command", lambda: AbstractValue.Make(JointGroupCommand()), self._arms)
        self.DeclareAbstractOutputPort("pick", lambda: AbstractValue.Make(""), self._pick)
        self.DeclareAbstractOutputPort("release", lambda: AbstractValue.Make(False),
                                       self._release)

    def _arms(self, context, output):
        s = np.clip((context.get_time() - self.t0) / (self.t1 - self.t0), 0.0, 1.0)
        output.set_value(JointGroupCommand.position(self.q0 + s * (self.q1 - self.q0),
                                                    [60.0] * 8, [3.0] * 8))

    def _pick(self, context, output):
        output.set_value(self.hand if context.get_time() < self.t_release else "")

    def _release(self, context, output):
        output.set_value(bool(context.get_time() >= self.t_release))


def rig(start: StartPose, seed: int = 0, arm1: dict | None = None, hand: str = "",
        t_release: float = np.inf, camera: CameraSettings | None = NO_CAMERA):
    st = StandingController()
    q0 = dict(zip(ARM_JOINTS, st.policy.q_arms_d))
    q1 = {**q0, **(arm1 or {})}
    cmd = Commands([q0[k] for k in ARM_JOINTS], [q1[k] for k in ARM_JOINTS],
                   t_release=t_release, hand=hand)

    def wire(b, tb):
        wire_standing_legs(b, tb, st)
        b.AddSystem(cmd)
        for n in ("arms_command", "pick", "release"):
            b.Connect(cmd.GetOutputPort(n), tb.GetInputPort(n))

    ep = Episode(Scenario(task=6, seed=seed, start=start, camera=camera), wire)
    ep.simulator.Initialize()
    return ep.simulator, ep.testbed, ep.tb_context, ep.plant_context


def body(tb, name):
    return tb.plant.get_body(tb.scene.data["bodies"][name])


def hand_position(tb, pc):
    return tb.plant.GetBodyByName("r_arm_sphere").EvalPoseInWorld(pc).translation()


def put(tb, pc, name, p):
    tb.plant.SetFreeBodyPose(pc, body(tb, name), RigidTransform(np.asarray(p, float)))
    tb.plant.SetFreeBodySpatialVelocity(pc, body(tb, name),
                                        SpatialVelocity(np.zeros(3), np.zeros(3)))


def put_near_hand(tb, pc, name, distance):
    """Place object ``name`` ``distance`` [m] in front of (and level with) the right hand."""
    yaw = RollPitchYaw(tb.plant.GetBodyByName("base_link").EvalPoseInWorld(pc).rotation()).yaw_angle()
    p = hand_position(tb, pc) + distance * np.array([np.cos(yaw), np.sin(yaw), 0.0])
    put(tb, pc, name, p)
    return p


def episode(tb, ctx):
    return tb.GetOutputPort("episode").Eval(ctx)


def pick_state(tb, ctx):
    return tb.GetOutputPort("pick_state").Eval(ctx)


# -- rubric ------------------------------------------------------------------------------------
def test_walk_to_pick_region_awards_5_only_near_the_target():
    sim, tb, ctx, pc = rig(AWAY, seed=1)
    sim.AdvanceTo(0.03)
    assert episode(tb, ctx).score == 0.0  # the target is in another room
    target = tb.scene.data["target"]
    p = body(tb, target).EvalPoseInWorld(pc).translation()
    base = tb.plant.GetBodyByName("base_link")
    X = base.EvalPoseInWorld(pc)
    r = SCENE["pick_region_radius"]
    # Just outside the region, then just inside (horizontal distance to the target).
    for d, expected in ((r + 0.1, 0.0), (r - 0.1, 5.0)):
        tb.plant.SetFreeBodyPose(pc, base, RigidTransform(X.rotation(),
                                                          [p[0], p[1] + d, X.translation()[2]]))
        sim.AdvanceTo(sim.get_context().get_time() + 0.03)
        assert episode(tb, ctx).score == expected
    assert episode(tb, ctx).earned("pick_region")


def test_pick_target_within_0_2_m_awards_10():
    sim, tb, ctx, pc = rig(NEAR_TABLE, seed=2, hand="right_hand")
    target = tb.scene.data["target"]
    p = put_near_hand(tb, pc, target, 0.15)
    sim.AdvanceTo(0.05)
    st = pick_state(tb, ctx)
    assert st.attached and st.object == target and st.hand == "right_hand"
    ep = episode(tb, ctx)
    assert ep.earned("pick_target")
    # The robot stands in the coffee-table region holding the target: walk-to-table too.
    assert ep.earned("table_region")
    assert ep.score == 10 + 5 + 5  # pick_target, table_region, pick_region (target at hand)
    assert np.linalg.norm(body(tb, target).EvalPoseInWorld(pc).translation() - p) < 0.02


def test_no_pick_beyond_0_2_m():
    sim, tb, ctx, pc = rig(NEAR_TABLE, seed=2, hand="right_hand")
    target = tb.scene.data["target"]
    put_near_hand(tb, pc, target, 0.23)
    sim.AdvanceTo(0.03)
    assert not pick_state(tb, ctx).attached
    ep = episode(tb, ctx)
    assert not ep.earned("pick_target") and not ep.earned("table_region")


def test_picking_a_non_target_object_earns_nothing():
    sim, tb, ctx, pc = rig(NEAR_TABLE, seed=2, hand="right_hand")
    target = tb.scene.data["target"]
    other = next(n for n in SCENE["objects"] if n != target)
    put_near_hand(tb, pc, other, 0.1)
    sim.AdvanceTo(0.05)
    st = pick_state(tb, ctx)
    assert st.attached and st.object == other
    ep = episode(tb, ctx)
    assert ep.score == 0.0 and not ep.earned("pick_target") and not ep.earned("table_region")


def test_nearest_object_is_picked():
    sim, tb, ctx, pc = rig(NEAR_TABLE, seed=2, hand="right_hand")
    target = tb.scene.data["target"]
    other = next(n for n in SCENE["objects"] if n != target)
    put_near_hand(tb, pc, other, 0.18)
    put_near_hand(tb, pc, target, -0.12)  # behind the hand, but nearer
    sim.AdvanceTo(0.03)
    assert pick_state(tb, ctx).object == target


def test_walk_to_table_needs_the_target_in_hand():
    sim, tb, ctx, pc = rig(NEAR_TABLE, seed=2)
    sim.AdvanceTo(0.1)
    assert not episode(tb, ctx).earned("table_region")


def test_place_on_coffee_table_awards_5_and_floor_does_not():
    sim, tb, ctx, pc = rig(AWAY, seed=3)
    target = tb.scene.data["target"]
    top = np.asarray(tb.scene.priors["coffee_table_center"])
    half_h, _ = model_extent(tb.scene.priors["object_models"][target]["sdf"])
    # Released on the floor of the living room: no points.
    put(tb, pc, target, [-3.0, -0.6, half_h + 0.003])
    sim.AdvanceTo(0.6)
    assert episode(tb, ctx).score == 0.0
    # On the (USD-imported) coffee table's top: it rests there and earns the place points.
    put(tb, pc, target, [top[0] + 0.2, top[1] - 0.1, top[2] + half_h + 0.003])
    sim.AdvanceTo(1.2)
    p = body(tb, target).EvalPoseInWorld(pc).translation()
    assert p[2] == pytest.approx(top[2] + half_h, abs=0.01)  # resting on the table top
    ep = episode(tb, ctx)
    assert ep.earned("place_on_table") and ep.score == 5.0


# -- grasp physics -----------------------------------------------------------------------------
def test_picked_object_follows_hand_and_drops_when_released():
    # Pick, raise the right arm forward (0.3..1.0 s), release at 1.3 s.
    sim, tb, ctx, pc = rig(AWAY, seed=4, arm1={"r_shoulder_y": 1.2}, hand="right_hand",
                           t_release=1.3)
    target = tb.scene.data["target"]
    p0 = put_near_hand(tb, pc, target, 0.12)
    sim.AdvanceTo(0.1)
    assert pick_state(tb, ctx).attached
    offset0 = body(tb, target).EvalPoseInWorld(pc).translation() - hand_position(tb, pc)
    sim.AdvanceTo(1.25)
    p1 = body(tb, target).EvalPoseInWorld(pc).translation()
    offset1 = p1 - hand_position(tb, pc)
    assert p1[2] - p0[2] > 0.15  # lifted with the hand
    assert np.linalg.norm(offset1) == pytest.approx(np.linalg.norm(offset0), abs=0.03)
    sim.AdvanceTo(1.35)
    assert not pick_state(tb, ctx).attached
    sim.AdvanceTo(1.6)
    p2 = body(tb, target).EvalPoseInWorld(pc).translation()
    v2 = tb.plant.EvalBodySpatialVelocityInWorld(pc, body(tb, target)).translational()
    assert p2[2] < p1[2] - 0.1 and v2[2] < -0.5  # falling under gravity
    sim.AdvanceTo(2.3)
    half_h, _ = model_extent(tb.scene.priors["object_models"][target]["sdf"])
    assert body(tb, target).EvalPoseInWorld(pc).translation()[2] < 0.3  # down on the floor
    assert not episode(tb, ctx).earned("place_on_table")


# -- layout, start, sentence, camera -----------------------------------------------------------
def _tables():
    plant, _ = AddMultibodyPlantSceneGraph(DiagramBuilder(), 0.001)
    return add_house(plant, SCENE)


def test_layout_and_start_over_100_seeds():
    tables = _tables()
    draws = [TASK.draw_episode(tables, np.random.default_rng(seed)) for seed in range(100)]
    targets, sentences, starts = set(), set(), set()
    for target, poses, sentence, start in draws:
        room = tables[SCENE["objects"][target]["table"]].room
        room_rect = region_from_yaml(SCENE["rooms"][room]["rect"])
        start_rect = region_from_yaml(SCENE["rooms"][room]["start"])
        assert room_rect.contains((start.x, start.y)) and start_rect.contains((start.x, start.y))
        nominal = SCENE["rooms"][room]["start"]["heading_deg"]
        assert abs(np.degrees(start.yaw) - nominal) <= SPEC.heading_noise_deg
        assert SCENE["objects"][target]["label"] in sentence
        p = poses[target].translation()  # the start never earns pick_region by itself
        assert np.hypot(p[0] - start.x, p[1] - start.y) > SCENE["pick_region_radius"]
        for name, X in poses.items():
            t = tables[SCENE["objects"][name]["table"]]
            inner = t.grown(-SCENE["placement_margin"] + 1e-9)
            assert inner.contains(X.translation())
            assert X.translation()[2] > t.height
        targets.add(target)
        sentences.add(sentence)
        starts.add((start.x, start.y, start.yaw))
    assert targets == set(SCENE["candidates"])
    assert len(starts) == 100 and len(sentences) > 20
    # Same seed, same draw.
    t2, p2, s2, st2 = TASK.draw_episode(tables, np.random.default_rng(5))
    t1, p1, s1, st1 = draws[5]
    assert (t1, s1, st1) == (t2, s2, st2)
    assert all(np.allclose(p1[n].GetAsMatrix4(), p2[n].GetAsMatrix4()) for n in p1)


def test_built_scene_matches_the_draw_and_is_seeded():
    tb = Testbed(TestbedConfig(task=6, seed=11, camera=NO_CAMERA))
    target, poses, sentence, start = TASK.draw_episode(_tables(), np.random.default_rng(11))
    assert tb.scene.data["target"] == target and tb.scene.start == start
    ctx = tb.CreateDefaultContext()
    assert tb.GetOutputPort("instruction").Eval(ctx) == sentence
    assert tb.scene.priors["instruction"] == sentence
    pc = tb.plant.GetMyContextFromRoot(ctx)
    for name, X in poses.items():
        assert np.allclose(body(tb, name).EvalPoseInWorld(pc).translation(), X.translation())
    other = Testbed(TestbedConfig(task=6, seed=12, camera=NO_CAMERA))
    assert other.scene.start != tb.scene.start


def test_priors_list_nine_object_models():
    tb = Testbed(TestbedConfig(task=6, seed=0, camera=NO_CAMERA))
    models = tb.scene.priors["object_models"]
    assert len(models) == 9 and {"cup", "teddy_bear", "cube"} <= set(models)
    for m in models.values():
        assert Path(m["sdf"]).is_file() and Path(m["mesh"]).is_file()
    assert np.allclose(tb.scene.priors["coffee_table_center"], [-2.0, -2.0, 0.45])


def test_task_turns_the_head_camera_on_unless_the_user_sets_it():
    sim, tb, ctx, pc = rig(NEAR_TABLE, seed=0, camera=None)  # user left it to the task
    assert tb.has_camera() and tb.HasOutputPort("rgbd")
    sim.AdvanceTo(0.02)  # the sensor holds its first frame from t = 0
    frame = tb.GetOutputPort("rgbd").Eval(ctx)
    assert frame.color.shape == (480, 640, 3) and frame.depth.shape == (480, 640)
    # Facing the coffee table from 0.7 m: the centre pixel sees something within ~2 m.
    assert 0.3 < frame.depth[240, 320] < 2.0 and frame.color.std() > 10
    small = Testbed(TestbedConfig(task=6, seed=0, camera=CameraSettings(enabled=True, width=160,
                                                                        height=120)))
    assert small.GetOutputPort("rgbd").Eval(small.CreateDefaultContext()).color.shape == (120,
                                                                                          160, 3)
    assert not Testbed(TestbedConfig(task=6, seed=0, camera=NO_CAMERA)).has_camera()


def test_fall_ends_episode_with_fell_and_keeps_score():
    sim, tb, ctx, pc = rig(AWAY, seed=1)
    target = tb.scene.data["target"]
    half_h, _ = model_extent(tb.scene.priors["object_models"][target]["sdf"])
    put(tb, pc, target, [AWAY.x + 0.5, AWAY.y - 0.3, half_h + 0.003])  # target beside the robot
    sim.AdvanceTo(0.05)
    assert episode(tb, ctx).score == 5.0  # pick_region
    base = tb.plant.GetBodyByName("base_link")
    tb.plant.SetFreeBodyPose(pc, base, RigidTransform(RollPitchYaw(np.pi / 2, 0, 0),
                                                      [AWAY.x, AWAY.y, 0.15]))
    sim.AdvanceTo(0.1)
    ep = episode(tb, ctx)
    assert ep.done and ep.termination == "fell" and not ep.success
    assert ep.score == 5.0

"""Object sleeping (pr2_drake/sleep.py): resting objects sleep bit-still, wake without a jump
when the robot comes near, decide at the same simulated times under any chunking, and
``sleep.enabled: false`` is today's physics."""

import math

import numpy as np
import pytest
from pydrake.math import RigidTransform
from pydrake.multibody.math import SpatialVelocity

from pr2_drake.camera import CameraSettings
from pr2_drake.controllers.standing import StandingController
from pr2_drake.env import Env
from pr2_drake.episode import Episode, wire_system
from pr2_drake.scenario import Scenario, ScenarioError, load_scenario
from pr2_drake.scene import StartPose
from pr2_drake.sleep import ObjectSleeper, SleepSettings

NO_CAMERA = CameraSettings(enabled=False)
ALL = ["apple", "book", "bottle", "bowl", "cube", "cup", "pencil_box", "teddy_bear", "toy_car"]
MIDDLE = StartPose(0.0, 0.0, 0.0)  # the house's centre: at least 1 m from every table


def standing(seed=0, start=MIDDLE, sleep=None, wire=None):
    scenario = Scenario(task=6, seed=seed, camera=NO_CAMERA, seconds=math.inf, start=start,
                        sleep=sleep or SleepSettings())
    ep = Episode(scenario, wire or wire_system(StandingController()))
    ep.initialize()
    return ep


def object_states(ep):
    """{name: (q (7), v (6))} of every object."""
    plant, pc = ep.testbed.plant, ep.plant_context
    out = {}
    for g in ep.testbed.scene.graspables:
        body = plant.get_body(g.body)
        out[g.name] = (plant.GetPositions(pc, body.model_instance()).copy(),
                       plant.GetVelocities(pc, body.model_instance()).copy())
    return out


def object_contacts(ep) -> int:
    """Point contacts that involve an object's body."""
    plant = ep.testbed.plant
    bodies = {g.body for g in ep.testbed.scene.graspables}
    results = plant.get_contact_results_output_port().Eval(ep.plant_context)
    n = 0
    for k in range(results.num_point_pair_contacts()):
        c = results.point_pair_contact_info(k)
        n += c.bodyA_index() in bodies or c.bodyB_index() in bodies
    return n


def test_resting_objects_sleep_bit_still_where_they_would_have_rested():
    ep = standing()
    ep.advance_to(1.2)  # they settle (spawned 2 mm high) and rest 0.5 s
    assert ep.sleeper.sleeping == ALL
    assert object_contacts(ep) == 0
    asleep = object_states(ep)
    ep.advance_to(2.2)
    for name, (q, v) in object_states(ep).items():
        np.testing.assert_array_equal(q, asleep[name][0])  # bit for bit
        assert not v.any()
    assert ep.status.score == 0 and not ep.status.done
    # Without sleeping they rest at the same places (within 1 mm, 1 mrad) with contacts.
    off = standing(sleep=SleepSettings(enabled=False))
    off.advance_to(2.2)
    assert off.sleeper.sleeping == [] and object_contacts(off) >= 9
    for name, (q, _) in object_states(off).items():
        assert np.linalg.norm(q[4:] - asleep[name][0][4:]) < 1e-3
        assert np.linalg.norm(q[:4] - asleep[name][0][:4]) < 1e-3
    assert off.status.score == ep.status.score


def beside(table, p_WO, gap):
    """A base pose (x, y, yaw) beside ``table``, facing the object at p_WO, ``gap`` [m] off
    the table's nearest edge to it."""
    c, half = np.asarray(table.center), np.asarray(table.size) / 2
    d = p_WO[:2] - c
    axis = int(np.argmax(np.abs(d) / half))  # leave by the edge nearest the object
    p = p_WO[:2].copy()
    p[axis] = c[axis] + np.sign(d[axis]) * (half[axis] + gap)
    yaw = math.atan2(*(p_WO[:2] - p)[::-1])
    return p, yaw


def teleport_base(ep, xy, yaw):
    plant, pc = ep.testbed.plant, ep.plant_context
    base = plant.GetBodyByName("base_link")
    X = base.EvalPoseInWorld(pc)
    z = X.translation()[2]
    from pydrake.math import RollPitchYaw

    rpy = RollPitchYaw(X.rotation())
    plant.SetFreeBodyPose(pc, base, RigidTransform(
        RollPitchYaw(rpy.roll_angle(), rpy.pitch_angle(), yaw), [xy[0], xy[1], z]))
    plant.SetFreeBodySpatialVelocity(pc, base, SpatialVelocity(np.zeros(3), np.zeros(3)))


def test_the_robot_coming_near_wakes_objects_that_keep_resting():
    ep = standing(seed=0)
    ep.advance_to(1.2)
    assert ep.sleeper.sleeping == ALL
    target = ep.testbed.scene.data["target"]
    tables = ep.testbed.scene.data["tables"]
    key = ep.testbed.task.spec.scene["objects"][target]["table"]
    table = tables[key]
    before = object_states(ep)
    xy, yaw = beside(table, before[target][0][4:], gap=0.3)
    teleport_base(ep, xy, yaw)
    ep.advance_to(1.22)  # the next check
    assert target not in ep.sleeper.sleeping
    ep.advance_to(1.23)
    assert object_contacts(ep) >= 1  # its contacts are back
    ep.advance_to(1.7)
    after = object_states(ep)
    assert np.linalg.norm(after[target][0][4:] - before[target][0][4:]) < 1e-3  # no jump
    assert np.linalg.norm(after[target][1]) < 0.01
    # Objects on other tables sleep on.
    others = [n for n in ALL if ep.testbed.task.spec.scene["objects"][n]["table"] != key]
    assert set(others) <= set(ep.sleeper.sleeping)
    assert not ep.status.done


def test_a_sleeping_object_teleported_into_the_hand_is_picked_and_carried():
    """The pick of test_task6 (latched within 0.20 m) on an object asleep until then."""
    from test_task6 import Commands, put_near_hand
    from conftest import wire_standing_legs
    from pr2_drake.robot.params import ARM_JOINTS

    st = StandingController()
    q0 = dict(zip(ARM_JOINTS, st.policy.q_arms_d))
    q1 = {**q0, "r_shoulder_y": 1.2}
    cmd = Commands([q0[k] for k in ARM_JOINTS], [q1[k] for k in ARM_JOINTS], t0=1.3, t1=2.0,
                   hand="right_hand")

    def wire(b, tb):
        wire_standing_legs(b, tb, st)
        b.AddSystem(cmd)
        for n in ("arms_command", "pick", "release"):
            b.Connect(cmd.GetOutputPort(n), tb.GetInputPort(n))

    ep = standing(seed=4, wire=wire)
    ep.advance_to(1.2)
    target = ep.testbed.scene.data["target"]
    assert target in ep.sleeper.sleeping
    p0 = put_near_hand(ep.testbed, ep.plant_context, target, 0.12)
    ep.advance_to(1.25)
    pick = ep.testbed.GetOutputPort("pick_state").Eval(ep.tb_context)
    assert pick.attached and pick.object == target
    assert target not in ep.sleeper.sleeping
    ep.advance_to(2.2)
    p1 = object_states(ep)[target][0][4:]
    assert p1[2] - p0[2] > 0.15  # lifted with the hand
    assert ep.status.earned("pick_target")


def test_same_state_whatever_the_chunks():
    states = []
    for dt in (0.013, 0.1):
        ep = standing(seed=1)
        while ep.time < 1.3 - 1e-9:
            ep.advance_to(min(ep.time + dt, 1.3))
        states.append((ep.plant_context.get_discrete_state_vector().value().copy(),
                       ep.sleeper.sleeping))
    assert states[0][1] and states[0][1] == states[1][1]
    np.testing.assert_array_equal(states[0][0], states[1][0])


def test_disabled_is_the_physics_without_sleeping():
    ep = standing(sleep=SleepSettings(enabled=False))
    assert not ep.sleeper.active
    ep.advance_to(1.3)
    plain = standing(sleep=SleepSettings(enabled=False))
    plain.simulator.AdvanceTo(1.3)  # no Episode stops at all: today's physics
    np.testing.assert_array_equal(ep.plant_context.get_discrete_state_vector().value(),
                                  plain.plant_context.get_discrete_state_vector().value())
    sg = ep.testbed.scene_graph
    assert not sg.collision_filter_manager(sg.GetMyContextFromRoot(ep.context)) \
        .has_transient_history()
    # Without free objects (task 1) the sleeper has nothing to do either.
    flat = Episode(Scenario(task=1, seed=0, seconds=1.0), wire_system(StandingController()))
    assert not flat.sleeper.active


def test_env_reset_wakes_everything():
    env = Env(task=6, seed=0, control_dt=0.05,
              scenario=Scenario(task=6, camera=NO_CAMERA, start=MIDDLE))
    from pr2_drake.agents.standing import StandingAgent

    agent = StandingAgent()
    obs = env.reset()
    for _ in range(24):
        _, _, obs = env.step(agent.next_action(obs))
    ep = env.episode
    assert ep.sleeper.sleeping == ALL
    env.reset()
    assert ep.sleeper.sleeping == []
    grasp = ep.testbed.grasp
    assert grasp.sleeping(grasp.GetMyContextFromRoot(ep.context)) == ()
    env.step(agent.next_action(env.observation()))
    assert object_contacts(ep) >= 9


@pytest.mark.parametrize("field, value", [
    ("check_period", 0.0), ("rest_speed", -1.0), ("rest_time", math.nan),
    ("wake_distance", "far"), ("sleep_distance", 0.1), ("enabled", "yes")])
def test_bad_settings_name_the_field(field, value):
    with pytest.raises(ScenarioError, match=f"sleep.{field}"):
        Scenario(task=6, sleep=SleepSettings(**{field: value})).validate()
    with pytest.raises(ValueError, match=f"sleep.{field}"):
        ObjectSleeper(None, SleepSettings(**{field: value}))


def test_scenario_yaml_turns_sleeping_off():
    s = load_scenario(overrides=["task=6", "sleep.enabled=false", "sleep.rest_time=0.3"])
    assert s.sleep == SleepSettings(enabled=False, rest_time=0.3)
    assert "sleep:" in s.dump()

"""Task 5 (steps and button): start sampling, geometry, step items, button presses, endings."""

import numpy as np
import pytest

from pr2_drake.tasks import get_task
from tests._locomotion_sim import (
    TaskSim,
    assert_starts_in_region,
    min_distance_to_terrain,
    scene_geometry,
)

SPEC = get_task(5).spec
STEPS = SPEC.scene["steps"]
PRESS = SPEC.scene["press_time"]
FLOOR_Z = STEPS["count"] * STEPS["height"]


def test_spec_matches_tasks_md():
    assert SPEC.time_limit == 240.0 and SPEC.max_score == 20.0
    assert {r.item: r.points for r in SPEC.rubric} == {
        "onto_step": 5, "over_steps": 5, "touch_button": 5, "touch_button_arm": 5}
    assert (STEPS["height"], STEPS["width"]) == (0.10, 2.0) and STEPS["count"] >= 2
    assert PRESS == 0.2 and SPEC.heading_noise_deg == 0.0


def test_start_poses_in_region_without_heading_noise_and_seeded():
    assert_starts_in_region(SPEC)
    _, a, *_ = scene_geometry(5, seed=8)
    _, b, *_ = scene_geometry(5, seed=8)
    _, c, *_ = scene_geometry(5, seed=9)
    assert (a.start.x, a.start.y) == (b.start.x, b.start.y) != (c.start.x, c.start.y)


def test_steps_geometry_matches_ground_height_and_priors():
    _, scene, plant, sg, diagram, ctx = scene_geometry(5, seed=0)
    gh = scene.ground_height
    x0, d, h = STEPS["start_x"], STEPS["depth"], STEPS["height"]
    assert gh(x0 - 0.2, 0.0) == 0.0
    assert gh(x0 + 0.5 * d, 0.5) == pytest.approx(h)
    assert gh(x0 + 1.5 * d, -0.5) == pytest.approx(2 * h)
    assert gh(x0 + STEPS["count"] * d + 0.5, 0.0) == pytest.approx(FLOOR_Z)
    for x, y in [(x0 - 0.3, 0.2), (x0 + 0.2, 0.9), (x0 + 0.6, -0.4), (x0 + 1.2, 0.0),
                 (x0 + 2.0, -0.9)]:
        z = gh(x, y)
        assert abs(min_distance_to_terrain(plant, sg, diagram, ctx, [x, y, z])) < 1e-6
        assert min_distance_to_terrain(plant, sg, diagram, ctx, [x, y, z + 0.02]) > 0.015
    p = scene.priors
    assert set(p) == set(SPEC.priors)
    assert (p["step_height"], p["step_depth"], p["step_width"], p["step_count"]) == (
        h, d, STEPS["width"], STEPS["count"])
    # The button's front face centre is on its collision geometry.
    button = plant.GetBodyByName(SPEC.scene["button"]["name"])
    front = np.asarray(p["button_center"])
    assert abs(min_distance_to_terrain(plant, sg, diagram, ctx, front, button)) < 1e-6
    assert min_distance_to_terrain(plant, sg, diagram, ctx, front - [0.01, 0, 0], button) == \
        pytest.approx(0.01)
    X_WB = plant.EvalBodyPoseInWorld(plant.GetMyContextFromRoot(ctx), button)
    assert X_WB.translation()[0] - SPEC.scene["button"]["thickness"] / 2 == \
        pytest.approx(p["button_center"][0])
    assert p["button_center"][2] == pytest.approx(FLOOR_Z + SPEC.scene["button"]["height"])


def _stand(x, y=0.0, settle=0.05):
    sim = TaskSim(5, seed=0)
    sim.advance_to(0.105)  # between referee ticks (see TaskSim.teleport)
    sim.stand_at(x, y, lift=0.002)
    sim.advance_by(settle)
    return sim


def test_standing_before_the_steps_earns_nothing():
    sim = _stand(STEPS["start_x"] - 0.25, settle=0.5)
    ep = sim.verdict()
    assert ep.items == [] and not ep.done


def test_on_the_first_and_second_step_but_not_over():
    x0, d = STEPS["start_x"], STEPS["depth"]
    sim = _stand(x0 + 0.2, settle=0.2)  # soles span x0 + [0.18, 0.31]: on step 1
    assert sim.items() == ["onto_step"]
    sim.stand_at(x0 + d + 0.2, 0.0, lift=0.002)  # step 2
    sim.advance_by(0.2)
    assert sim.items() == ["onto_step"] and sim.verdict().score == 5.0


def test_feet_above_a_step_without_contact_earn_nothing():
    sim = TaskSim(5, seed=0)
    sim.advance_to(0.105)
    X = sim.standing_pose(STEPS["start_x"] + 0.2, 0.0, lift=0.05)
    for _ in range(20):
        sim.teleport(X)
        sim.advance_by(0.01)
    assert sim.items() == []


def test_on_the_floor_after_the_steps():
    sim = _stand(STEPS["start_x"] + STEPS["count"] * STEPS["depth"] + 0.4, settle=0.1)
    assert sim.items() == ["onto_step", "over_steps"]
    assert sim.verdict().score == 10.0


def _button_front():
    _, scene, *_ = scene_geometry(5, seed=0)
    return np.asarray(scene.priors["button_center"])


def _press_with_right_hand(sim, hold):
    """Arm forward, hand sphere pushed 3 mm into the button for ``hold`` seconds."""
    q = sim.controller.policy.q_arms_d.copy()
    q[4], q[7] = 1.3, 0.0  # r_shoulder_y forward, r_elbow straight
    sim.controller.arm_targets = q
    floor_x = STEPS["start_x"] + STEPS["count"] * STEPS["depth"]
    X = sim.standing_pose(floor_x + 0.5, 0.0, lift=0.002)
    sim.teleport(X)
    for name, angle in zip(("r_shoulder_y", "r_elbow"), (1.3, 0.0)):
        sim.plant.GetJointByName(name, sim.robot).set_angle(sim.plant_ctx, angle)
    p_hand = sim.frame_position("r_arm_sphere") - X.translation()
    button = _button_front()
    target = button - p_hand - [0.04 - 0.003, 0.0, 0.0]  # sphere radius 0.04
    X_press = sim.standing_pose(target[0], target[1], lift=0.002)
    _hold(sim, X_press, hold)
    return X_press


def _hold(sim, X_WB, duration):
    """Keep the robot pressed in place (re-placed every 10 ms, joints as they are): a standing
    robot pushed 3 mm into a rigid button would otherwise bounce off it."""
    t_end = sim.time + duration
    while sim.time < t_end - 1e-9:
        sim.teleport(X_WB, joints=False)
        sim.advance_by(0.01)


def test_pressing_with_the_hand_earns_both_button_items():
    sim = _stand(2.3)
    t0 = sim.time
    _press_with_right_hand(sim, hold=PRESS + 0.1)
    ep = sim.verdict()
    assert ep.earned("touch_button") and ep.earned("touch_button_arm")
    assert ep.score == 20.0 and ep.done and ep.success and ep.termination == "completed"
    press = [e.time for e in ep.items if e.item == "touch_button_arm"][0]
    assert t0 + PRESS <= press <= t0 + PRESS + 0.02  # after the hold time, not before


def test_a_touch_shorter_than_the_hold_time_earns_nothing():
    sim = _stand(2.3)
    items_before = sim.items()
    X = _press_with_right_hand(sim, hold=PRESS - 0.08)
    assert sim.verdict().memo["arm_touch_since"] is not None  # the hand is on the button
    sim.teleport(X.__class__(X.rotation(), X.translation() - [0.2, 0.0, 0.0]), joints=False)
    sim.advance_by(0.3)
    assert sim.items() == items_before  # only the step items, no button items


def test_torso_on_the_button_is_a_touch_but_not_an_arm_touch():
    button = _button_front()
    sim = _stand(2.3)
    # base_link's torso box front face is 0.08 m ahead of the base; push it 3 mm in.
    _hold(sim, sim.standing_pose(button[0] - 0.08 + 0.003, button[1], lift=0.002), PRESS + 0.1)
    ep = sim.verdict()
    assert ep.earned("touch_button") and not ep.earned("touch_button_arm")
    assert ep.score == 15.0 and not ep.done


def test_falling_on_a_step_ends_the_episode_and_keeps_points():
    sim = _stand(STEPS["start_x"] + 0.2)
    sim.controller.limp = True
    sim.advance_by(2.0)
    ep = sim.verdict()
    assert ep.termination == "fell" and [e.item for e in ep.items] == ["onto_step"]
    assert ep.score == 5.0


def test_walking_off_the_side_of_the_steps_ends_the_episode():
    sim = _stand(STEPS["start_x"] + 0.2, y=1.1)
    ep = sim.verdict()
    assert ep.termination == "left_region"

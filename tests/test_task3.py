"""Task 3 (moving bar): start sampling, the bar's prescribed motion, step/jump/contact rules."""

import numpy as np
import pytest

from pr2_drake.scene import StartPose
from pr2_drake.tasks import get_task
from pr2_drake.tasks.base import EpisodeStatus
from tests._locomotion_sim import TaskSim, assert_starts_in_region, roll_about_sole, scene_geometry

SPEC = get_task(3).spec
BAR = SPEC.scene["bar"]
STOP = BAR["start_time"] + BAR["travel"] / BAR["speed"]  # 3.65 s


def test_spec_matches_tasks_md():
    assert SPEC.time_limit == 240.0 and SPEC.max_score == 15.0
    assert {r.item: r.points for r in SPEC.rubric} == {
        "step_over": 10, "jump_over": 15, "bar_contact": -5}
    assert (BAR["speed"], BAR["travel"]) == (1.0, 1.65)
    assert SPEC.heading_noise_deg == 0.0


def test_start_poses_in_region_without_heading_noise_and_seeded():
    assert_starts_in_region(SPEC)
    _, a, *_ = scene_geometry(3, seed=5)
    _, b, *_ = scene_geometry(3, seed=5)
    _, c, *_ = scene_geometry(3, seed=6)
    assert (a.start.x, a.start.y) == (b.start.x, b.start.y) != (c.start.x, c.start.y)
    assert a.priors["bar_id"] == BAR["name"]
    assert set(a.priors) == set(SPEC.priors)


def _referee_and_status():
    sim = TaskSim(3, seed=0)
    return sim.testbed.referee, EpisodeStatus(max_score=SPEC.max_score)


def test_score_is_the_better_item_minus_contacts_clipped():
    ref, st = _referee_and_status()
    ref.award(st, "step_over", 1.0)
    assert st.score == 10.0
    ref.award(st, "jump_over", 2.0)
    assert st.score == 15.0  # the better one counts: not 25
    ref.award(st, "bar_contact", 2.5)
    ref.award(st, "bar_contact", 2.6)  # every contact episode costs 5
    assert st.score == 5.0
    ref.award(st, "bar_contact", 2.7)
    ref.award(st, "bar_contact", 2.8)
    assert st.score == 0.0  # clipped at 0
    _, st2 = _referee_and_status()
    ref.award(st2, "bar_contact", 1.0)
    ref.award(st2, "step_over", 2.0)
    ref.award(st2, "step_over", 3.0)  # earned once
    assert st2.score == 5.0 and len(st2.items) == 2


def test_bar_moves_as_prescribed_and_round_its_end_earns_nothing():
    # The robot stands beyond the bar's end (x = 1.3 > 1.0): the bar passes its feet without
    # touching them; their side changes but not over the bar, so nothing is earned.
    sim = TaskSim(3, seed=0, start=StartPose(1.3, 0.0, 0.0))
    sim.advance_to(1.9)
    fb = sim.feedback()
    assert set(fb) <= set(SPEC.feedback)
    assert fb["bar_position"][1] == pytest.approx(BAR["start_y"], abs=1e-3)
    assert np.linalg.norm(fb["bar_velocity"]) < 1e-3
    sim.advance_to(2.6)
    fb = sim.feedback()
    assert fb["bar_position"][1] == pytest.approx(BAR["start_y"] + 0.6, abs=0.02)
    assert fb["bar_velocity"] == pytest.approx([0.0, 1.0, 0.0], abs=0.05)
    assert fb["bar_position"][2] == pytest.approx(BAR["clearance"] + BAR["size"][2] / 2, abs=1e-3)
    sim.advance_to(STOP + 0.4)
    fb = sim.feedback()
    assert fb["bar_position"][1] == pytest.approx(BAR["start_y"] + BAR["travel"], abs=0.01)
    assert np.linalg.norm(fb["bar_velocity"]) < 0.01
    ep = sim.verdict()
    assert ep.items == [] and ep.score == 0.0 and not ep.done
    assert ep.memo["side"] == {"left": -1, "right": -1}  # the bar is now past both feet


def test_bar_hits_a_standing_robot_once_and_costs_points():
    sim = TaskSim(3, seed=0, start=StartPose(0.0, 0.0, 0.0))
    sim.advance_to(STOP + 0.3)
    ep = sim.verdict()
    contacts = [e for e in ep.items if e.item == "bar_contact"]
    assert len(contacts) == 1 and contacts[0].points == -5
    assert contacts[0].time > BAR["start_time"]
    assert not ep.earned("step_over") and not ep.earned("jump_over")
    assert ep.score == 0.0


def _hover(sim, t_end, sole_height):
    """Keep the robot upright with its soles ``sole_height`` above the ground until t_end."""
    X = sim.standing_pose(0.0, 0.0, lift=sole_height)
    while sim.time < t_end - 1e-9:
        sim.teleport(X)
        sim.advance_by(0.01)


def test_jump_over_scores_15_and_completes():
    sim = TaskSim(3, seed=0, start=StartPose(0.0, 0.0, 0.0))
    sim.advance_to(2.505)
    _hover(sim, 3.055, 0.09)  # the bar (top at 0.06 m) passes under both feet in flight
    sim.stand_at(0.0, 0.0, lift=0.002)
    sim.advance_to(3.055 + 0.3)
    assert sim.items() == []  # not yet: it must stay up for settle_time
    sim.advance_to(3.055 + 0.6)
    ep = sim.verdict()
    assert [e.item for e in ep.items] == ["jump_over"]
    assert ep.score == 15.0 and ep.done and ep.success and ep.termination == "completed"


def test_jump_touching_the_bar_twice_loses_ten():
    # Soles 5 mm into the bar's top: each foot scrapes the bar as it passes (0.2 s apart).
    sim = TaskSim(3, seed=0, start=StartPose(0.0, 0.0, 0.0))
    sim.advance_to(2.505)
    _hover(sim, 3.055, BAR["clearance"] + BAR["size"][2] - 0.005)
    sim.stand_at(0.0, 0.0, lift=0.002)
    sim.advance_to(3.7)
    ep = sim.verdict()
    assert [e.item for e in ep.items] == ["bar_contact", "bar_contact", "jump_over"]
    assert ep.score == 5.0


def test_jump_then_fall_earns_nothing():
    sim = TaskSim(3, seed=0, start=StartPose(0.0, 0.0, 0.0))
    sim.advance_to(2.505)
    _hover(sim, 3.055, 0.09)
    sim.stand_at(0.0, 0.0, lift=0.002)
    sim.controller.limp = True
    sim.advance_to(4.0)
    ep = sim.verdict()
    assert ep.termination == "fell" and ep.items == [] and ep.score == 0.0


def test_step_over_one_foot_at_a_time_scores_10():
    # Roll the robot about one sole so the other foot is ~0.1 m up while the bar passes under
    # it: one foot always on the ground, so this is a step, not a jump.
    sim = TaskSim(3, seed=0, start=StartPose(0.0, 0.0, 0.0))
    sim.advance_to(2.505)
    X0 = sim.standing_pose(0.0, 0.0)
    sim.teleport(X0)
    p_left, p_right = sim.frame_position("l_sole"), sim.frame_position("r_sole")
    while sim.time < 3.055 - 1e-9:
        bar_y = sim.feedback()["bar_position"][1]
        sim.teleport(roll_about_sole(X0, p_left, -0.45) if bar_y < 0.0
                     else roll_about_sole(X0, p_right, 0.45))
        sim.advance_by(0.01)
    sim.teleport(X0)
    sim.advance_to(STOP + 0.1)
    ep = sim.verdict()
    assert [e.item for e in ep.items] == ["step_over"]
    assert ep.score == 10.0 and not ep.earned("jump_over")
    assert ep.done and ep.termination == "completed"  # bar stopped: nothing more to gain


def test_getting_behind_the_bar_before_it_moves_earns_nothing():
    sim = TaskSim(3, seed=0, start=StartPose(0.0, 0.0, 0.0))
    sim.advance_to(0.5)
    sim.stand_at(0.0, -1.1)  # behind the resting bar (y = -0.825): it then moves away
    sim.advance_to(STOP + 0.6)
    ep = sim.verdict()
    assert ep.items == [] and not ep.done


def test_falling_ends_the_episode():
    sim = TaskSim(3, seed=0)
    sim.advance_to(0.1)
    sim.controller.limp = True
    sim.advance_to(1.5)
    ep = sim.verdict()
    assert ep.termination == "fell" and ep.score == 0.0

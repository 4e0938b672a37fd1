"""Task 4 (slope): start sampling, the slope geometry and height map, rubric items, endings."""

import numpy as np
import pytest

from pr2_drake.tasks import get_task
from tests._locomotion_sim import (
    TaskSim,
    assert_starts_in_region,
    min_distance_to_terrain,
    scene_geometry,
)

SPEC = get_task(4).spec
SLOPE = SPEC.scene["slope"]


def test_spec_matches_tasks_md():
    assert SPEC.time_limit == 120.0 and SPEC.max_score == 10.0
    assert {r.item: r.points for r in SPEC.rubric} == {"task_region": 5, "finish": 5}
    assert SLOPE["angle_deg"] == 7.0


def test_start_poses_in_region_bounded_heading_and_seeded():
    yaws = [s.yaw for s in assert_starts_in_region(SPEC)]
    assert np.ptp(np.degrees(yaws)) > 40.0
    _, a, *_ = scene_geometry(4, seed=1)
    _, b, *_ = scene_geometry(4, seed=1)
    _, c, *_ = scene_geometry(4, seed=2)
    assert (a.start.x, a.start.y, a.start.yaw) == (b.start.x, b.start.y, b.start.yaw)
    assert (a.start.x, a.start.y, a.start.yaw) != (c.start.x, c.start.y, c.start.yaw)


def test_slope_surface_is_7_degrees_and_matches_ground_height():
    _, scene, plant, sg, diagram, ctx = scene_geometry(4, seed=0)
    gh = scene.ground_height
    x0, run = SLOPE["start_x"], SLOPE["run"]
    rise = run * np.tan(np.radians(7.0))
    assert np.degrees(np.arctan((gh(x0 + 2.0, 0.3) - gh(x0 + 0.5, 0.3)) / 1.5)) == \
        pytest.approx(7.0)
    assert gh(x0 + run + 1.0, 0.0) == pytest.approx(rise)
    assert gh(-0.5, 0.0) == 0.0
    assert scene.priors["slope_angle_deg"] == 7.0
    assert set(scene.priors) == set(SPEC.priors)
    goal = scene.priors["goal_center"]
    assert goal == pytest.approx([*SPEC.scene["finish"]["center"], rise])
    rng = np.random.default_rng(0)
    for x in np.concatenate([rng.uniform(x0 + 0.05, x0 + run - 0.05, 10),
                             rng.uniform(x0 + run + 0.05, x0 + run + 1.9, 5),
                             rng.uniform(-0.7, x0 - 0.05, 3)]):
        y = rng.uniform(-0.9, 0.9)
        z = gh(x, y)
        assert abs(min_distance_to_terrain(plant, sg, diagram, ctx, [x, y, z])) < 1e-6
        assert min_distance_to_terrain(plant, sg, diagram, ctx, [x, y, z + 0.02]) > 0.015


def test_standing_in_start_region_earns_nothing():
    sim = TaskSim(4, seed=0)
    sim.advance_to(0.5)
    ep = sim.verdict()
    assert ep.items == [] and not ep.done


def test_task_region_then_finish_completes():
    sim = TaskSim(4, seed=0)
    sim.advance_to(0.1)
    sim.stand_at(2.0, 0.0, lift=0.03)
    sim.advance_by(0.05)
    assert sim.items() == ["task_region"] and sim.verdict().score == 5.0
    gx, gy = SPEC.scene["finish"]["center"]
    sim.stand_at(gx + 0.45, gy)  # on the plateau, outside the 0.4 m circle
    sim.advance_by(0.05)
    assert sim.items() == ["task_region"]
    sim.stand_at(gx + 0.3, gy)
    sim.advance_by(0.05)
    ep = sim.verdict()
    assert [e.item for e in ep.items] == ["task_region", "finish"]
    assert ep.score == 10.0 and ep.done and ep.success and ep.termination == "completed"


def test_finish_alone_is_not_completion():
    sim = TaskSim(4, seed=0)
    sim.advance_to(0.1)
    sim.stand_at(*SPEC.scene["finish"]["center"])
    sim.advance_by(0.05)
    ep = sim.verdict()
    assert [e.item for e in ep.items] == ["finish"] and ep.score == 5.0 and not ep.done


def test_falling_on_the_slope_ends_the_episode_and_keeps_points():
    sim = TaskSim(4, seed=0)
    sim.advance_to(0.1)
    sim.stand_at(1.6, 0.0, lift=0.03)
    sim.controller.limp = True
    sim.advance_by(2.0)
    ep = sim.verdict()
    assert ep.termination == "fell" and not ep.success
    assert [e.item for e in ep.items] == ["task_region"] and ep.score == 5.0


def test_walking_off_the_side_ends_the_episode():
    sim = TaskSim(4, seed=0)
    sim.advance_to(0.1)
    sim.stand_at(4.0, 1.1)  # beside the plateau
    sim.advance_by(0.05)
    ep = sim.verdict()
    assert ep.termination == "left_region" and ep.score == 0.0

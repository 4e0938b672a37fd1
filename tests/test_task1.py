"""Task 1 (rocky road): start sampling, the fixed road, its height map, rubric items, endings."""

import numpy as np
import pytest

from pr2_drake.scene import StartPose
from pr2_drake.tasks import get_task
from tests._locomotion_sim import (
    assert_starts_in_region,
    TaskSim,
    min_distance_to_terrain,
    scene_geometry,
    world_geometry_poses,
)

SPEC = get_task(1).spec


def test_spec_matches_tasks_md():
    assert SPEC.time_limit == 50.0
    assert SPEC.max_score == 15.0
    assert {r.item: r.points for r in SPEC.rubric} == {
        "task_region": 5, "half_road": 5, "finish": 5}
    assert SPEC.scene["road"]["length"] == pytest.approx(4.96)
    assert SPEC.scene["finish"]["radius"] == pytest.approx(0.4)


def test_start_poses_stay_in_region_with_bounded_heading():
    yaws = [s.yaw for s in assert_starts_in_region(SPEC)]
    # The noise is really used: headings spread over most of +-30 deg.
    assert np.ptp(np.degrees(yaws)) > 40.0


def test_same_seed_same_start_and_road_different_seed_different_start_same_road():
    _, a, plant_a, sg_a, *_ = scene_geometry(1, seed=3)
    _, b, plant_b, sg_b, *_ = scene_geometry(1, seed=3)
    _, c, plant_c, sg_c, *_ = scene_geometry(1, seed=4)
    assert (a.start.x, a.start.y, a.start.yaw) == (b.start.x, b.start.y, b.start.yaw)
    assert (a.start.x, a.start.y, a.start.yaw) != (c.start.x, c.start.y, c.start.yaw)
    geo_a, geo_c = world_geometry_poses(plant_a, sg_a), world_geometry_poses(plant_c, sg_c)
    n_road = int(np.prod(SPEC.scene["road"]["cells"]))
    assert len(geo_a) == len(geo_c) == n_road + 1  # stones + the ground box
    for (name_a, X_a), (name_c, X_c) in zip(geo_a, geo_c):
        assert name_a == name_c
        np.testing.assert_array_equal(X_a, X_c)
    # The road is rough: the stones differ in height and tilt.
    road = a.data["road"]
    assert np.ptp(road.top) > 0.015
    assert np.max(np.abs(np.degrees(road.roll))) > 2.0


def test_ground_height_is_the_stone_surface():
    _, scene, plant, sg, diagram, ctx = scene_geometry(1, seed=0)
    road = scene.data["road"]
    rng = np.random.default_rng(7)
    for _ in range(40):
        i, j = rng.integers(road.cells[0]), rng.integers(road.cells[1])
        c = road.cell_center(i, j) + rng.uniform(-0.35, 0.35, 2) * [road.dx, road.dy]
        z = scene.ground_height(*c)
        assert z == pytest.approx(road.height(*c))
        assert abs(min_distance_to_terrain(plant, sg, diagram, ctx, [*c, z])) < 1e-6
        assert min_distance_to_terrain(plant, sg, diagram, ctx, [*c, z + 0.01]) == \
            pytest.approx(0.01, abs=1e-3)
    assert scene.ground_height(-0.5, 0.0) == 0.0  # before the road: flat ground
    goal = scene.priors["goal_center"]
    assert set(scene.priors) == set(SPEC.priors)  # the YAML documents every prior
    assert goal[:2] == pytest.approx(SPEC.scene["finish"]["center"])


def test_standing_in_start_region_earns_nothing():
    sim = TaskSim(1, seed=0)
    sim.advance_to(0.5)
    ep = sim.verdict()
    assert ep.score == 0.0 and ep.items == [] and not ep.done


def test_task_region_without_half_road():
    sim = TaskSim(1, seed=0)
    sim.advance_to(0.1)
    sim.stand_at(1.2, 0.0, lift=0.03)
    sim.advance_by(0.05)
    assert sim.items() == ["task_region"]
    assert sim.verdict().score == 5.0


def test_half_road_and_finish_complete_the_task():
    sim = TaskSim(1, seed=0)
    sim.advance_to(0.1)
    sim.stand_at(3.3, 0.0, lift=0.03)
    sim.advance_by(0.05)
    assert sim.items() == ["task_region", "half_road"]
    # Just outside the finish circle (0.45 m from its centre): no finish.
    gx, gy = SPEC.scene["finish"]["center"]
    sim.stand_at(gx - 0.45, gy)
    sim.advance_by(0.05)
    assert "finish" not in sim.items()
    sim.stand_at(gx - 0.3, gy)
    sim.advance_by(0.05)
    ep = sim.verdict()
    assert [e.item for e in ep.items] == ["task_region", "half_road", "finish"]
    assert ep.score == 15.0 and ep.done and ep.success and ep.termination == "completed"


def test_beside_the_road_past_halfway_earns_nothing():
    # Inside the arena but off the road (|y| > width / 2): neither task region nor half road.
    sim = TaskSim(1, seed=0, start=StartPose(3.5, 0.8, 0.0))
    sim.advance_to(0.1)
    ep = sim.verdict()
    assert ep.items == [] and not ep.done


def test_falling_ends_the_episode_and_keeps_points():
    sim = TaskSim(1, seed=0)
    sim.advance_to(0.1)
    sim.stand_at(1.5, 0.0, lift=0.03)
    sim.controller.limp = True
    sim.advance_by(2.0)
    ep = sim.verdict()
    assert ep.done and ep.termination == "fell" and not ep.success
    assert ep.score == 5.0 and [e.item for e in ep.items] == ["task_region"]
    assert sim.base_position()[2] < SPEC.fall_height + 0.03


def test_leaving_the_arena_ends_the_episode():
    sim = TaskSim(1, seed=0)
    sim.advance_to(0.1)
    sim.stand_at(0.0, 1.0)
    sim.advance_by(0.05)
    ep = sim.verdict()
    assert ep.done and ep.termination == "left_region" and ep.score == 0.0

"""Task-6 navigation: occupancy grid from the task YAML, A* paths that keep clear of walls and
furniture, and a path-following velocity source driving the walking controller."""

import math

import numpy as np
import pytest
from pydrake.systems.framework import DiagramBuilder

from pr2_drake.agents.search.navigation import (
    NavigationParams,
    NoPathError,
    OccupancyGrid,
    PathFollower,
    follow_velocity,
    house_obstacles,
    plan_path,
    pursuit_point,
)
from pr2_drake.tasks import get_task

SCENE = get_task(6).spec.scene
GRID = OccupancyGrid.from_scene(SCENE)
OBSTACLES = house_obstacles(SCENE)
RADIUS = NavigationParams().robot_radius


def clearance(path: np.ndarray) -> float:
    """Smallest distance [m] from the path (sampled every 1 cm) to any wall/table/decor box."""
    pts = [a + s * (b - a) for a, b in zip(path[:-1], path[1:])
           for s in np.linspace(0, 1, max(2, int(np.linalg.norm(b - a) / 0.01)))]
    pts = np.asarray(pts)
    return min(float(o.distance(pts).min()) for o in OBSTACLES)


def test_grid_marks_walls_tables_and_decor_and_leaves_doorways_open():
    assert not GRID.free((0.0, -2.5))  # living room | kitchen wall
    assert GRID.free((0.0, -1.05))  # its doorway
    assert not GRID.free((2.0, -2.4))  # kitchen table
    assert not GRID.free((-2.0, -3.45))  # sofa
    assert GRID.free((-2.0, -1.0)) and GRID.free((2.0, 2.0))


@pytest.mark.parametrize("seed", range(6))
def test_paths_between_rooms_never_cross_walls_or_furniture(seed):
    rng = np.random.default_rng(seed)
    inflated = GRID.inflated(RADIUS)
    for _ in range(5):
        while True:
            a, b = rng.uniform(-3.6, 3.6, 2), rng.uniform(-3.6, 3.6, 2)
            if inflated.free(a) and inflated.free(b) and np.linalg.norm(a - b) > 2.0:
                break
        path = plan_path(GRID, a, b, RADIUS)
        assert np.linalg.norm(path[0] - a) < 0.05 and np.linalg.norm(path[-1] - b) < 0.05
        assert clearance(path) > RADIUS - 0.05  # never through (or grazing) an obstacle


def test_room_to_room_path_goes_through_the_doorway():
    # Study start -> the coffee table's north side: through the study-kitchen and the
    # kitchen-living room doorways (no direct door between study and living room).
    path = plan_path(GRID, (2.2, 0.95), (-2.0, -1.3), RADIUS)
    assert clearance(path) > RADIUS - 0.05
    # Where the path crosses x = 0 (the kitchen | living room wall): inside that doorway.
    ys = [a[1] + (0 - a[0]) * (b[1] - a[1]) / (b[0] - a[0])
          for a, b in zip(path[:-1], path[1:]) if (a[0] > 0) != (b[0] > 0)]
    assert len(ys) == 1 and -1.6 < ys[0] < -0.5


def test_blocked_goal_is_moved_and_walled_in_goal_is_an_error():
    path = plan_path(GRID, (-2.0, -1.0), (-2.0, -2.0), RADIUS)  # goal: the coffee table centre
    assert np.linalg.norm(path[-1] - [-2.0, -2.0]) < 0.75 and clearance(path) > RADIUS - 0.05
    closed = OccupancyGrid.from_obstacles(OBSTACLES + [], [-4, -4], [4, 4])
    closed.occupied[:, 78:82] = True  # a wall along x = 0 with no doorway
    with pytest.raises(NoPathError, match="no path"):
        plan_path(closed, (-2.0, -1.0), (2.0, -1.0), RADIUS)


def test_pursuit_and_velocity():
    path = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]])
    q, left = pursuit_point(path, np.array([0.5, 0.1]), 0.3)
    assert np.allclose(q, [0.8, 0.0]) and left == pytest.approx(1.2)
    q, _ = pursuit_point(path, np.array([0.95, 0.0]), 0.3)
    assert np.allclose(q, [1.0, 0.25])  # around the corner
    p = NavigationParams()
    v = follow_velocity(path, np.array([0.5, 0.0]), 0.0, None, p)
    assert v[0] > 0 and abs(v[2]) < 1e-9
    v = follow_velocity(path, np.array([1.0, 0.95]), math.pi / 2, 0.0, p)
    assert v[0] == 0 and v[2] < 0  # at the end: turn right to the final heading
    assert not np.any(follow_velocity(path, np.array([1.0, 0.95]), 0.0, 0.0, p))


def test_walking_robot_follows_a_path_with_a_turn():
    from pr2_drake.controllers.posture import ArmPosture
    from pr2_drake.controllers.walking import WalkingController
    from pr2_drake.controllers.walking_params import WalkingParams
    from pr2_drake.episode import Episode
    from pr2_drake.scenario import Scenario

    path = np.array([[0.0, 0.0], [0.45, 0.0], [0.45, 0.4]])
    follower = PathFollower(path=path)

    def wire(b: DiagramBuilder, tb):
        walker = b.AddSystem(WalkingController(WalkingParams.load("params/controllers/walking.yaml")))
        arms = b.AddSystem(ArmPosture())
        b.AddSystem(follower)
        for n in ("joint_state", "body_state"):
            b.Connect(tb.GetOutputPort(n), walker.GetInputPort(n))
        b.Connect(tb.GetOutputPort("body_state"), follower.GetInputPort("body_state"))
        b.Connect(follower.GetOutputPort("velocity_command"), walker.GetInputPort("velocity_command"))
        b.Connect(walker.GetOutputPort("legs_command"), tb.GetInputPort("legs_command"))
        b.Connect(arms.GetOutputPort("arms_command"), tb.GetInputPort("arms_command"))
        return follower

    ep = Episode(Scenario(seconds=math.inf), wire)
    tb = ep.testbed
    tb.GetInputPort("pick").FixValue(ep.tb_context, "")
    tb.GetInputPort("release").FixValue(ep.tb_context, False)
    ep.simulator.Initialize()
    track = []
    for k in range(1, 15):
        ep.simulator.AdvanceTo(0.5 * k)
        track.append(tb.GetOutputPort("body_state").Eval(ep.tb_context)[:3].copy())
    track = np.asarray(track)
    assert track[:, 2].min() > 0.4  # never fell
    assert np.linalg.norm(track[-1, :2] - path[-1]) < 0.2  # reached the end of the path ...
    assert track[:, 1].max() > 0.25  # ... after turning left at the corner
    dist = [min(np.linalg.norm(p[:2] - (a + np.clip((p[:2] - a) @ (b - a) / ((b - a) @ (b - a)), 0, 1) * (b - a)))
                for a, b in zip(path[:-1], path[1:])) for p in track]
    assert max(dist) < 0.2  # stayed near the path

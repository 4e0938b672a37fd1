"""Task-6 mapping: the search agent's height map from rendered head-camera depth (walls and
furniture occupied where they stand, the floor free, tops found at their place and height,
the robot's own surroundings left out), and the map-driven stages: a path planned again when a
newly seen obstacle blocks it, exploring when no top is left."""

import math

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator

from pr2_drake.agents.search.mapping import HeightMap, MappingParams
from pr2_drake.agents.search.memory import Stage
from pr2_drake.agents.search.perception import CameraIntrinsics, HeadCameraKinematics
from pr2_drake.bench.rigs import ViewRig
from tests.test_search_agent import MAP, TABLES, body_state, searching, sequencer

P = MappingParams.load()


@pytest.fixture(scope="module")
def study_map():
    """The map of six frames turning on the spot in the study (seed 0), and the rig."""
    rig = ViewRig("low", seed=0)
    kin, K = HeadCameraKinematics(), CameraIntrinsics.from_settings(rig.settings)
    m = HeightMap.empty((-4.0, -4.0), (4.0, 4.0), P.resolution)
    for yaw in np.radians(np.arange(0.0, 360.0, 60.0)):
        rig.pose_robot(2.2, 1.2, yaw)
        _, depth = rig.render()
        body, joints = rig.states()
        m = m.integrate(depth, kin.camera_pose(body, joints), K, body[:3], P)
    return m, rig


def test_walls_and_furniture_are_occupied_and_the_floor_free(study_map):
    m, rig = study_map
    assert m.version == 6
    grid = m.grid()
    for p in [(3.96, 2.0), (2.0, 3.96), (2.5, 0.0), (2.0, 2.8), (3.63, 2.6)]:  # walls, desk, shelf face
        assert not grid.free(p), p
    for p in [(2.2, 2.3), (3.4, 1.5), (1.05, 0.0)]:  # the study's floor, the doorway
        i, j = grid.cell(p)
        assert grid.free(p) and m.floor[i, j] > 0, p
    i, j = grid.cell((2.2, 1.2))
    assert m.floor[i, j] > 0 and m.obstacle[i, j] == 0  # where the robot stands: free
    i, j = grid.cell((-3.0, 3.0))
    assert not m.known()[i, j]  # the playroom, behind walls: unknown


def test_the_desk_top_is_found_at_its_place_and_height(study_map):
    m, rig = study_map
    desk = rig.tables["desk"]
    tops = [t for t in m.surfaces(P) if t.contains(desk.center)]
    assert len(tops) == 1
    top = tops[0]
    assert top.height == pytest.approx(desk.height, abs=0.01)
    assert np.allclose(top.center, desk.center, atol=0.05)
    assert np.allclose(top.size, desk.size, atol=0.1)


def test_a_top_seen_from_noisy_camera_poses_keeps_its_height():
    """Each frame's camera pose off by the randomised sensor noise (base orientation 0.005
    rad about a random axis, position 2 mm): the desk's height stays within 5 mm (the lowest
    height over the frames read it about 1.5 cm low, and a place 2 cm high tipped a bear)."""
    from pydrake.math import RigidTransform, RotationMatrix
    rig = ViewRig("low", seed=0)
    kin, K = HeadCameraKinematics(), CameraIntrinsics.from_settings(rig.settings)
    m = HeightMap.empty((-4.0, -4.0), (4.0, 4.0), P.resolution)
    rig.pose_robot(2.2, 1.2, math.radians(60.0))
    _, depth = rig.render()
    body, joints = rig.states()
    X_WC = kin.camera_pose(body, joints)
    rng = np.random.default_rng(7)
    for _ in range(40):
        axis = rng.normal(size=3)
        R = RotationMatrix.MakeFromOneVector(axis / np.linalg.norm(axis), 2)
        err = RigidTransform(R @ RotationMatrix.MakeZRotation(rng.normal(0.0, 0.005)) @ R.inverse(),
                             rng.normal(0.0, 0.002, 3))
        m = m.integrate(depth, err @ X_WC, K, body[:3], P)
    desk = rig.tables["desk"]
    tops = [t for t in m.surfaces(P) if t.contains(desk.center)]
    assert len(tops) == 1
    assert tops[0].height == pytest.approx(desk.height, abs=0.005)


def test_a_map_is_never_changed_in_place(study_map):
    m, _ = study_map
    floor = m.floor.copy()
    m2 = m.with_free_disc((0.0, 0.0), 1.0)
    assert np.array_equal(m.floor, floor) and m2.version == m.version + 1
    import copy

    assert copy.deepcopy(m) is m  # shared by the memory's copies until it changes


def test_a_path_blocked_by_a_newly_seen_obstacle_is_planned_again():
    seq, ctx = sequencer()
    sim = searching(seq, ctx, 2.0, -1.0, math.pi)  # in the kitchen: the desk is far
    m = seq.mutable_memory(ctx)
    assert m.stage == Stage.NAVIGATE
    old = np.asarray(m.path).copy()
    # A box seen across the path's first leg, 1 m ahead.
    mid = old[0] + (old[1] - old[0]) * min(1.0, 1.0 / np.linalg.norm(old[1] - old[0]))
    m.map = m.map.with_box(mid, (0.8, 0.8), 0.4)
    sim.AdvanceTo(0.1)
    m = seq.memory(ctx)
    g = m.map.grid().inflated(seq.nav.robot_radius)
    assert any("plan again" in line for line in m.log)
    new = np.asarray(m.path)
    assert not np.array_equal(new, old)
    for a, b in zip(new[1:], new[2:]):  # the new path keeps off the box
        for s in np.linspace(0, 1, 20):
            assert g.free(a + s * (b - a))


def test_with_no_top_left_it_walks_to_a_frontier_and_scans_there():
    seq, ctx = sequencer()
    # Only the kitchen seen: its table searched already; the rest of the house unknown.
    world = HeightMap.empty((-4.0, -4.0), (4.0, 4.0), P.resolution)
    world = world.with_free_disc((2.0, -2.0), 1.9)
    k = TABLES["kitchen_table"]
    world = world.with_box(k.center, k.size, k.height)
    seq.mutable_memory(ctx).searched = [k.center.copy()]
    sim = searching(seq, ctx, 2.0, -1.0, 0.0, world)
    m = seq.memory(ctx)
    assert m.stage == Stage.NAVIGATE and m.nav_then == Stage.SCAN and m.explored == 1
    assert np.linalg.norm(m.goal[:2] - [2.0, -1.0]) >= seq.p.explore_distance
    # There: a scan (turning on the spot).
    seq.GetInputPort("body_state").FixValue(ctx, body_state(*m.goal))
    sim.AdvanceTo(0.2)
    assert seq.memory(ctx).stage == Stage.SCAN
    assert seq.GetOutputPort("velocity_command").Eval(ctx)[2] > 0

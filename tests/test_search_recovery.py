"""Task-6 reference agent: its recovery paths (pr2_drake/agents/search/recovery.py, issue 29),
on the sequencer alone with synthetic inputs (a stub detector, robot states held fixed, a map of
the whole house as if seen): stalled approaches and walks end in a recovery instead of stepping
on for ever, no path to the destination is worked round, and a place is checked with the camera
(the object seen on the coffee table: done; seen on another top: picked up again; on the floor
or not seen: failed, with the reason). Whole randomised episodes are a benchmark
(``pr2-drake eval --task 6 --set randomize.enabled=true``, docs/benchmarks.md)."""

import math

import numpy as np
import pytest

from pr2_drake.agents.search.memory import SearchAgentParams, Stage
from pr2_drake.agents.search.tables import Table, best_side, sides_by_preference
from pr2_drake.grasp import PickState
from tests.test_search_agent import (
    GRID,
    MAP,
    TABLES,
    StubDetector,
    body_state,
    searching,
    sequencer,
)

P_WO = np.array([2.3, 2.7, 0.63])  # on the desk, picked from its south side


def hold(seq, ctx, x: float, y: float, yaw: float) -> None:
    seq.GetInputPort("body_state").FixValue(ctx, body_state(x, y, yaw))


def approaching(detector=None):
    """The sequencer in APPROACH to the desk's object (found from the look pose)."""
    seq, ctx = sequencer(detector=detector or StubDetector(P_WO))
    sim = searching(seq, ctx, 2.0, 1.95, math.pi / 2)
    sim.AdvanceTo(1.0)
    assert seq.memory(ctx).stage == Stage.APPROACH
    return seq, ctx, sim


def test_a_pick_approach_stepping_away_walks_there_again_then_settles_within_reach():
    seq, ctx, sim = approaching()
    p = seq.p
    x, y, yaw = seq.memory(ctx).goal
    # The gait steps the other way than commanded: the base ends up 0.4 m to the side and
    # stays there. Before the stall time: still stepping.
    hold(seq, ctx, x + 0.4, y, yaw)
    sim.AdvanceTo(1.0 + p.approach_stall_time - 0.3)
    assert seq.memory(ctx).stage == Stage.APPROACH
    sim.AdvanceTo(1.0 + p.approach_stall_time + 0.3)
    m = seq.memory(ctx)
    assert m.stage == Stage.NAVIGATE and m.nav_then == Stage.APPROACH, m.log[-3:]
    assert m.approach_tries == 1 and "walk there again" in " ".join(m.log[-3:])
    assert np.allclose(m.pick_goal, [x, y, yaw])  # the same pick pose, on a path
    assert GRID.inflated(seq.nav.robot_radius).free(m.path[-1])
    # At the stage point the approach starts again; it stalls 0.13 m short of the pose,
    # with the object within reach of the shoulder: it settles there.
    hold(seq, ctx, *m.path[-1], yaw)
    t = sim.get_context().get_time()
    sim.AdvanceTo(t + 0.1)
    assert seq.memory(ctx).stage == Stage.APPROACH
    hold(seq, ctx, x, y - 0.13, yaw)
    sim.AdvanceTo(t + 0.2)
    reach = np.linalg.norm(seq.model.shoulder_position(seq.memory(ctx).hand) - P_WO)
    assert reach <= p.reach_accept  # (the case this test is about)
    sim.AdvanceTo(t + 0.2 + p.approach_stall_time + 0.2)
    m = seq.memory(ctx)
    log = " ".join(m.log[-3:])
    assert m.stage == Stage.SETTLE and "the object is within reach" in log, log


def test_a_pick_approach_that_stalls_out_of_reach_every_time_settles_after_its_retries():
    seq, ctx, sim = approaching()
    p = seq.p
    x, y, yaw = seq.memory(ctx).goal
    hold(seq, ctx, x + 0.5, y - 0.2, yaw)  # out of reach, and stays there
    for k in range(p.approach_retries):
        m = seq.mutable_memory(ctx)
        m.stage, m.goal = Stage.APPROACH, m.pick_goal  # back on the approach (walked there)
        t = sim.get_context().get_time()
        sim.AdvanceTo(t + p.approach_stall_time + 0.3)
        assert seq.memory(ctx).stage == Stage.NAVIGATE
        assert seq.memory(ctx).approach_tries == k + 1
    m = seq.mutable_memory(ctx)
    m.stage, m.goal = Stage.APPROACH, m.pick_goal
    t = sim.get_context().get_time()
    sim.AdvanceTo(t + p.approach_stall_time + 0.3)
    m = seq.memory(ctx)
    log = " ".join(m.log[-3:])
    assert m.stage in (Stage.SETTLE, Stage.REACH) and "settle anyway" in log, log


def placing(side=(0.0, 1.0)):
    """The sequencer carrying the object to the coffee table, in APPROACH_TABLE across
    ``side``, the object held in the right hand as picked (0.45 m ahead, 0.25 m right)."""
    seq, ctx = sequencer()
    seq.GetInputPort("pick_state").FixValue(ctx, PickState(True, "right_hand", "book"))
    m = seq.mutable_memory(ctx)
    m.map, m.frame_time = MAP, 0.0
    m.side, m.hand = np.array(side), 1
    m.r_pick, m.o_pick = np.array([0.35, -0.18, 0.05]), np.array([0.45, -0.25, 0.02])
    m.hand_over_top, m.p_WO = 0.09, np.array([2.3, 2.7, 0.63])
    m.goal = seq._place_pose(m, seq.destination)
    m.stage = Stage.APPROACH_TABLE
    from pydrake.systems.analysis import Simulator

    return seq, ctx, Simulator(seq, ctx)


def test_a_place_approach_drifting_along_the_table_settles_with_the_object_over_the_top():
    seq, ctx, sim = placing()
    x, y, yaw = seq.memory(ctx).goal
    hold(seq, ctx, x - 0.25, y, yaw)  # 0.25 m along the table's long side: still over it
    sim.AdvanceTo(seq.p.approach_stall_time + 0.3)
    m = seq.memory(ctx)
    assert m.stage == Stage.SETTLE_TABLE and "over the top" in " ".join(m.log[-3:]), m.log[-3:]
    tab = seq.destination
    o = seq._held_object_at(m, np.array([x - 0.25, y]), yaw)
    assert tab.contains(o, -seq.p.place_margin)


def test_a_place_approach_stalled_past_the_table_end_turns_the_object_over_the_top():
    seq, ctx, sim = placing()
    x, y, yaw = seq.memory(ctx).goal
    hold(seq, ctx, x - 0.55, y, yaw)  # the object 0.55 m along: past the top's margin
    assert not seq._object_over_top(seq.memory(ctx), np.array([x - 0.55, y]), yaw)
    sim.AdvanceTo(seq.p.approach_stall_time + 0.3)
    m = seq.memory(ctx)
    assert m.stage == Stage.APPROACH_TABLE and m.approach_tries == 1, m.log[-3:]
    assert "turn to" in " ".join(m.log[-3:])
    turned = m.goal[2]
    assert np.allclose(m.goal[:2], [x - 0.55, y]) and abs(turned - yaw) > math.radians(5)
    assert seq._object_over_top(m, m.goal[:2], turned)
    hold(seq, ctx, x - 0.55, y, turned)  # it turned on the spot: placed from there
    t = sim.get_context().get_time()
    sim.AdvanceTo(t + 0.1)
    assert seq.memory(ctx).stage == Stage.SETTLE_TABLE


def test_a_place_approach_off_the_table_carries_again_then_fails_after_its_retries():
    seq, ctx, sim = placing()
    p = seq.p
    x, y, yaw = seq.memory(ctx).goal
    hold(seq, ctx, x + 0.9, y, yaw)  # the object would be past the table's end
    sim.AdvanceTo(p.approach_stall_time + 0.3)
    m = seq.memory(ctx)
    assert m.stage == Stage.CARRY and m.approach_tries == 1, m.log[-3:]
    assert m.path is not None and "carry it there again" in " ".join(m.log[-3:])
    for _ in range(p.approach_retries - 1):
        m = seq.mutable_memory(ctx)
        m.stage, m.goal = Stage.APPROACH_TABLE, seq._place_pose(m, seq.destination)
        t = sim.get_context().get_time()
        sim.AdvanceTo(t + p.approach_stall_time + 0.3)
        assert seq.memory(ctx).stage == Stage.CARRY
    m = seq.mutable_memory(ctx)
    m.stage, m.goal = Stage.APPROACH_TABLE, seq._place_pose(m, seq.destination)
    t = sim.get_context().get_time()
    sim.AdvanceTo(t + p.approach_stall_time + 0.3)
    m = seq.memory(ctx)
    assert m.stage == Stage.FAILED and m.failure == "the place pose was not reached"


def test_a_walk_circling_near_its_goal_ends_there_but_not_far_from_it():
    seq, ctx, sim = approaching()
    p = seq.p
    x, y, yaw = seq.memory(ctx).goal
    seq._walk_round(seq.mutable_memory(ctx), seq.memory(ctx).surfaces[seq.memory(ctx).place],
                    seq.memory(ctx).side, np.array([x, y - 1.0, 0.57]), 1.0)
    goal = seq.memory(ctx).goal
    hold(seq, ctx, goal[0] + 0.8, goal[1] - 0.4, yaw)  # 0.9 m away: no progress, far
    sim.AdvanceTo(1.0 + p.walk_stall_time + 1.0)
    assert seq.memory(ctx).stage == Stage.NAVIGATE
    hold(seq, ctx, goal[0] + 0.3, goal[1] - 0.1, yaw)  # 0.32 m away, circling
    t = sim.get_context().get_time()
    sim.AdvanceTo(t + p.walk_stall_time - 1.0)
    assert seq.memory(ctx).stage == Stage.NAVIGATE
    sim.AdvanceTo(t + p.walk_stall_time + 0.5)
    m = seq.memory(ctx)
    assert m.stage == Stage.APPROACH and "walk stalled" in " ".join(m.log[-3:]), m.log[-3:]


def with_cells(world, xs, ys, obstacle: int, floor: int):
    """``world`` with the cells over [xs] x [ys] (m) holding these point counts."""
    c = world.cell_centers()
    box = ((c[..., 0] >= xs[0]) & (c[..., 0] <= xs[1]) & (c[..., 1] >= ys[0])
           & (c[..., 1] <= ys[1]))
    obst, fl = world.obstacle.copy(), world.floor.copy()
    obst[box], fl[box] = obstacle, floor
    return world._copy(obstacle=obst, floor=fl)


def test_no_path_to_the_destination_is_planned_past_weak_obstacles_never_through_the_table():
    seq, ctx = sequencer()
    m = seq.mutable_memory(ctx)
    start = np.array([2.0, 1.0, 0.57])  # in the study
    # Stray points (1 each, over floor seen 10 times) close both ways into the living room.
    world = with_cells(MAP, (-1.6, -0.5), (-0.3, 0.3), 1, 10)
    world = with_cells(world, (-0.3, 0.3), (-1.6, -0.5), 1, 10)
    m.map = world
    assert seq._plan_destination(m, start, 0.0) and m.lenient
    assert "past weak obstacles" in m.log[-1]
    tab = seq.destination
    inside = [q for q in np.linspace(m.path[:-1], m.path[1:], 20).reshape(-1, 2)
              if tab.contains(q)]
    assert not inside  # the coffee table of the priors stays an obstacle
    # Checked against the same lenient grid, the path is not blocked: no replanning loop.
    m.path_version = -1
    assert not seq._path_blocked(m, start)
    # Real obstacles (many points, no floor) there: no path, and nothing to walk.
    m.map = with_cells(with_cells(MAP, (-1.6, -0.5), (-0.3, 0.3), 50, 0),
                       (-0.3, 0.3), (-1.6, -0.5), 50, 0)
    assert not seq._plan_destination(m, start, 0.0) and m.path is None
    # A plan that works on the map is made on it (first choice: the best side).
    m.map = MAP
    assert seq._plan_destination(m, start, 0.0) and not m.lenient
    assert np.allclose(m.side, best_side(GRID, tab, seq.p.look_distance, seq.nav.robot_radius))


def test_the_destination_sides_are_tried_best_first():
    tab = TABLES["coffee_table"]
    r = 0.32
    sides = sides_by_preference(GRID, tab, 0.55, r)
    assert np.allclose(sides[0], best_side(GRID, tab, 0.55, r)) and len(sides) == 4
    assert np.allclose(sides[0], [0, 1]) and np.allclose(sides[-1], [0, -1])  # sofa: last
    # The north side walled off right at the table: the plan goes to another side.
    seq, ctx = sequencer()
    m = seq.mutable_memory(ctx)
    m.map = with_cells(MAP, (-2.6, -1.4), (-1.6, -1.3), 50, 0)
    assert seq._plan_destination(m, np.array([-1.0, -0.5, 0.57]), 0.0)
    assert not np.allclose(m.side, [0, 1]) and not m.lenient


def verifying(seen):
    """The sequencer stepping back from a place, the stub detector seeing the object at
    ``seen`` (or nowhere); run until the check decides."""
    det = StubDetector(seen)
    seq, ctx = sequencer(detector=det)
    m = seq.mutable_memory(ctx)
    m.map, m.frame_time = MAP, 0.0
    m.stage, m.t_stage = Stage.BACK, 0.0
    m.place, m.surfaces = "s0", {"s0": TABLES["desk"]}
    hold(seq, ctx, -2.0, -1.0, -math.pi / 2)  # before the coffee table, facing it
    from pydrake.systems.analysis import Simulator

    sim = Simulator(seq, ctx)
    sim.AdvanceTo(seq.p.back_time + 0.1)
    assert seq.memory(ctx).stage == Stage.VERIFY
    sim.AdvanceTo(seq.p.back_time + 0.1 + seq.p.verify_frames * (seq.p.look_settle + 0.5))
    return seq, ctx, det


def test_a_place_seen_on_the_coffee_table_is_done():
    h = 0.03  # the stub target's height (see tests/test_search_agent.sequencer)
    seq, ctx, det = verifying(np.array([-2.1, -1.95, 0.45 + h / 2]))
    m = seq.memory(ctx)
    assert m.stage == Stage.DONE and det.calls == 1 and "placed" in " ".join(m.log[-3:])


def test_a_placed_object_on_the_floor_or_not_seen_fails_with_the_reason():
    seq, ctx, det = verifying(np.array([-2.0, -1.55, 0.015]))  # rolled off onto the floor
    m = seq.memory(ctx)
    assert m.stage == Stage.FAILED and m.failure == "the placed object fell off the table"
    seq, ctx, det = verifying(None)
    m = seq.memory(ctx)
    assert m.stage == Stage.FAILED and det.calls == seq.p.verify_frames
    assert m.failure == "the placed object was not seen on the table"


def test_a_placed_object_seen_on_another_top_is_picked_up_again_once():
    on_kitchen_table = np.array([2.1, -2.3, 0.55 + 0.015])
    seq, ctx, det = verifying(on_kitchen_table)
    m = seq.memory(ctx)
    assert m.place_tries == 1 and "pick it up again" in " ".join(m.log[-3:]), m.log[-3:]
    assert m.stage in (Stage.APPROACH, Stage.NAVIGATE)  # on the way to pick it
    assert m.place == "fallen" and m.surfaces["fallen"].contains(on_kitchen_table)
    assert np.allclose(m.p_WO, on_kitchen_table)
    assert np.linalg.norm(m.pick_goal[:2] - on_kitchen_table[:2]) < 0.6
    # Placed again and seen there again: no more tries.
    m = seq.mutable_memory(ctx)
    m.stage, m.t_stage, m.t_still, m.look_tries = Stage.VERIFY, 100.0, -1.0, 0
    from pydrake.systems.analysis import Simulator

    sim = Simulator(seq, ctx)
    sim.get_mutable_context().SetTime(100.0)
    sim.AdvanceTo(100.0 + seq.p.look_settle + 0.5)
    m = seq.memory(ctx)
    assert m.stage == Stage.FAILED and m.failure == "the placed object fell off the table again"


@pytest.mark.parametrize("stage", [Stage.NAVIGATE, Stage.CARRY])
def test_no_path_left_to_a_walks_goal_gives_it_up_instead_of_standing(stage):
    seq, ctx = sequencer(detector=StubDetector(P_WO))
    sim = searching(seq, ctx, 2.0, 1.0, math.pi / 2)
    m = seq.mutable_memory(ctx)
    assert m.stage == Stage.NAVIGATE and m.nav_then == Stage.LOOK
    first = m.place
    m.stage = stage
    if stage == Stage.CARRY:
        seq.GetInputPort("pick_state").FixValue(ctx, PickState(True, "right_hand", "book"))
        m.hand, m.goal = 1, np.array([-2.0, -1.15, -math.pi / 2])
        # the robot walled in where it stands (real obstacles)
        walls = [((1.4, 2.6), (0.45, 0.55)), ((1.4, 2.6), (1.45, 1.55)),
                 ((1.45, 1.55), (0.45, 1.55)), ((2.45, 2.55), (0.45, 1.55))]
    else:  # the desk and the floor before it walled off
        walls = [((1.2, 2.8), (1.55, 1.65)), ((1.15, 1.25), (1.55, 3.95)),
                 ((2.75, 2.85), (1.55, 3.95))]
    world = MAP
    for xs, ys in walls:
        world = with_cells(world, xs, ys, 50, 0)
    m.map = world  # a new map version: the path is checked, blocked, and no plan is left
    sim.AdvanceTo(sim.get_context().get_time() + 0.1)
    m = seq.memory(ctx)
    assert any("give it up" in line for line in m.log), m.log[-4:]
    if stage == Stage.CARRY:
        assert m.stage == Stage.FAILED and m.failure == "no path to the destination"
    else:  # that top counts as searched; on to the next one
        assert len(m.searched) == 1 and TABLES["desk"].contains(m.searched[0])
        assert m.stage == Stage.NAVIGATE and m.place != first and m.path is not None
        assert not TABLES["desk"].contains(m.surfaces[m.place].center)


def test_a_place_from_a_base_stopped_short_reaches_towards_the_planned_drop_within_place_reach():
    """A failure at nominal physics (task 6 seed 3): the approach accepted a base 0.2 m short
    of the place pose; the object, released where the base stood, hung over the edge on the
    thigh. The hand now moves towards the planned drop, at most ``place_reach``."""
    from pr2_drake.agents.sequencer import Now

    seq, ctx, _ = placing()
    m = seq.mutable_memory(ctx)
    x, y, yaw = m.goal
    n = np.asarray(m.side, float)
    tab, p = seq.destination, seq.p

    def depth(o):  # the object's centre inside the near edge [m]
        return tab.side_frame(n)[0] - float(n @ (o[:2] - tab.center))

    planned = seq._drop_point(m, m.goal[:2], yaw, tab)
    at_pose = seq._place_drop(m, Now(10.0, np.array([x, y, 0.9]), yaw, True, 0.0))
    assert np.allclose(at_pose, planned)  # on its pose (object 0.17 m in): no reach
    assert depth(seq._held_object_at(m, m.goal[:2], yaw)) == pytest.approx(p.place_inset)

    short = np.array([x, y]) + 0.2 * n  # 0.2 m back from the table
    here = seq._drop_point(m, short, yaw, tab)
    drop = seq._place_drop(m, Now(10.0, np.array([*short, 0.9]), yaw, True, 0.0))
    assert drop[2] == pytest.approx(here[2])  # the same height
    assert np.linalg.norm(drop[:2] - here[:2]) == pytest.approx(p.place_reach)
    assert float(-n @ (drop[:2] - here[:2])) == pytest.approx(p.place_reach)  # towards the top
    assert "the hand reaches 0.12 m" in m.log[-1]
    o_here = seq._held_object_at(m, short, yaw)
    assert depth(o_here) == pytest.approx(p.place_inset - 0.2)  # it would have hung over
    assert depth(o_here + (drop[:2] - here[:2])) == pytest.approx(p.place_inset - 0.2 + 0.12)


def test_an_object_held_near_the_body_is_set_down_place_inset_inside_the_edge():
    """Held 0.25 m ahead, the place pose (the base ``place_standoff`` from the edge) would set
    it 0.10 m inside: the hand reaches the rest of ``place_inset``."""
    from pr2_drake.agents.sequencer import Now

    seq, ctx, _ = placing()
    m = seq.mutable_memory(ctx)
    m.r_pick, m.o_pick = np.array([0.15, -0.18, 0.05]), np.array([0.25, -0.25, 0.02])
    m.goal = seq._place_pose(m, seq.destination)
    x, y, yaw = m.goal
    n, tab = np.asarray(m.side, float), seq.destination
    drop = seq._place_drop(m, Now(10.0, np.array([x, y, 0.9]), yaw, True, 0.0))
    shift = drop[:2] - seq._drop_point(m, m.goal[:2], yaw, tab)[:2]
    assert np.allclose(shift, -n * (seq.p.place_inset - (0.25 - seq.p.place_standoff)))


def test_a_carry_whose_path_ends_short_of_its_goal_goes_on_from_that_end():
    """A goal inside the map's grown obstacles: the path ends at the free cell nearest it, where
    the path follower stops. Arrived there, the walk ends at once (even more than walk_arrive
    from the goal, where the stall watch never acts); short of that end it walks on."""
    seq, ctx, sim = placing()
    m = seq.mutable_memory(ctx)
    tab = seq.destination
    goal = np.array([tab.center[0], tab.center[1], -math.pi / 2])  # its centre
    start = np.array([tab.center[0], tab.center[1] + 2.0, 0.57])
    assert seq._plan(m, start, goal)
    m.stage = Stage.CARRY
    end = np.asarray(m.path[-1])
    short = float(np.linalg.norm(end - goal[:2]))
    assert short > seq.p.walk_arrive  # the case the stall watch missed
    hold(seq, ctx, end[0], end[1] + 0.3, goal[2])  # 0.3 m before the path's end: walking on
    sim.AdvanceTo(sim.get_context().get_time() + 0.3)
    assert seq.memory(ctx).stage == Stage.CARRY
    hold(seq, ctx, end[0], end[1] + 0.05, goal[2])  # at the end of the path
    sim.AdvanceTo(sim.get_context().get_time() + 0.3)
    m = seq.memory(ctx)
    log = " ".join(m.log[-3:])
    assert m.stage == Stage.APPROACH_TABLE and "at the path's end" in log, log


def test_a_walk_whose_path_reaches_its_goal_does_not_end_at_a_near_path_end():
    """The path's last point within a cell of the goal: the walk goes on to the goal's own
    approach_radius (the rule above leaves ordinary walks as they were)."""
    seq, ctx, sim = placing()
    m = seq.mutable_memory(ctx)
    tab = seq.destination
    goal = np.array([tab.center[0], tab.center[1] + 0.5 * tab.size[1] + 0.9, -math.pi / 2])
    start = np.array([tab.center[0], tab.center[1] + 2.5, 0.57])
    assert seq._plan(m, start, goal)
    m.stage = Stage.CARRY
    assert np.linalg.norm(np.asarray(m.path[-1]) - goal[:2]) <= seq.mp.resolution
    hold(seq, ctx, goal[0], goal[1] + 0.2, goal[2])  # 0.2 m out: past approach_radius
    sim.AdvanceTo(sim.get_context().get_time() + 0.3)
    assert seq.memory(ctx).stage == Stage.CARRY


def at_the_drop(drop_below_hand: float):
    """The sequencer in PLACE, its hand path ended 0.1 s ago at a drop point this far [m]
    below where the hand is (measured from the joint state)."""
    seq, ctx, sim = placing()
    x, y, yaw = seq.memory(ctx).goal
    hold(seq, ctx, x, y, yaw)
    m = seq.mutable_memory(ctx)
    m.stage = Stage.DONE  # one update: the robot model at this state
    sim.AdvanceTo(0.02)
    p_WH = seq.model.hand_point(m.hand)[0].copy()
    m = seq.mutable_memory(ctx)
    t = sim.get_context().get_time()
    m.stage, m.t_stage, m.place_lower = Stage.PLACE, t, 0.0
    m.hand_path = [p_WH + [0.0, 0.0, 0.08], p_WH - [0.0, 0.0, drop_below_hand]]
    m.hand_t0 = t - 0.1 - seq.p.reach_time * (len(m.hand_path) - 1) - 0.3
    return seq, ctx, sim, t


def test_a_place_releases_at_once_where_the_hand_reached_its_drop_point():
    seq, ctx, sim, t = at_the_drop(0.5 * SearchAgentParams().place_tolerance)
    sim.AdvanceTo(t + 0.03)
    m = seq.memory(ctx)
    assert m.stage == Stage.RELEASE and m.place_lower == 0.0


def test_a_place_with_the_hand_held_high_lowers_its_target_then_releases():
    """The arm sags 2.5 cm above its target (heavier load, weaker motors than the model's):
    the target moves down by the height error, within place_lower_max, and the release
    waits for place_settle_time (the hand here is held where it is: the limit decides)."""
    seq, ctx, sim, t = at_the_drop(0.025)
    p = seq.p
    drop = seq.memory(ctx).hand_path[-1].copy()
    sim.AdvanceTo(t + 0.5)
    m = seq.memory(ctx)
    assert m.stage == Stage.PLACE and 0.02 < m.place_lower <= p.place_lower_max
    assert np.allclose(m.targets[m.hand], drop - [0.0, 0.0, m.place_lower])
    sim.AdvanceTo(t + p.place_settle_time + 0.1)
    m = seq.memory(ctx)
    assert m.stage == Stage.RELEASE and m.place_lower == pytest.approx(p.place_lower_max)
    assert "moved 0.040 m down" in " ".join(m.log[-3:]), m.log[-3:]


def test_a_place_held_high_past_the_lowering_limit_draws_its_target_back_to_the_base():
    """The hand stays 5 cm above its drop point (a target beyond the arm's reach): once the
    target is place_lower_max down it is drawn back horizontally towards the base, within
    place_pull_max, and the release logs both."""
    seq, ctx, sim, t = at_the_drop(0.05)
    p = seq.p
    drop = seq.memory(ctx).hand_path[-1].copy()
    x, y, _ = seq.memory(ctx).goal
    sim.AdvanceTo(t + 0.15)
    m = seq.memory(ctx)
    assert m.place_lower < p.place_lower_max and m.place_pull == 0.0  # lowering first
    sim.AdvanceTo(t + p.place_settle_time - 0.5)  # the path ended 0.4 s before t
    m = seq.memory(ctx)
    assert m.stage == Stage.PLACE and m.place_lower == pytest.approx(p.place_lower_max)
    assert 0.02 < m.place_pull <= p.place_pull_max
    target = np.asarray(m.targets[m.hand], float)
    assert target[2] == pytest.approx(drop[2] - p.place_lower_max)
    moved = target[:2] - drop[:2]
    assert np.linalg.norm(moved) == pytest.approx(m.place_pull)
    base = np.array([x, y]) - drop[:2]
    assert moved @ base == pytest.approx(m.place_pull * np.linalg.norm(base))  # towards it
    sim.AdvanceTo(t + p.place_settle_time - 0.3)
    m = seq.memory(ctx)
    assert m.stage == Stage.RELEASE and "m back" in " ".join(m.log[-3:]), m.log[-3:]

"""Task-6 reference agent: the sequencer's stage logic on synthetic inputs (a stub detector,
fixed robot states, a map of the whole house as if seen), the search order and table sides,
and an unreadable sentence ending the episode with the parser's message; one closed-loop pick
(seed 0, started before the desk: a short scan, look, find the book, step in, reach, pick;
the whole episode is measured with ``pr2-drake eval --task 6``)."""

import math

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator

from pr2_drake.agents.search.memory import SearchAgentParams, Stage
from pr2_drake.agents.search.sequencer import ObjectSearchSequencer
from pr2_drake.agents.search.tables import (
    Table,
    best_side,
    in_heading,
    out_from_under,
    surface_order,
)
from pr2_drake.agents.search.instruction import Instruction, InstructionError
from pr2_drake.agents.search.mapping import MappingParams
from pr2_drake.agents.search.navigation import NavigationParams
from pr2_drake.agents.search.perception import CameraIntrinsics, Detection
from pr2_drake.grasp import PickState
from pr2_drake.ports import BODY_STATE_SIZE, JOINT_STATE_SIZE
from pr2_drake.tasks import get_task
from tests._search_sim import scene_map

SCENE = get_task(6).spec.scene
TABLES = {k: Table(k, np.array(f["center"], float), np.array(f["size"], float),
                   float(f["height"])) for k, f in SCENE["furniture"].items()}
MAP = scene_map(SCENE)
GRID = MAP.grid()
BOOK = Instruction("book", "desk", "study", "coffee_table", "living_room")


class StubDetector:
    """Finds the target at a fixed point (or nowhere); counts its calls."""

    def __init__(self, p_WO=None):
        self.p_WO = p_WO
        self.calls = 0

    def find(self, rgb, depth, X_WC, target):
        self.calls += 1
        if self.p_WO is None:
            return None
        return Detection(target, 1.0, np.asarray(self.p_WO, float), 0.6, 0.05, (0.2, 0.15), 100,
                         (0, 0, 1, 1))


class StubKinematics:
    def camera_pose(self, body_state, joint_state):
        from pydrake.math import RigidTransform

        return RigidTransform()


def body_state(x: float, y: float, yaw: float) -> np.ndarray:
    b = np.zeros(BODY_STATE_SIZE)
    b[:3] = [x, y, 0.57]
    b[3:7] = [math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)]
    return b


def sequencer(instruction=BOOK, detector=None, error="", expected_height=0.60):
    seq = ObjectSearchSequencer(instruction, TABLES["coffee_table"], detector or StubDetector(),
                                0.03, CameraIntrinsics.from_fov(4, 4, 60.0), 0.1,
                                ((-4.0, -4.0), (4.0, 4.0)), SearchAgentParams.load(),
                                NavigationParams.load(), StubKinematics(), error,
                                expected_height, MappingParams.load())
    ctx = seq.CreateDefaultContext()
    seq.GetInputPort("joint_state").FixValue(ctx, np.zeros(JOINT_STATE_SIZE))
    seq.GetInputPort("pick_state").FixValue(ctx, PickState())
    seq.GetInputPort("walker_status").FixValue(ctx, np.array([1.0, 0, 0, 0, 0, 0]))  # standing
    from pr2_drake.camera import RgbdFrame

    seq.GetInputPort("rgbd").FixValue(ctx, RgbdFrame(np.zeros((4, 4, 3), np.uint8),
                                                     np.ones((4, 4), np.float32)))
    return seq, ctx


def searching(seq, ctx, x: float, y: float, yaw: float, world=MAP):
    """The robot at (x, y, yaw), the scan done with ``world`` in the map: on to a top."""
    seq.GetInputPort("body_state").FixValue(ctx, body_state(x, y, yaw))
    m = seq.mutable_memory(ctx)
    m.map, m.frame_time = world, 0.0  # (the stub frame is not mapped)
    seq._next_place(m, np.array([x, y, 0.57]), 0.0)
    return Simulator(seq, ctx)


def test_search_order_hinted_then_named_height_then_nearest():
    p = SearchAgentParams.load()
    tops = [TABLES[k] for k in ("kitchen_table", "play_table", "desk")]
    p0 = np.array([2.0, -1.0])  # in the kitchen
    order = [t.name for t in surface_order(tops, [], None, p0, p)]
    assert order == ["kitchen_table", "desk", "play_table"]  # nearest first
    assert surface_order(tops, [], 0.50, p0, p)[0].name == "play_table"  # the named height
    seen = [np.array([1.9, 2.8, 0.64])]  # the target seen on the desk while scanning
    assert surface_order(tops, seen, 0.50, p0, p)[0].name == "desk"


def test_the_map_tops_are_the_tables_and_the_destination_is_never_searched():
    seq, ctx = sequencer()
    searching(seq, ctx, 2.0, 1.0, math.pi / 2)
    m = seq.memory(ctx)

    def top_of(name):
        t = TABLES[name]
        return next((k for k, s in m.surfaces.items() if s.contains(t.center)
                     and abs(s.height - t.height) < 0.01), None)

    assert top_of("coffee_table") is None  # the destination (the decor's seats are tops too)
    assert None not in [top_of(k) for k in ("kitchen_table", "play_table", "desk")]
    assert m.place == top_of("desk")  # the sentence's desk: its height first
    top = m.surfaces[m.place]
    assert np.allclose(top.center, TABLES["desk"].center, atol=0.03)
    assert np.allclose(top.size, TABLES["desk"].size, atol=0.06)
    assert top.height == pytest.approx(TABLES["desk"].height)


def test_tables_are_approached_from_their_open_long_side():
    r = NavigationParams().robot_radius
    assert np.allclose(best_side(GRID, TABLES["desk"], 0.55, r), [0, -1])  # desk at the wall
    assert np.allclose(best_side(GRID, TABLES["play_table"], 0.55, r), [0, -1])
    assert np.allclose(best_side(GRID, TABLES["kitchen_table"], 0.55, r), [0, 1])
    assert np.allclose(best_side(GRID, TABLES["coffee_table"], 0.55, r), [0, 1])  # not the sofa


def test_stages_walk_look_and_approach_the_detected_object():
    p_WO = np.array([2.3, 2.7, 0.63])
    det = StubDetector(p_WO)
    seq, ctx = sequencer(detector=det)
    # At the desk's look pose, facing it: NAVIGATE ends at once, LOOK takes a frame.
    sim = searching(seq, ctx, 2.0, 2.5 - 0.55, math.pi / 2)
    sim.AdvanceTo(0.05)
    m = seq.memory(ctx)
    assert m.stage == Stage.LOOK and m.surfaces[m.place].contains(TABLES["desk"].center)
    sim.AdvanceTo(1.0)
    assert det.calls == 1 and seq.memory(ctx).stage == Stage.APPROACH
    assert np.allclose(seq.memory(ctx).p_WO, p_WO)
    # The pick pose: facing the desk (+y), before its south edge, in line with the object.
    x, y, yaw = seq.memory(ctx).goal
    assert yaw == pytest.approx(math.pi / 2)
    assert y == pytest.approx(2.5 - seq.p.pick_standoff)
    assert abs(x - p_WO[0]) <= seq.p.hand_lateral + 1e-9
    assert seq.memory(ctx).hand == 1  # object to the robot's right: the right hand
    vx, vy, _ = seq.GetOutputPort("velocity_command").Eval(ctx)
    assert vx > 0 and vy < 0  # steps forward and to the right


def test_nothing_found_moves_on_to_the_next_table():
    det = StubDetector(None)
    seq, ctx = sequencer(detector=det)
    sim = searching(seq, ctx, 2.0, 1.95, math.pi / 2)
    desk = seq.memory(ctx).place
    sim.AdvanceTo(1.0)
    assert seq.memory(ctx).stage == Stage.LOOK
    cmd = seq.GetOutputPort("velocity_command").Eval(ctx)
    assert det.calls == 2 and cmd[2] > 0  # two frames, then turns to the next heading
    # Never turning (the body state is fixed), it keeps asking to turn; a detection far from
    # the searched table is ignored.
    det.p_WO = np.array([-2.0, 2.6, 0.55])  # on the play table
    m = seq.mutable_memory(ctx)
    m.look_k = len(seq.p.look_yaws_deg) - 1
    m.t_still = -1.0
    seq.GetInputPort("body_state").FixValue(ctx, body_state(2.0, 1.95, math.pi / 2 - 0.52))
    sim.AdvanceTo(3.0)
    m = seq.memory(ctx)
    assert m.stage == Stage.NAVIGATE and not m.surfaces[m.place].contains(TABLES["desk"].center)
    assert m.path is not None and len(m.path) >= 2  # on to the next table
    assert len(m.searched) == 1 and TABLES["desk"].contains(m.searched[0])  # never again
    assert desk not in m.surfaces or not m.surfaces[desk].contains(TABLES["desk"].center)


def _last_look_heading(seq, ctx, sim, t: float):
    """Let the look at the goal's pose reach its last heading (the body turned to it) by t."""
    x, y, yaw = seq.memory(ctx).goal
    m = seq.mutable_memory(ctx)
    m.look_k = len(seq.p.look_yaws_deg) - 1
    m.t_still = -1.0
    seq.GetInputPort("body_state").FixValue(
        ctx, body_state(x, y, yaw + math.radians(seq.p.look_yaws_deg[-1])))
    sim.AdvanceTo(t)


def test_a_top_the_scan_saw_the_target_on_is_looked_at_from_another_side():
    # The scan saw the book on the desk, but the look from the desk's open side finds
    # nothing (another object hides it from there): the robot walks to another side of the
    # desk and looks again before it gives the desk up.
    det = StubDetector(None)
    seq, ctx = sequencer(detector=det)
    seq.mutable_memory(ctx).hints = [np.array([2.3, 2.7, 0.66])]  # on the desk, while scanning
    sim = searching(seq, ctx, 2.0, 1.95, math.pi / 2)
    desk = seq.memory(ctx).place
    assert seq.memory(ctx).surfaces[desk].contains(TABLES["desk"].center)
    sim.AdvanceTo(0.5)
    first_goal = seq.memory(ctx).goal.copy()
    assert seq.memory(ctx).stage == Stage.LOOK
    _last_look_heading(seq, ctx, sim, 2.0)
    m = seq.memory(ctx)
    assert m.stage == Stage.NAVIGATE and m.nav_then == Stage.LOOK and m.place == desk
    assert m.searched == [] and len(m.look_sides) == 1
    n1 = m.look_sides[0]
    assert np.allclose(n1, [0, -1])  # the first look was from the open long side
    # The new look pose faces the desk from another side, look_distance out from its edge.
    x, y, yaw = m.goal
    assert not np.allclose(m.goal, first_goal)
    n2 = -np.array([math.cos(yaw), math.sin(yaw)])
    assert abs(float(n2 @ n1)) < 1e-9  # a short side of the desk
    half = TABLES["desk"].size[0] / 2
    assert abs(float((np.array([x, y]) - TABLES["desk"].center) @ n2)) == pytest.approx(
        half + seq.p.look_distance, abs=0.05)
    # Found nothing from there either (look_sides: 2 in all): the desk is given up.
    seq.GetInputPort("body_state").FixValue(ctx, body_state(x, y, yaw))
    sim.AdvanceTo(2.5)
    assert seq.memory(ctx).stage == Stage.LOOK
    _last_look_heading(seq, ctx, sim, 4.5)
    m = seq.memory(ctx)
    assert m.stage == Stage.NAVIGATE and m.place != desk
    assert len(m.searched) == 1 and TABLES["desk"].contains(m.searched[0])
    assert m.look_sides == []


def test_unreadable_sentence_ends_with_the_parsers_message():
    seq, ctx = sequencer(instruction=None, error="no object named in 'bring me a banana'")
    sim = Simulator(seq, ctx)
    seq.GetInputPort("body_state").FixValue(ctx, body_state(0.0, 0.0, 0.0))
    with pytest.raises(InstructionError, match="banana"):
        sim.AdvanceTo(0.1)


def test_agent_builds_with_a_bad_sentence_and_refuses_other_priors():
    from pr2_drake.agents.search.agent import ObjectSearchAgent
    from pr2_drake.paths import resolve_user_path

    models = {}
    for name, o in SCENE["objects"].items():
        sdf = resolve_user_path(o["model"], name)
        models[name] = {"sdf": str(sdf), "mesh": str(sdf.with_suffix(".obj")),
                        "label": o["label"]}
    agent = ObjectSearchAgent({"object_models": models, "instruction": "fetch the banana",
                               "coffee_table_center": [-2.0, -2.0, 0.45],
                               "coffee_table_size": [1.0, 0.6]})
    seq = agent.GetSubsystemByName("sequencer")
    assert seq.instruction is None and "banana" in seq.error
    assert {agent.get_input_port(i).get_name() for i in range(agent.num_input_ports())} == {
        "joint_state", "body_state", "pick_state", "rgbd"}
    with pytest.raises(ValueError, match="object_models"):
        ObjectSearchAgent({"valve_center": [0, 0, 1]})


def test_agent_takes_navigation_overrides_and_names_a_missing_file(tmp_path):
    from pr2_drake.agents.search.agent import ObjectSearchAgent
    from pr2_drake.agents.search.navigation import NavigationParams
    from pr2_drake.paths import resolve_user_path

    models = {}
    for name, o in SCENE["objects"].items():
        sdf = resolve_user_path(o["model"], name)
        models[name] = {"sdf": str(sdf), "mesh": str(sdf.with_suffix(".obj")),
                        "label": o["label"]}
    priors = {"object_models": models, "instruction": "bring the apple to the coffee table",
              "coffee_table_center": [-2.0, -2.0, 0.45], "coffee_table_size": [1.0, 0.6]}
    base = NavigationParams.load()
    override = tmp_path / "nav.yaml"
    override.write_text(f"lookahead: {base.lookahead + 0.25}\n")
    nav = ObjectSearchAgent(priors, navigation_params=str(override)).GetSubsystemByName(
        "sequencer").nav
    assert nav.lookahead == pytest.approx(base.lookahead + 0.25)
    assert nav.max_yaw_rate == base.max_yaw_rate  # only the file's entries change
    with pytest.raises(Exception, match="nope.yaml"):
        ObjectSearchAgent(priors, navigation_params=str(tmp_path / "nope.yaml"))


def test_closed_loop_pick_on_seed_0_from_the_desk(tmp_path):
    """Seed 0: the book on the desk. The robot starts before the desk (start override) and
    scans no more than its first frame (a parameter file), so the walk from the study's door
    and the turn on the spot are skipped; everything else is the full agent: the desk found
    in the map of that frame."""
    from tests._search_sim import desk_episode

    params = tmp_path / "search.yaml"
    params.write_text("scan_turn_deg: 0.0\n")
    ep, agent = desk_episode(16.0, str(params))
    assert ep.testbed.scene.data["target"] == "book"
    ep.initialize()
    status = ep.advance_to(16.0)
    items = [i.item for i in status.items]
    seq = agent.GetSubsystemByName("sequencer")
    m = seq.memory(seq.GetMyContextFromRoot(ep.context))
    assert "pick_target" in items, m.log
    true = ep.testbed.scene.data["initial_poses"]["book"].translation()
    assert np.linalg.norm(m.p_WO - true) < 0.05  # found by the camera, not told


def test_object_on_the_far_half_is_picked_from_the_other_side():
    det = StubDetector(np.array([2.0, 3.04, 0.63]))  # desk's far (north) edge
    seq, ctx = sequencer(detector=det)
    sim = searching(seq, ctx, 2.0, 1.95, math.pi / 2)
    sim.AdvanceTo(1.0)
    assert seq.memory(ctx).stage == Stage.NAVIGATE and seq.memory(ctx).nav_then == Stage.APPROACH
    x, y, yaw = seq.memory(ctx).pick_goal
    assert y == pytest.approx(3.1 + seq.p.pick_standoff) and yaw == pytest.approx(-math.pi / 2)
    assert np.linalg.norm(seq.memory(ctx).path[-1] - [x, 3.1 + seq.p.stage_distance]) < 0.1


def test_approach_stopped_short_by_the_table_settles_after_a_timeout():
    seq, ctx = sequencer(detector=StubDetector(np.array([2.3, 2.7, 0.63])))
    sim = searching(seq, ctx, 2.0, 1.95, math.pi / 2)
    sim.AdvanceTo(1.0)
    assert seq.memory(ctx).stage == Stage.APPROACH
    x, y, yaw = seq.memory(ctx).goal
    seq.GetInputPort("body_state").FixValue(ctx, body_state(x, y - 0.07, yaw))  # 7 cm short
    sim.AdvanceTo(1.0 + seq.p.approach_timeout - 0.5)
    assert seq.memory(ctx).stage == Stage.APPROACH
    sim.AdvanceTo(1.0 + seq.p.approach_timeout + 0.5)
    assert seq.memory(ctx).stage in (Stage.SETTLE, Stage.REACH)


def test_object_models_load_from_any_working_folder(tmp_path, monkeypatch):
    """The priors give mesh paths relative to the data root; a sandboxed agent runs elsewhere."""
    from pr2_drake.agents.search.perception import load_object_model

    monkeypatch.chdir(tmp_path)
    model = load_object_model("cup", "models/objects/cup/cup.obj")
    assert 0.05 < model.height < 0.3
    with pytest.raises(FileNotFoundError, match="object model mesh of 'cup'"):
        load_object_model("cup", "models/objects/cup/missing.obj")


def test_the_object_is_placed_with_the_arm_as_at_the_pick():
    seq, ctx = sequencer()
    tab = seq.destination
    m = seq.mutable_memory(ctx)
    m.side = np.array([0.0, 1.0])  # approached from its +y side (the sofa is at -y)
    m.r_pick = np.array([0.35, -0.18, 0.05])  # hand at the pick, heading frame
    m.o_pick = np.array([0.45, -0.25, 0.02])  # the object it held
    m.hand_over_top = 0.09
    x, y, yaw = seq._place_pose(m, tab)
    assert yaw == pytest.approx(-math.pi / 2)  # facing the table
    c, s = math.cos(yaw), math.sin(yaw)
    p_obj = np.array([x + c * 0.45 + s * 0.25, y + s * 0.45 - c * 0.25])
    near_edge = tab.center[1] + tab.size[1] / 2
    assert p_obj[1] == pytest.approx(near_edge - seq.p.place_inset)  # inset from the edge
    assert p_obj[0] == pytest.approx(tab.center[0])  # on the centre line
    p_WB = np.array([x, y, 0.57])
    drop = seq._drop_point(m, p_WB, yaw, tab)
    assert np.allclose(in_heading(p_WB, yaw, drop)[:2], [0.35, -0.18])  # arm as before
    assert drop[2] == pytest.approx(tab.height + 0.09 + seq.p.place_clearance)
    # Set down upright: while placing, the hand target carries the object's vertical in the
    # hand frame (the QP keeps it vertical); while walking it does not.
    m.hand, m.targets, m.up_H = 1, [None, drop], np.array([0.0, 0.6, 0.8])
    for stage, size in ((Stage.PLACE, 6), (Stage.RELEASE, 6), (Stage.CARRY, 3)):
        seq.mutable_memory(ctx).stage = stage  # (the output sees the change)
        target = seq.GetOutputPort("hand_targets").Eval(ctx)[1]
        assert target.size == size and np.allclose(target[:3], drop)
    # A short reach would put the base against the table: it keeps place_standoff, and the
    # object lands deeper.
    m.o_pick = np.array([0.2, -0.2, 0.0])
    _, y, _ = seq._place_pose(m, tab)
    assert y - near_edge == pytest.approx(seq.p.place_standoff)


def test_an_object_out_of_reach_from_the_look_side_is_picked_from_the_nearest_free_side():
    # 0.45 m inside the desk's south (look) edge, 0.10 m from its west end: beyond the arm's
    # reach from the south, so the robot walks round to the nearest side with floor.
    p_WO = np.array([1.5, 2.95, 0.63])
    seq, ctx = sequencer(detector=StubDetector(p_WO))
    searching(seq, ctx, 2.0, 1.95, math.pi / 2).AdvanceTo(1.0)
    assert seq.memory(ctx).stage == Stage.NAVIGATE and seq.memory(ctx).nav_then == Stage.APPROACH
    tab = seq.memory(ctx).surfaces[seq.memory(ctx).place]
    depth = tab.side_frame(seq.memory(ctx).side)[0] - float((p_WO[:2] - tab.center) @ seq.memory(ctx).side)
    assert depth <= 0.15 + 1e-9  # the west end (0.10) or the north side (0.15), not 0.45
    x, y, yaw = seq.memory(ctx).pick_goal
    assert np.allclose([math.cos(yaw), math.sin(yaw)], -seq.memory(ctx).side)  # facing the table
    grid = GRID.inflated(seq.nav.robot_radius)
    assert grid.free(seq.memory(ctx).path[-1])


def test_the_grasp_point_keeps_away_from_other_objects_seen():
    # pick latches the object nearest the hand: a bottle standing between the target and the
    # shoulder would be picked instead, so the hand comes from another side.
    seq, ctx = sequencer()
    m = seq.mutable_memory(ctx)
    m.hand = 1
    m.p_WO = np.array([1.906, -2.35, 0.596])
    shoulder = np.array([1.85, -1.98, 0.902])
    seq.model.shoulder_position = lambda side: shoulder
    plain = seq._grasp_point(m, seq.p.grasp_offset)  # nothing else seen: towards the shoulder
    to_shoulder = (shoulder - m.p_WO) / np.linalg.norm(shoulder - m.p_WO)
    assert np.allclose(plain, m.p_WO + seq.p.grasp_offset * to_shoulder)
    m.others = [np.array([1.803, -2.304, 0.665])]  # a bottle on that side (seed 19)
    g = seq._grasp_point(m, seq.p.grasp_offset)
    assert np.linalg.norm(g - m.p_WO) == pytest.approx(seq.p.grasp_offset)
    assert np.linalg.norm(g - m.others[0]) >= seq.p.grasp_offset + seq.p.grasp_margin
    assert np.linalg.norm(plain - m.others[0]) < seq.p.grasp_offset  # would have taken it
    assert np.linalg.norm(g - shoulder) <= seq.p.reach


def test_a_hand_hanging_under_a_table_edge_backs_out_before_it_rises():
    tab = Table("desk", np.array([0.0, 0.0]), np.array([1.0, 0.6]), 0.60)  # edge at y = -0.3
    margin = SearchAgentParams(edge_clearance=0.07).edge_clearance
    facing = np.array([0.0, 1.0])  # the robot at y < -0.3, facing the desk
    back = out_from_under(np.array([0.1, -0.27, 0.50]), facing, tab, margin)  # 3 cm under
    assert back is not None and back[2] == 0.50 and back[0] == 0.1  # straight back, same height
    assert not tab.contains(back, 0.07) and back[1] > -0.3 - 0.07 - 0.02
    assert out_from_under(np.array([0.1, -0.45, 0.50]), facing, tab, margin) is None  # clear
    assert out_from_under(np.array([0.1, -0.27, 0.65]), facing, tab, margin) is None  # above


def picking():
    """The sequencer in PICK at t = 1 s at the desk's object (seen from its south side), and
    that side's outward normal."""
    seq, ctx = sequencer(detector=StubDetector(np.array([2.3, 2.7, 0.63])))
    sim = searching(seq, ctx, 2.0, 1.95, math.pi / 2)
    sim.AdvanceTo(1.0)
    m = seq.mutable_memory(ctx)
    look = np.array(m.side)
    assert np.allclose(look, [0, -1])  # reachable from the look side: no walk round yet
    m.stage, m.t_stage = Stage.PICK, 1.0
    return seq, ctx, sim, look


def test_a_pick_that_misses_from_one_side_walks_round_to_the_next_free_side():
    # The hand never closes on the object (no attachment): after ``pick_tries`` the robot
    # lifts the hand, steps back and walks round to another side with floor on the map.
    seq, ctx, sim, look = picking()
    sim.AdvanceTo(1.0 + seq.p.pick_tries * seq.p.pick_timeout + 0.1)
    m = seq.memory(ctx)
    assert m.stage == Stage.RETRACT and m.retry_side is not None
    assert not np.allclose(m.retry_side, look) and np.allclose(m.sides_tried[0], look)
    sim.AdvanceTo(sim.get_context().get_time() + seq.p.back_time + 2 * seq.p.reach_time + 1.0)
    m = seq.memory(ctx)
    assert m.stage == Stage.NAVIGATE and m.nav_then == Stage.APPROACH
    assert not np.allclose(m.side, look) and m.retry_side is None
    assert GRID.inflated(seq.nav.robot_radius).free(m.path[-1])


def test_a_pick_that_latched_another_object_lets_go_and_walks_round_to_the_next_side():
    # The grasp latches the object nearest the hand: here the teddy bear beside the book.
    # The sequencer lets go of it (RELEASE, no LIFT), then steps back and walks round.
    seq, ctx, sim, look = picking()
    seq.GetInputPort("pick_state").FixValue(ctx, PickState(True, "right_hand", "teddy_bear"))
    sim.AdvanceTo(1.1)
    m = seq.memory(ctx)
    assert m.stage == Stage.RELEASE, m.log[-3:]
    assert "holds teddy_bear, not book" in " ".join(m.log[-3:])
    assert seq.GetOutputPort("release").Eval(ctx) is True
    assert np.allclose(m.sides_tried[0], look) and not np.allclose(m.retry_side, look)
    seq.GetInputPort("pick_state").FixValue(ctx, PickState())  # let go
    sim.AdvanceTo(1.1 + seq.p.release_hold + 2 * seq.p.reach_time + seq.p.back_time + 1.0)
    m = seq.memory(ctx)
    assert m.stage == Stage.NAVIGATE and m.nav_then == Stage.APPROACH, m.log[-4:]
    assert not np.allclose(m.side, look) and m.retry_side is None
    assert "LIFT" not in " ".join(m.log)


def test_a_pick_of_the_target_lifts_it():
    seq, ctx, sim, _ = picking()
    seq.GetInputPort("pick_state").FixValue(ctx, PickState(True, "right_hand", "book"))
    sim.AdvanceTo(1.1)
    assert seq.memory(ctx).stage == Stage.LIFT

"""Whole-body control as parts (pr2_drake.controllers.{tasks,gait,whole_body,footsteps}):
task rows, the QP with the arms and a hand contact force, a footstep planner of our own, hand
targets, and the task-2 reference agent."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from pr2_drake.bench.rigs import WalkingSim
from pr2_drake.controllers.planning.footsteps import FixedFootstepPlanner, FootstepPlanner
from pr2_drake.controllers.plan import WholeBodyPlan
from pr2_drake.controllers.tracking.objectives import HandUprightObjective, PostureObjective, ObjectiveCost
from pr2_drake.controllers.walking_params import WalkingParams
from pr2_drake.controllers.model import WholeBodyModel
from pr2_drake.controllers.tracking.qp import WholeBodyQp
from pr2_drake.controllers.whole_body import WholeBodyController, check_hand_targets
from pr2_drake.ports import N_ARMS, Q_ARMS


def _standing_q(model: WholeBodyModel) -> np.ndarray:
    """The nominal pose with the base at standing height (the soles near z = 0)."""
    q = model.q_nominal.copy()
    q[model.maps.q_base[:4]] = [1.0, 0.0, 0.0, 0.0]
    q[model.maps.q_base[4:]] = [0.0, 0.0, 0.58]
    return q


def test_posture_task_alone_sets_the_joint_accelerations():
    """No contacts, only a posture task: the QP's joint accelerations equal its target (the
    base falls freely; the arms and legs are actuated)."""
    params = WalkingParams.load()
    m = WholeBodyModel()
    q = _standing_q(m)
    rng = np.random.default_rng(0)
    q_nominal = q[m.maps.q_joints] + rng.uniform(-0.05, 0.05, len(m.maps.q_joints))
    v = np.zeros(m.nv)
    m.update(q, v)
    n = len(m.maps.v_joints)
    task = PostureObjective(m, q_nominal, np.full(n, 20.0), np.full(n, 4.0), np.ones(n))
    plan = WholeBodyPlan()
    (J, a, w), = task.rows(m, plan)
    np.testing.assert_allclose(a, 20.0 * (q_nominal - q[m.maps.q_joints]))
    assert J.shape == (n, m.nv) and np.all(w == 1.0)
    cost = ObjectiveCost(m.nv)
    task.add_to(cost, m, plan)
    qp = WholeBodyQp(m.nv, m.maps.v_base, m.v_legs, m.effort[N_ARMS:], 2 * m.n_points,
                     params.qp, arm_v=m.v_arms, arm_effort=m.effort[:N_ARMS])
    res = qp.solve(m.mass_matrix(), m.bias(), np.zeros((6 * m.n_points, m.nv)), cost.H,
                   cost.g, np.zeros(2 * m.n_points))
    assert res.ok
    np.testing.assert_allclose(res.vdot[m.maps.v_joints], a, atol=1e-3)
    # Free fall: the base accelerates down with gravity (no support).
    assert res.vdot[m.maps.v_base[5]] == pytest.approx(-m.gravity, abs=0.05)
    # The torques reproduce the dynamics: M vdot + h = [0; tau].
    gen = m.mass_matrix() @ res.vdot + m.bias()
    np.testing.assert_allclose(gen[m.maps.v_base], 0.0, atol=1e-6)
    np.testing.assert_allclose(gen[m.v_legs], res.tau, atol=1e-6)
    np.testing.assert_allclose(gen[m.v_arms], res.tau_arms, atol=1e-6)


def _posture_problem(kp: float):
    """Free fall with a posture task of gain ``kp`` [1/s^2] towards a pose 0.05 rad off: the
    model, its cost and the posture accelerations the task asks for."""
    m = WholeBodyModel()
    q = _standing_q(m)
    rng = np.random.default_rng(1)
    q_nominal = q[m.maps.q_joints] + rng.uniform(-0.05, 0.05, len(m.maps.q_joints))
    m.update(q, np.zeros(m.nv))
    n = len(m.maps.v_joints)
    task = PostureObjective(m, q_nominal, np.full(n, kp), np.full(n, 4.0), np.ones(n))
    cost = ObjectiveCost(m.nv)
    task.add_to(cost, m, WholeBodyPlan())
    return m, cost, kp * (q_nominal - q[m.maps.q_joints])


def _solve_free(m, cost, arm_effort, arm_limits):
    qp = WholeBodyQp(m.nv, m.maps.v_base, m.v_legs, m.effort[N_ARMS:], 2 * m.n_points,
                     WalkingParams.load().qp, arm_v=m.v_arms, arm_effort=arm_effort,
                     arm_limits=arm_limits)
    res = qp.solve(m.mass_matrix(), m.bias(), np.zeros((6 * m.n_points, m.nv)), cost.H,
                   cost.g, np.zeros(2 * m.n_points))
    assert res.ok
    return res


def test_arm_rows_left_out_of_the_qp_change_nothing_until_an_arm_limit_binds():
    """``arm_limits=False`` (arms="balance"): the arm torque rows leave the QP. Far from the
    arms' peak torques the solution is the one with the rows; where a limit would bind, the
    arms follow their posture task anyway and their torques are clamped afterwards."""
    m, cost, a = _posture_problem(200.0)
    arm_effort = m.effort[:N_ARMS]
    with_rows = _solve_free(m, cost, arm_effort, True)
    without = _solve_free(m, cost, arm_effort, False)
    np.testing.assert_allclose(without.vdot, with_rows.vdot, atol=1e-9)
    np.testing.assert_allclose(without.tau_arms, with_rows.tau_arms, atol=1e-6)
    np.testing.assert_allclose(without.tau, with_rows.tau, atol=1e-6)
    # Arm peak torques of 0.05 Nm: the rows bound the arm torques (the arms lag their task);
    # without them the arms track the task and the output torques are clamped.
    weak = np.full(N_ARMS, 0.05)
    bound = _solve_free(m, cost, weak, True)
    free = _solve_free(m, cost, weak, False)
    gen = m.mass_matrix() @ bound.vdot + m.bias()
    np.testing.assert_allclose(gen[m.v_arms], bound.tau_arms, atol=1e-6)
    assert np.all(np.abs(gen[m.v_arms]) <= weak + 1e-6)
    arms = m.maps.v_joints[:N_ARMS]
    np.testing.assert_allclose(free.vdot[arms], a[:N_ARMS], atol=1e-3)
    assert np.abs(bound.vdot[arms] - a[:N_ARMS]).max() > 0.1
    need = (m.mass_matrix() @ free.vdot + m.bias())[m.v_arms]
    assert np.any(np.abs(need) > 2 * weak)
    np.testing.assert_allclose(free.tau_arms, np.clip(need, -weak, weak), atol=1e-9)


def test_balance_arms_are_driven_by_the_qp_without_hand_inputs():
    """arms="balance": the walking QP outputs arm torques (effort mode), with no hand-target
    or pick-state inputs and no hand-force variables; the robot walks, arms swinging."""
    sim = WalkingSim(arms="balance")
    walker = sim.walker
    assert walker.core.arms_driven and not walker.core.hands
    assert not walker.HasInputPort("hand_targets") and not walker.HasInputPort("pick_state")
    assert walker.core.qp.n_hands == 0
    sim.run(0.5)
    q0 = sim.testbed.GetOutputPort("joint_state").Eval(
        sim.testbed.GetMyContextFromRoot(sim.context))[Q_ARMS].copy()
    sim.set_command(0.3, 0.0, 0.0)
    p0, *_ = sim.base_pose()
    moved = 0.0
    for _ in range(15):
        assert sim.run(0.2), "the robot fell"
        q = sim.testbed.GetOutputPort("joint_state").Eval(
            sim.testbed.GetMyContextFromRoot(sim.context))[Q_ARMS]
        moved = max(moved, float(np.abs(q - q0).max()))
    p1, *_ = sim.base_pose()
    assert p1[0] - p0[0] > 0.3
    cmd = walker.GetOutputPort("arms_command").Eval(sim.walker_context)
    assert cmd.mode == "effort" and np.all(np.abs(cmd.values) <= walker.core.arm_effort + 1e-9)
    assert moved > 0.02  # [rad] the QP moves the arms; a position-mode posture holds them


def test_held_hand_force_is_a_bounded_qp_variable():
    """With a hand attached, its contact force enters the floating-base rows and stays within
    the configured bounds; without, it is zero."""
    core = WholeBodyController(arms="effort")
    m = core.model
    q = _standing_q(m)
    v = np.zeros(m.nv)
    core.update(0.0, q, v, np.zeros(3))
    np.testing.assert_array_equal(core.last_result.hand_forces, 0.0)
    m.update(q, v)
    target = m.hand_point(0)[0] + np.array([0.05, 0.0, 0.05])
    core.update(0.004, q, v, np.zeros(3), hand_targets=[target, None], attached=(True, False))
    res = core.last_result
    assert res.ok and res.tau_arms.shape == (N_ARMS,)
    f_hand = res.hand_forces
    assert np.all(np.abs(f_hand[0]) <= core.params.qp.hand_force_max + 1e-6)
    np.testing.assert_array_equal(f_hand[1], 0.0)
    m.update(q, v)
    Jc = core.contacts.J_all
    J_hand = m.hand_point(0)[2]
    gen = (m.mass_matrix() @ res.vdot + m.bias() - Jc.T @ res.forces.reshape(-1)
           - J_hand.T @ f_hand[0])
    assert np.max(np.abs(gen[m.maps.v_base])) < 0.5
    np.testing.assert_allclose(gen[m.v_arms], res.tau_arms, atol=0.5)


def test_hand_targets_are_checked_and_clipped():
    with pytest.raises(ValueError, match="hand_targets"):
        check_hand_targets([[0.1, np.nan, 0.8], None])
    with pytest.raises(ValueError, match="hand_targets"):
        check_hand_targets([[0.1, 0.2], None])
    with pytest.raises(ValueError, match="hand_targets"):
        check_hand_targets([None])
    assert check_hand_targets({"right_hand": [0.3, -0.2, 0.8]})[0] is None
    core = WholeBodyController(arms="effort")
    m = core.model
    q = _standing_q(m)
    core.update(0.0, q, np.zeros(m.nv), np.zeros(3))
    far = m.shoulder_position(0) + np.array([2.0, 0.0, 0.0])
    clipped = core.clip_hand_target(0, far)
    assert np.linalg.norm(clipped - m.shoulder_position(0)) == pytest.approx(
        core.params.arms.reach_max)
    low = core.clip_hand_target(0, m.shoulder_position(0) + np.array([0.1, 0.0, -0.9]))
    assert low[2] >= core.planner.plan.ground_z + core.params.arms.z_min - 1e-9
    with pytest.raises(ValueError, match="hand_targets"):
        core.update(0.004, q, np.zeros(m.nv), np.zeros(3), hand_targets=[[np.inf, 0, 1], None])


def test_hand_target_in_reach_is_reached_while_standing():
    sim = WalkingSim(arms="effort")
    assert sim.run(1.0)
    m = sim.walker.core.model
    p_WB, *_ = sim.base_pose()
    target = p_WB + np.array([0.28, 0.12, 0.15])
    sim.set_hand_targets([target, None])
    assert sim.run(3.0)  # no fall
    err = np.linalg.norm(m.hand_point(0)[0] - target)
    assert err < 0.02, err
    p1, roll, pitch, _ = sim.base_pose()
    assert abs(roll) < 0.1 and abs(pitch) < 0.1
    assert np.linalg.norm(p1[:2] - p_WB[:2]) < 0.05  # no stepping away


def _tilt_after_lowering(upright: bool) -> float:
    """Angle [deg] of a held object's vertical after the right hand went 0.10 m down (its
    vertical is the hand-frame axis that was up before), with and without the up axis."""
    sim = WalkingSim(arms="effort")
    assert sim.run(1.0)
    m = sim.walker.core.model
    p_WB, *_ = sim.base_pose()
    above = p_WB + np.array([0.30, -0.20, 0.10])
    sim.set_hand_targets([None, above])
    assert sim.run(3.0)
    up_H = m.hand_rotation(1)[0].T @ np.array([0.0, 0.0, 1.0])
    below = above - np.array([0.0, 0.0, 0.10])
    sim.set_hand_targets([None, np.r_[below, up_H] if upright else below])
    assert sim.run(3.0)
    assert np.linalg.norm(m.hand_point(1)[0] - below) < 0.04
    return float(np.degrees(np.arccos(min(1.0, (m.hand_rotation(1)[0] @ up_H)[2]))))


def test_an_up_axis_keeps_a_held_object_upright_as_the_hand_moves():
    # The arm has 4 joints: lowering the hand 10 cm tilts it ~20 deg; the upright task trades
    # a little position for it.
    free, upright = _tilt_after_lowering(False), _tilt_after_lowering(True)
    assert free > 10.0 and upright < 1.5, (free, upright)
    with pytest.raises(ValueError, match="up axis is zero"):
        check_hand_targets([None, [0.3, -0.2, 0.8, 0.0, 0.0, 0.0]])
    t = check_hand_targets([None, [0.3, -0.2, 0.8, 0.0, 0.0, 2.0]])[1]
    np.testing.assert_allclose(t, [0.3, -0.2, 0.8, 0.0, 0.0, 1.0])


def test_fixed_footstep_planner_steps_on_its_footholds():
    """A footstep planner of the test's own (three fixed footholds): the soles land there."""
    gait = WalkingParams.load().gait
    soles = [np.array([0.0167, 0.11, 0.0, 0.0]), np.array([0.0167, -0.11, 0.0, 0.0])]
    steps = [soles[1] + [0.10, 0.0, 0.0, 0.0], soles[0] + [0.20, 0.0, 0.0, 0.0],
             soles[1] + [0.20, 0.0, 0.0, 0.0]]
    planner = FixedFootstepPlanner(steps, first_side=1, gait=gait)
    sim = WalkingSim(footsteps=planner)
    assert sim.run(5.0)
    m = sim.walker.core.model
    for side, target in ((1, steps[2]), (0, steps[1])):
        p = m.sole_pose(side).translation()
        assert np.hypot(*(p[:2] - target[:2])) < 0.02, (side, p, target)
    assert int(sim.status()[3]) == 0  # standing again


def test_valve_agent_turns_the_valve_beyond_45_degrees():
    from pr2_drake.agents.valve import ValveAgent
    from pr2_drake.episode import connect_by_name
    from pr2_drake.testbed import Testbed, TestbedConfig

    testbed = Testbed(TestbedConfig(task=2, seed=0))
    builder = DiagramBuilder()
    builder.AddSystem(testbed)
    connect_by_name(builder, testbed, builder.AddSystem(ValveAgent(priors=testbed.scene.priors)))
    simulator = Simulator(builder.Build())
    ctx = testbed.GetMyContextFromRoot(simulator.get_mutable_context())
    simulator.Initialize()
    t = 0.0
    while t < 30.0:
        t += 1.0
        simulator.AdvanceTo(t)
        status = testbed.GetOutputPort("episode").Eval(ctx)
        if status.done:
            break
    assert status.termination == "completed", status.termination
    assert status.score == 15
    assert status.memo["max_valve_angle_deg"] > 45.0


def test_force_on_a_held_hand_is_estimated_and_leaned_against():
    """A 30 N forward pull on the held left hand: the estimate finds it, the standing CoM leans
    back against it (quasi-static moment balance), but no further than over the heel points
    less ``gait.lean_margin``; no fall."""
    from pr2_drake.grasp import PickState

    sim = WalkingSim(arms="effort", pick_state_from_testbed=False)
    sim.walker.GetInputPort("pick_state").FixValue(
        sim.walker_context, PickState(True, "left_hand", "rope"))
    assert sim.run(1.0)
    core = sim.walker.core
    p_B, *_ = sim.base_pose()
    sim.set_hand_targets([p_B + np.array([0.26, 0.14, 0.16]), None])
    assert sim.run(1.0)
    com0 = core.model.com()[0].copy()
    sim.push(np.array([30.0, 0.0, 0.0]), body=sim.plant.GetBodyByName("l_arm_sphere"),
             p_BQ=np.zeros(3))
    assert sim.run(2.0)
    f = core.hand_force.f[0]
    assert abs(f[0] - 30.0) < 3.0 and np.all(np.abs(f[1:]) < 3.0), f
    m = core.model
    z_hand = m.hand_point(0)[0][2] - core.planner.plan.ground_z
    lean = -30.0 * z_hand / (m.mass * m.gravity)
    limit = float(np.max(m.p_SC[0])) - core.params.gait.lean_margin
    assert lean < -limit  # this force asks for more lean than the feet allow
    assert m.com()[0][0] - com0[0] == pytest.approx(-limit, abs=0.01)
    _, roll, pitch, _ = sim.base_pose()
    assert abs(pitch) < 0.1 and abs(roll) < 0.1


def test_support_polygon_geometry():
    """The hull and ray helpers of the hand-force limits on a 1 x 2 rectangle (and an inner
    point that the hull drops); a force direction with no horizontal part is refused."""
    from pr2_drake.bench.whole_body import convex_hull, ray_to_edge, support_limits

    hull = convex_hull(np.array([[0, 0], [1, 0], [1, 2], [0, 2], [0.5, 1]]))
    assert len(hull) == 4
    c = np.array([0.5, 1.0])
    assert ray_to_edge(hull, c, np.array([1.0, 0.0])) == pytest.approx(0.5)
    assert ray_to_edge(hull, c, np.array([0.0, -1.0])) == pytest.approx(1.0)
    assert ray_to_edge(hull, c, np.array([1.0, 1.0]) / np.sqrt(2)) == pytest.approx(np.sqrt(0.5))
    assert ray_to_edge(hull, np.array([2.0, 1.0]), np.array([1.0, 0.0])) == pytest.approx(-1.0)
    with pytest.raises(ValueError, match="direction_W"):
        support_limits(None, np.array([0.0, 0.0, 1.0]))  # vertical: no horizontal direction


def test_turned_stance_holds_a_held_pull_above_the_square_on_limit():
    """Line soles leave a square-on stance 0.13 m along the heading, so a pull built up at the
    hand can be leaned against only up to m g (0.13 m - lean_margin) / h (about 51 N). Turned
    45 degrees to the pull, the stance's diagonal is longer: a 58 N pull, above the square-on
    limit, is held and let go without a fall."""
    from pr2_drake.bench.whole_body import HAND_OFFSET_B, _sim, hand_force_row, support_limits

    sim = _sim(held=True)
    assert sim.run(1.0)
    p_B, *_ = sim.base_pose()
    sim.set_hand_targets([p_B + HAND_OFFSET_B, None])  # where the row holds the hand
    assert sim.run(1.5)
    square = support_limits(sim, np.array([1.0, 0.0, 0.0]))
    assert square["chord"] == pytest.approx(0.13, abs=0.01)
    assert square["built_up"] < 58.0
    row = hand_force_row(58.0, "forward", held=True, ramp=0.5, turn_deg=-45.0)
    assert not row["fell"], row
    assert row["limit"] > 58.0
    assert row["f_est"][0] == pytest.approx(58.0, abs=4.0)
    assert row["pitch"] < 5.0 and row["roll"] < 5.0


class _ThreeSteps(FootstepPlanner):
    """The test's own footstep planner: right, left, right onto fixed footholds, then stop."""

    adjustable = False  # land on the footholds (no capture-point adjustment)

    def __init__(self, steps, gait):
        self.steps = steps  # [(side, (x, y, z, yaw))]
        self.gait = gait

    def _index(self, sole, side):
        for k, (s, f) in enumerate(self.steps):
            if s == side and np.hypot(*(np.asarray(f[:2]) - sole[:2])) < 0.05:
                return k
        return -1

    def keep_walking(self, command, footholds):
        side, _ = self.steps[-1]
        return footholds[side] is None or self._index(footholds[side], side) < 0

    def first_swing_side(self, command, footholds):
        return self.steps[0][0]

    def next_steps(self, stance, stance_side, heading, command, n):
        k = self._index(stance, stance_side)
        out = [np.asarray(f, float) for _, f in self.steps[k + 1:k + 1 + n]]
        while len(out) < n:  # after the last: stay (the gait stops there)
            out.append(out[-1] if out else np.asarray(stance, float))
        return out


def test_own_footstep_planner_is_followed():
    gait = WalkingParams.load().gait
    x0 = 0.0167
    steps = [(1, (x0 + 0.08, -0.11, 0.0, 0.0)), (0, (x0 + 0.16, 0.11, 0.0, 0.0)),
             (1, (x0 + 0.16, -0.11, 0.0, 0.0))]
    sim = WalkingSim(footsteps=_ThreeSteps(steps, gait))
    assert sim.run(5.0)
    m = sim.walker.core.model
    for side, f in steps[1:]:
        p = m.sole_pose(side).translation()
        assert np.hypot(p[0] - f[0], p[1] - f[1]) < 0.02, (side, p, f)
    assert int(sim.status()[3]) == 0  # standing again


@pytest.mark.parametrize("bad", [0.0, -0.2, 1.5, float("nan")])
def test_hand_upright_max_error_out_of_range_names_the_parameter(bad):
    gains = WalkingParams().arms.hand_upright
    with pytest.raises(ValueError, match="arms.hand_upright_max_error"):
        HandUprightObjective(0, gains, bad)

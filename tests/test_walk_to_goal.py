"""The goal-seeking velocity planner of the walking reference agents."""

import math

import numpy as np
import pytest

from pr2_drake.agents.walk_to_goal import GoalPlannerParams, goal_velocity, yaw_from_quaternion

P = GoalPlannerParams()


def test_yaw_from_quaternion():
    for yaw in (-2.5, -0.3, 0.0, 1.0, 3.0):
        q = [math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)]
        assert yaw_from_quaternion(np.array(q)) == pytest.approx(yaw)


def test_walks_straight_at_a_goal_ahead():
    v = goal_velocity(np.zeros(3), 0.0, np.array([3.0, 0.0]), P)
    assert v[0] == pytest.approx(P.forward_speed)
    assert v[2] == pytest.approx(0.0)


def test_turns_on_the_spot_towards_a_goal_behind():
    v = goal_velocity(np.zeros(3), 0.0, np.array([-3.0, 0.5]), P)
    assert v[0] == 0.0 and v[1] == 0.0
    assert v[2] == pytest.approx(P.max_yaw_rate)  # goal to the left-behind: turn left


def test_steers_towards_the_goal_and_slows_near_it():
    v = goal_velocity(np.zeros(3), 0.0, np.array([2.0, -0.3]), P)
    assert v[0] > 0 and v[2] < 0
    near = goal_velocity(np.zeros(3), 0.0, np.array([0.25, 0.0]), P)
    assert 0 < near[0] < P.forward_speed
    assert np.all(goal_velocity(np.zeros(3), 0.0, np.array([0.05, 0.0]), P) == 0.0)


def test_heading_error_wraps_around():
    # Facing almost -x (yaw = pi - 0.1) with the goal at -x: small left turn, not a full circle.
    v = goal_velocity(np.zeros(3), math.pi - 0.1, np.array([-3.0, 0.0]), P)
    assert v[0] > 0
    assert 0 < v[2] < 0.2


def test_pursuit_point_runs_along_the_start_goal_line():
    from pr2_drake.agents.walk_to_goal import pursuit_point

    start, goal = np.array([0.0, 0.0]), np.array([6.0, 0.0])
    assert np.allclose(pursuit_point(np.array([1.0, 0.5]), start, goal, 1.0), [2.0, 0.0])
    assert np.allclose(pursuit_point(np.array([-1.0, 0.0]), start, goal, 0.5), [0.0, 0.0])
    assert np.allclose(pursuit_point(np.array([5.5, 0.2]), start, goal, 1.0), goal)


def test_a_base_that_drifted_off_the_line_turns_back_to_it():
    """0.5 m to the left of the line from the start to a goal 5 m ahead, facing along the line:
    pursuit (lookahead 1 m) turns right at once (towards the line, about 27 deg off); without
    it, the goal's bearing (6 deg) turns it far less."""
    params = GoalPlannerParams(lookahead=1.0)
    p, start, goal = np.array([1.0, 0.5]), np.array([0.0, 0.0]), np.array([6.0, 0.0])
    v_line = goal_velocity(p, 0.0, goal, params, start)
    v_goal = goal_velocity(p, 0.0, goal, params)  # no start latched yet: the goal's bearing
    assert v_line[2] == pytest.approx(-params.max_yaw_rate)
    assert -params.max_yaw_rate < v_goal[2] < 0.0
    assert abs(v_goal[2]) < 0.4 * abs(v_line[2])
    assert v_line[0] > 0.0  # still walking, not turning on the spot


def test_the_planner_latches_where_the_base_started():
    """With a lookahead, the planner keeps the first valid base position in its Context and
    steers along the line from there, wherever the base goes next."""
    from pydrake.systems.analysis import Simulator

    from pr2_drake.agents.walk_to_goal import GoalVelocityPlanner
    from pr2_drake.ports import BODY_STATE_SIZE

    planner = GoalVelocityPlanner([6.0, 0.0], GoalPlannerParams(lookahead=1.0))
    sim = Simulator(planner)
    ctx = sim.get_mutable_context()
    body = np.zeros(BODY_STATE_SIZE)
    body[3] = 1.0  # identity quaternion (w, x, y, z) after the position
    body[:3] = [0.0, -0.3, 0.8]
    port = planner.get_input_port(0)
    port.FixValue(ctx, body)
    sim.Initialize()
    body[:3] = [1.0, 0.5, 0.8]  # drifted left: the line from (0, -0.3) is now to its right
    port.FixValue(ctx, body)
    sim.AdvanceTo(0.2)
    assert np.allclose(ctx.get_discrete_state(0).get_value(), [1.0, 0.0, -0.3])
    cmd = planner.get_output_port(0).Eval(ctx)
    assert cmd[2] == pytest.approx(-0.4)

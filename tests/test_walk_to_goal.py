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

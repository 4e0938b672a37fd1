"""Jumping (pr2_drake.controllers.{centroidal_mpc,jump_planner,jumping}): the launch MPC's forces
and its ballistic take-off, a closed-loop vertical jump, and jump-command validation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pr2_drake.controllers.planning.centroidal_mpc import CentroidalMpc, leg_force_limits
from pr2_drake.controllers.jump_params import JumpParams
from pr2_drake.controllers.jumping import JumpController, check_jump_command
from pr2_drake.controllers.model import WholeBodyModel


def _launch_problem(apex: float):
    """The MPC at the start of a launch from a crouch (CoM 0.42 m over the soles, at rest)."""
    p = JumpParams.load()
    m = WholeBodyModel()
    mpc = CentroidalMpc(p.mpc, m.mass, m.gravity, 2 * m.n_points)
    g = m.gravity
    vz = math.sqrt(2 * g * apex)
    T = 2 * (p.takeoff_height - p.crouch_height) / vz
    c0 = np.array([0.0, 0.0, p.crouch_height])
    v_to = np.array([0.0, 0.0, vz])
    c_to = np.array([0.0, 0.0, p.takeoff_height])
    h, _ = mpc.knots(T)
    taus = np.cumsum(h)
    c_ref = np.array([c0 + 0.5 * v_to / T * min(s, T) ** 2 for s in taus])
    v_ref = np.array([v_to / T * min(s, T) for s in taus])
    # Heel and toe of each sole, 0.22 m apart, on the ground.
    pts = np.array([[-0.065, 0.11, 0.0], [0.065, 0.11, 0.0], [-0.065, -0.11, 0.0],
                    [0.065, -0.11, 0.0]])
    fz = np.full(4, 400.0)
    return mpc, p, m, (c0, np.zeros(3), np.zeros(3), T, c_ref, v_ref, c_to, v_to, pts, fz)


@pytest.mark.parametrize("apex", [0.05, 0.12])
def test_mpc_forces_respect_friction_and_limits_and_reach_the_ballistic_takeoff(apex):
    mpc, p, m, args = _launch_problem(apex)
    T = args[3]
    sol = mpc.solve(*args)
    assert sol.ok
    f = sol.forces  # (N, 4, 3)
    mu = p.mpc.mu
    assert np.all(f[..., 2] >= -1e-6)
    assert np.all(f[..., 2] <= 400.0 + 1e-6)
    assert np.all(np.abs(f[..., 0]) <= mu * f[..., 2] + 1e-6)
    assert np.all(np.abs(f[..., 1]) <= mu * f[..., 2] + 1e-6)
    h, K = mpc.knots(T)
    assert np.sum(h[:K]) == pytest.approx(T)
    # No force after take-off (the contact schedule's flight knots).
    assert np.all(np.abs(f[K:]) < 1e-6)
    # Ballistic check: the predicted take-off velocity gives the requested apex.
    v_to = sol.states[K, 3:6]
    assert v_to[2] ** 2 / (2 * m.gravity) == pytest.approx(apex, rel=0.05)
    assert np.linalg.norm(v_to[:2]) < 0.02
    assert sol.states[K, 2] == pytest.approx(p.takeoff_height, abs=0.01)
    # The prediction is the dynamics: after take-off the CoM falls freely.
    np.testing.assert_allclose(sol.states[-1, 5], v_to[2] - m.gravity * np.sum(h[K:]), atol=1e-6)


def test_leg_force_limit_follows_the_joint_torques():
    """tau = J^T f: the limit is the smallest margin * effort / |J_z| (halved per point)."""
    J = np.zeros((3, 6))
    J[2, [3, 4, 5]] = [0.2, 0.1, 0.05]
    f = leg_force_limits(J, np.array([3, 4, 5]), np.array([100.0, 100.0, 40.0]), 1.0, 1e4)
    assert f == pytest.approx(0.5 * min(100 / 0.2, 100 / 0.1, 40 / 0.05))


def test_jump_command_errors_name_the_port():
    p = JumpParams.load()
    with pytest.raises(ValueError, match="jump_command.*NaN"):
        check_jump_command([2.0, 0.0, 0.0, np.nan], p)
    with pytest.raises(ValueError, match="jump_command.*apex.*>= 0"):
        check_jump_command([2.0, 0.0, 0.0, -0.1], p)
    with pytest.raises(ValueError, match="jump_command.*4 values"):
        check_jump_command([2.0, 0.1], p)
    with pytest.raises(ValueError, match="jump_command.*max_apex"):
        check_jump_command([2.0, 0.0, 0.0, 5.0], p)
    assert check_jump_command(np.zeros(4), p) is None


@pytest.fixture(scope="module")
def vertical_jump():
    """A 0.10 m vertical jump in closed loop (testbed, 1 ms SAP), sampled every 5 ms."""
    from pr2_drake.bench.rigs import JumpSim

    sim = JumpSim()
    sim.advance(1.0)
    sim.set_jump((1.8, 0.0, 0.0, 0.10))
    log = []
    errors = []
    while sim.time < 3.6 - 1e-9:
        sim.advance(sim.time + 0.005)
        log.append((sim.time, int(sim.jump_status()[0]), sim.sole_heights().copy(),
                    sim.fallen()))
        if int(sim.jump_status()[0]) == 3 and not errors:
            # A new request while in flight: a ValueError naming the port.
            try:
                sim.walker.jump.request(sim.time, (3.0, 0.0, 0.0, 0.05))
            except ValueError as e:
                errors.append(str(e))
    return sim, log, errors


def test_vertical_jump_lifts_both_soles_and_lands_standing(vertical_jump):
    sim, log, _ = vertical_jump
    phases = [ph for _, ph, _, _ in log]
    assert {1, 2, 3, 4, 5} <= set(phases)  # crouch, launch, flight, landing, recovery
    both_up = max(h.min() for _, _, h, _ in log)
    assert both_up > 0.03  # both soles more than 3 cm off the ground at once
    assert not any(f for *_, f in log)
    assert phases[-1] == 0  # handed back to the walking planner: standing
    assert sim.walker.jump.jumps == 1
    # Standing again on both soles, upright at the walking height.
    assert np.all(log[-1][2] < 0.005)
    com, comd = sim.com()
    assert np.linalg.norm(comd) < 0.1
    assert com[2] == pytest.approx(sim.walker.params.gait.stand_com_height, abs=0.03)


def test_request_in_flight_is_a_value_error_naming_the_port(vertical_jump):
    _, _, errors = vertical_jump
    assert errors and "jump_command" in errors[0] and "already under way" in errors[0]


def test_in_process_command_validates_the_jump():
    jumper = JumpController()
    obs = {"agent": {"joint_state": {"legs_positions": np.zeros(10),
                                     "legs_velocities": np.zeros(10)},
                     "body_state": {"world_pos": [0, 0, 0.57], "world_orient": [1, 0, 0, 0],
                                    "linear_velocities": np.zeros(3),
                                    "angular_velocities": np.zeros(3)}}}
    with pytest.raises(ValueError, match="jump_command"):
        jumper.command(obs, jump=(1.0, 0.0, 0.0, float("nan")), t=0.0)
    with pytest.raises(ValueError, match="jump_command"):
        jumper.command(obs, jump=(1.0, 0.0, 0.0, -0.05), t=0.0)
    out = jumper.command(obs, jump=(1.0, 0.0, 0.0, 0.05), t=0.0)
    assert out["ctrl_mode"] == "effort" and out["joint_values"].shape == (10,)


def test_bar_takeoff_timing_centres_the_passage_in_the_clear_window():
    from pr2_drake.agents.moving_bar import MovingBarParams, takeoff_time

    p = MovingBarParams.load()
    soles = np.array([[0.0, 0.11], [0.0, -0.11]])
    bar = np.array([0.0, -0.8])
    timing = takeoff_time(2.0, soles, bar, np.array([0.0, 1.0]), 0.05, p)
    s_rel = 1.0 + p.lateral_speed
    w = 0.025 + p.sole_half_width + p.band_margin
    # Bar position relative to the soles along its motion at take-off, then after it.
    u_to = soles[:, 1] - (bar[1] + (timing.t_takeoff - 2.0))
    first_in = (u_to.min() - w) / s_rel
    last_out = (u_to.max() + w) / s_rel
    assert first_in - p.clear_from == pytest.approx(p.clear_until - last_out)
    assert timing.spare == pytest.approx((p.clear_until - p.clear_from) - (last_out - first_in))
    assert timing.spare > 0.0  # the measured window holds the passage, with time to spare
    np.testing.assert_allclose(timing.velocity_W, [0.0, -p.lateral_speed])  # against the bar


def test_moving_bar_agent_jumps_over_the_bar_without_touching_it():
    from pr2_drake.run import run_episode
    from pr2_drake.scenario import Scenario

    report = run_episode(Scenario(task=3, seed=0))
    assert report["score"] == 15.0 and report["termination"] == "completed"
    assert [e["item"] for e in report["items"]] == ["jump_over"]  # no bar contact


def test_forward_jump_travels_forward_and_lands_without_a_fall():
    from pr2_drake.bench.jumping import run_jump

    r = run_jump(0.08, 0.2, after=1.0)  # requested: 0.2 m forward, CoM apex 0.08 m
    assert r.landed and not r.fell
    assert r.airborne > 0.05 and r.sole_apex > 0.03  # a real flight phase
    assert r.distance > 0.1  # the soles landed more than 10 cm ahead

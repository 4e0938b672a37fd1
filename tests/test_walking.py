"""Tests of the built-in walking controller (pr2_drake.controllers.walking).

Behaviour only (no timing): the whole-body QP respects the torque limits and the floating-base
dynamics, the robot stands and walks in the testbed, and bad commands are rejected or clipped.
"""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.multibody.plant import MultibodyPlant

from pr2_drake.bench.rigs import WalkingSim
from pr2_drake.controllers.walking import WalkingController
from pr2_drake.observation import state_vectors
from pr2_drake.controllers.planning.gait import Phase
from pr2_drake.controllers.whole_body import COMMAND_PORT, WholeBodyController, check_command
from pr2_drake.controllers.walking_params import WalkingParams
from pr2_drake.ports import N_LEGS, P_WB, Q_ARMS, Q_LEGS, QUAT_WB, V_ARMS, V_LEGS, V_WB, W_WB
from pr2_drake.robot.model import add_kuavo, default_joint_positions, standing_base_pose
from pr2_drake.robot.params import load_robot_params


def _standing_state(core: WholeBodyController):
    """Plant (q, v) of the robot standing in its default pose on flat ground."""
    plant = MultibodyPlant(0.0)
    robot = add_kuavo(plant)
    plant.Finalize()
    joints = default_joint_positions()
    X_WB = standing_base_pose(plant, robot, joints)
    m = core.model
    q = m.q_nominal.copy()
    quat = X_WB.rotation().ToQuaternion()
    q[m.maps.q_base[:4]] = [quat.w(), quat.x(), quat.y(), quat.z()]
    q[m.maps.q_base[4:]] = X_WB.translation()
    q[m.maps.q_joints] = joints
    return q, np.zeros(m.nv)


def _check_qp_result(core: WholeBodyController, q, v, tau) -> bool:
    """Torques within the peak torque; if the QP solved, base rows of M vdot + h = J_c^T f
    hold and the forces are in the friction cone. Returns whether the QP solved."""
    effort = load_robot_params().effort_limits("legs")
    assert tau.shape == (N_LEGS,)
    assert np.all(np.isfinite(tau))
    assert np.all(np.abs(tau) <= effort + 1e-9)
    res = core.last_result
    if not res.ok:
        return False
    m = core.model
    m.update(q, v)
    M = m.mass_matrix()
    h = m.bias()
    Jc = np.vstack([m.contact_points(side)[0] for side in (0, 1)])
    gen = M @ res.vdot + h - Jc.T @ res.forces.reshape(-1)
    base = m.maps.v_base
    # No actuation on the floating base: its rows balance to solver tolerance.
    assert np.max(np.abs(gen[base])) < 0.5, gen[base]
    # The leg rows are the output torques (before clamping, which must not have been needed
    # by more than the solver tolerance).
    assert np.allclose(gen[m.v_legs], tau, atol=0.5)
    # Contact forces inside the friction pyramid and unilateral.
    f = res.forces
    mu = core.params.qp.mu
    assert np.all(f[:, 2] >= -1e-3)
    assert np.all(np.abs(f[:, :2]) <= (mu + 0.02) * f[:, 2:3] + 2.0)
    return True


@pytest.mark.parametrize("solver", ["daqp", "osqp"])
def test_qp_standing_respects_limits_and_dynamics(solver):
    params = WalkingParams.load()
    params.qp.solver = solver
    core = WholeBodyController(params)
    assert core.qp.use_daqp == (solver == "daqp")
    q, v = _standing_state(core)
    tau = core.update(0.0, q, v, [0.0, 0.0, 0.0])
    assert _check_qp_result(core, q, v, tau)
    # Standing torques carry the weight: knees and hips work against gravity.
    assert np.abs(tau).max() > 1.0


def test_qp_single_support_with_large_demands():
    """A frozen state far from the plan: demands saturate, constraints must still hold."""
    core = WholeBodyController()
    q, v = _standing_state(core)
    v = v.copy()
    v[core.model.maps.v_base[3:]] = [0.4, -0.3, 0.0]  # the base moving fast sideways
    phases = set()
    solved = 0
    t = 0.0
    n = 250
    for _ in range(n):
        tau = core.update(t, q, v, [0.3, 0.0, 0.0])
        phases.add(core.phase)
        solved += _check_qp_result(core, q, v, tau)
        t += core.params.control_period
    assert Phase.SINGLE in phases
    # Unsolved ticks fall back to the last torques (checked above to be within limits).
    assert solved >= 0.8 * n


def test_qp_failure_falls_back_without_exception():
    core = WholeBodyController()
    q, v = _standing_state(core)
    tau0 = core.update(0.0, q, v, [0.0, 0.0, 0.0]).copy()
    m = core.model
    bad_H = np.full((m.nv, m.nv), np.nan)
    res = core.qp.solve(m.mass_matrix(), m.bias(),
                        np.zeros((6 * m.n_points, m.nv)), bad_H, np.zeros(m.nv),
                        np.zeros(2 * m.n_points))
    assert not res.ok
    assert np.allclose(res.tau, tau0 * core.params.qp.fail_decay)


def test_infeasible_qp_falls_back_to_decayed_torques():
    """An infeasible tick (a hard row 0 = 1): DAQP finds no solution, nor does the OSQP
    fallback; the tick returns the last torques, decayed, without raising."""
    core = WholeBodyController()
    q, v = _standing_state(core)
    tau0 = core.update(0.0, q, v, [0.0, 0.0, 0.0]).copy()
    m = core.model
    n_kin = core.qp.n_kin
    a_kin = np.full(n_kin, np.nan)
    a_kin[0] = 1.0
    res = core.qp.solve(m.mass_matrix(), m.bias(), np.zeros((6 * m.n_points, m.nv)),
                        np.eye(m.nv), np.zeros(m.nv), np.full(2 * m.n_points, 100.0),
                        J_kin=np.zeros((n_kin, m.nv)), a_kin=a_kin)
    assert not res.ok
    assert np.allclose(res.tau, tau0 * core.params.qp.fail_decay)


def test_standing_five_seconds_keeps_base_within_2cm():
    sim = WalkingSim()
    p0, *_ = sim.base_pose()
    assert sim.run(5.0, check_every=0.5)
    p1, roll, pitch, _ = sim.base_pose()
    assert np.linalg.norm(p1 - p0) < 0.02
    assert abs(roll) < 0.05 and abs(pitch) < 0.05
    status = sim.status()
    assert status[0] == 1.0  # last QP solved


def test_walking_forward_three_seconds():
    sim = WalkingSim()
    sim.run(0.5)
    p0, *_ = sim.base_pose()
    sim.set_command(0.3, 0.0, 0.0)
    assert sim.run(3.0), "the robot fell"
    p1, _, _, yaw = sim.base_pose()
    assert p1[0] - p0[0] > 0.3
    assert abs(p1[1] - p0[1]) < 0.15
    assert abs(yaw) < 0.2


def test_bad_commands():
    with pytest.raises(ValueError, match=COMMAND_PORT):
        check_command([np.nan, 0.0, 0.0])
    with pytest.raises(ValueError, match=COMMAND_PORT):
        check_command([0.1, 0.2])
    # A port's value (a float array of 3) takes a fast path with the same checks.
    for bad in ([np.nan, 0.0, 0.0], [0.0, np.inf, 0.0], [0.0, 0.0, -np.inf]):
        with pytest.raises(ValueError, match=COMMAND_PORT):
            check_command(np.array(bad))
    good = np.array([0.1, -0.05, 0.2])
    np.testing.assert_array_equal(check_command(good), [0.1, -0.05, 0.2])
    core = WholeBodyController()
    lim = core.params.limits
    # Out-of-range commands are clipped to the limits of params/controllers/walking.yaml.
    np.testing.assert_allclose(core.clip_command([5.0, -3.0, 9.0]),
                               [lim.vx_max, -lim.vy_max, lim.yaw_rate_max])
    np.testing.assert_allclose(core.clip_command([-5.0, 3.0, -9.0]),
                               [lim.vx_min, lim.vy_max, -lim.yaw_rate_max])


def test_bad_command_on_the_diagram_port():
    sim = WalkingSim()
    sim.set_command(np.nan, 0.0, 0.0)
    with pytest.raises(Exception, match=COMMAND_PORT):
        sim.advance(0.01)


def _obs_from_sim(sim: WalkingSim) -> dict:
    js = sim.testbed.GetOutputPort("joint_state").Eval(sim.tb_context)
    bs = sim.testbed.GetOutputPort("body_state").Eval(sim.tb_context)
    return {"agent": {
        "joint_state": {"arms_positions": js[Q_ARMS], "legs_positions": js[Q_LEGS],
                        "arms_velocities": js[V_ARMS], "legs_velocities": js[V_LEGS]},
        "body_state": {"world_pos": bs[P_WB], "world_orient": bs[QUAT_WB],
                       "linear_velocities": bs[V_WB], "angular_velocities": bs[W_WB]},
    }}


def test_in_process_command_matches_the_action_format():
    sim = WalkingSim()
    obs = _obs_from_sim(sim)
    js, bs = state_vectors(obs)
    assert js.shape == (54,) and bs.shape == (13,)
    walker = WalkingController()
    legs = walker.command(obs, 0.0, 0.0, 0.0)
    assert legs["ctrl_mode"] == "effort"
    assert legs["stiffness"] is None and legs["dampings"] is None
    values = np.asarray(legs["joint_values"])
    assert values.shape == (N_LEGS,) and np.all(np.isfinite(values))
    # Same implementation as the diagram block: the standing torques agree.
    sim.advance(0.01)
    diagram_tau = sim.walker.GetOutputPort("legs_command").Eval(sim.walker_context).values
    assert np.allclose(diagram_tau, values, atol=5.0)
    with pytest.raises(ValueError, match=COMMAND_PORT):
        walker.command(obs, np.inf, 0.0, 0.0)
    with pytest.raises(ValueError, match="obs"):
        walker.command({"agent": {}}, 0.0, 0.0, 0.0)


def test_in_process_command_follows_the_observation_clock():
    """Called every 1 ms env step with obs["time"], the control law runs once per control
    period (torques held in between) and the gait clock is the simulation time."""
    sim = WalkingSim()
    obs = _obs_from_sim(sim)
    walker = WalkingController()
    period = walker.params.control_period
    updates = []
    core_update = walker.core.update

    def counting_update(t, *args, **kwargs):
        updates.append(t)
        return core_update(t, *args, **kwargs)

    walker.core.update = counting_update
    dt = 0.001
    n = 200
    actions = []
    for k in range(n):
        obs["time"] = k * dt
        actions.append(np.asarray(walker.command(obs, 0.3, 0.0, 0.0)["joint_values"]))
    steps_per_tick = round(period / dt)
    assert len(updates) == -(-n // steps_per_tick)  # one law update per control period
    np.testing.assert_allclose(updates, np.arange(0.0, n * dt - 1e-9, period), atol=1e-12)
    assert walker.core.t_last == pytest.approx((n - 1) // steps_per_tick * period)
    # Between updates the action is the held torque of the last update.
    for k in range(n):
        np.testing.assert_array_equal(actions[k], actions[k - k % steps_per_tick])
    # Without a time in the observation: the internal clock advances one period per call.
    walker.reset()
    updates.clear()
    del obs["time"]
    for _ in range(3):
        walker.command(obs, 0.0, 0.0, 0.0)
    np.testing.assert_allclose(updates, [0.0, period, 2 * period])

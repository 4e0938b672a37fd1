"""The plain environment: PR2 dictionaries, stepping, errors, determinism."""

import numpy as np
import pytest

from pr2_drake.agents.standing import StandingAgent
from pr2_drake.env import Env, EpisodeOver
from pr2_drake.observation import parse_action
from pr2_drake.testbed import DEFAULT_TIME_STEP


@pytest.fixture(scope="module")
def env():
    return Env(seed=0, control_dt=DEFAULT_TIME_STEP, time_limit=1.0)


def test_observation_has_the_original_keys(env):
    obs = env.reset()
    js = obs["agent"]["joint_state"]
    for group, n in (("arms", 8), ("legs", 10)):
        for kind in ("positions", "velocities", "applied_effort"):
            assert js[f"{group}_{kind}"].shape == (n,)
    bs = obs["agent"]["body_state"]
    assert bs["world_pos"].shape == (3,)
    assert np.linalg.norm(bs["world_orient"]) == pytest.approx(1.0)
    assert bs["linear_velocities"].shape == (3,) and bs["angular_velocities"].shape == (3,)
    assert obs["pick"] is False
    assert obs["time"] == 0.0
    np.testing.assert_allclose(obs["start_pos"], bs["world_pos"])
    assert "cam" not in obs  # camera off without a task that needs it


def test_standing_agent_stands_and_episode_ends_at_time_limit(env):
    agent = StandingAgent()
    obs = env.reset()
    z0 = obs["agent"]["body_state"]["world_pos"][2]
    done = False
    steps = 0
    while not done:
        done, success, obs = env.step(agent.next_action(obs))
        steps += 1
    assert steps == round(1.0 / DEFAULT_TIME_STEP)  # 1 s, one physics step each
    assert env.status.termination == "timeout" and not success
    assert abs(obs["agent"]["body_state"]["world_pos"][2] - z0) < 0.01
    with pytest.raises(EpisodeOver):
        env.step({})


def test_legs_without_torque_fall(env):
    obs = env.reset()
    done = False
    while not done:
        done, _, obs = env.step({"legs": {"ctrl_mode": "effort", "joint_values": np.zeros(10)}})
    # The joint hard stops catch the squat at ~0.29 m, below the 0.35 m fall height.
    assert obs["agent"]["body_state"]["world_pos"][2] < 0.35
    assert env.status.termination == "fell"


@pytest.mark.parametrize(
    "action, message",
    [
        ({"legz": {}}, r"action: unknown keys \['legz'\]"),
        ({"legs": {"ctrl_mode": "effort", "joint_values": np.zeros(3)}}, r"action\['legs'\]\['joint_values'\] must have 10"),
        ({"arms": {"ctrl_mode": "pos", "joint_values": np.zeros(8)}}, r"action\['arms'\]\['ctrl_mode'\]: unknown mode 'pos'"),
        ({"arms": {"ctrl_mode": "position", "joint_values": np.zeros(8), "dampings": -np.ones(8)}}, r"action\['arms'\]\['dampings'\] must be non-negative"),
        ({"legs": {"ctrl_mode": "effort", "joint_values": [np.inf] * 10}}, r"action\['legs'\]\['joint_values'\] contains NaN or inf"),
        ({"pick": "third_hand"}, r"action\['pick'\]"),
        ({"release": "yes"}, r"action\['release'\]: expected a bool"),
        ({"legs": {"joint_values": np.zeros(10), "gain": 1}}, r"unknown keys \['gain'\]"),
    ],
)
def test_bad_actions_name_the_fault(action, message):
    with pytest.raises(ValueError, match=message):
        parse_action(action)


def test_same_seed_and_actions_give_identical_observations():
    agent = StandingAgent()
    runs = []
    for _ in range(2):
        env = Env(seed=3, control_dt=0.005, time_limit=0.5)
        obs = env.reset()
        done = False
        while not done:
            done, _, obs = env.step(agent.next_action(obs))
        runs.append(obs)
    for key in ("legs_positions", "legs_velocities", "legs_applied_effort"):
        np.testing.assert_array_equal(runs[0]["agent"]["joint_state"][key],
                                      runs[1]["agent"]["joint_state"][key])
    np.testing.assert_array_equal(runs[0]["agent"]["body_state"]["world_pos"],
                                  runs[1]["agent"]["body_state"]["world_pos"])

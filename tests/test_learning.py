"""The learning suite: ids, spaces, rewards, resets, vector envs (pr2_drake.learning)."""

import subprocess
from dataclasses import replace
import sys

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")

import pr2_drake  # noqa: E402,F401  (registers the ids)
from pr2_drake.learning.ids import all_ids  # noqa: E402

NAMES = ("RockyRoad", "Valve", "MovingBar", "Slope", "StepsButton", "ObjectSearch")


def test_ids_exist_after_import_without_importing_gymnasium():
    code = ("import sys, pr2_drake; assert 'gymnasium' not in sys.modules; "
            "import gymnasium as gym; "
            "ids = sorted(k for k in gym.registry if k.startswith('pr2_drake/')); print(ids); "
            "print(gym.spec('pr2_drake/RockyRoadCommand-v0').max_episode_steps, "
            "gym.spec('pr2_drake/RockyRoad-v0').max_episode_steps)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.splitlines()
    expected = sorted(f"pr2_drake/{n}{s}-v0" for n in NAMES for s in ("", "Command"))
    assert eval(out[0]) == expected
    assert out[1].split() == ["500", "5000"]  # task 1's 50 s at 10 Hz and 100 Hz
    assert sorted(all_ids()) == expected


@pytest.mark.parametrize("name", NAMES)
def test_command_level_passes_check_env(name):
    from gymnasium.utils.env_checker import check_env

    env = gym.make(f"pr2_drake/{name}Command-v0", seconds=1.0)
    check_env(env.unwrapped, skip_render_check=True)
    names = env.unwrapped.action_names
    assert names[:3] == ("vx", "vy", "yaw_rate")
    assert ("jump_trigger" in names) == (name == "MovingBar")
    assert ("left_x" in names) == (name in ("Valve", "StepsButton", "ObjectSearch"))
    assert ("pick_left" in names) == (name in ("Valve", "ObjectSearch"))
    env.close()


@pytest.mark.parametrize("name", ["RockyRoad", "Valve"])
def test_joint_level_passes_check_env(name):
    from gymnasium.utils.env_checker import check_env

    env = gym.make(f"pr2_drake/{name}-v0", seconds=0.2)
    check_env(env.unwrapped, skip_render_check=True)
    assert env.action_space.shape == (10 + 8 + 3,)


def test_reward_is_dense_and_its_terms_sum_to_it():
    env = gym.make("pr2_drake/SlopeCommand-v0", seconds=3.0)
    env.reset(seed=1)
    env.action_space.seed(1)
    rewards = []
    for _ in range(20):
        _, reward, terminated, truncated, info = env.step(env.action_space.sample())
        assert reward == pytest.approx(sum(info["reward_terms"].values()), abs=1e-12)
        assert set(info["reward_terms"]) == {"progress", "rubric", "fall", "torque",
                                             "action_rate", "oscillation"}
        rewards.append(reward)
        if terminated or truncated:
            break
    assert np.mean(np.array(rewards) != 0.0) > 0.8
    sparse = gym.make("pr2_drake/SlopeCommand-v0", seconds=1.0, reward="rubric")
    sparse.reset(seed=1)
    _, reward, *_, info = sparse.step(np.zeros(3, np.float32))
    assert reward == 0.0 and info["reward_terms"] == {"rubric": 0.0}


def test_walking_forward_earns_progress_and_rubric_points():
    env = gym.make("pr2_drake/SlopeCommand-v0", seconds=6.0)
    obs, _ = env.reset(seed=2)
    total = {}
    while True:
        heading_error = np.arctan2(obs["target"][1], obs["target"][0])
        obs, reward, terminated, truncated, info = env.step(
            np.array([1.0, 0.0, np.clip(2.0 * heading_error, -1, 1)], np.float32))
        for k, v in info["reward_terms"].items():
            total[k] = total.get(k, 0.0) + v
        if terminated or truncated:
            break
    assert truncated and not terminated
    assert info["items"] == ["task_region"] and total["rubric"] == 5.0
    assert total["progress"] > 10.0 * 1.5  # more than 1.5 m nearer the goal


def test_reset_without_seed_starts_elsewhere_with_a_seed_repeats():
    env = gym.make("pr2_drake/RockyRoadCommand-v0")
    a, info_a = env.reset(seed=5)
    b, info_b = env.reset(seed=5)
    assert info_a["seed"] == info_b["seed"] == 5
    assert all(np.array_equal(a[k], b[k]) for k in a)
    c, info_c = env.reset()
    d, info_d = env.reset()
    assert len({5, info_c["seed"], info_d["seed"]}) == 3
    assert not np.array_equal(a["body"], c["body"]) and not np.array_equal(c["body"], d["body"])


def _rollout(env, seed, steps=15):
    obs, _ = env.reset(seed=seed)
    out = [np.concatenate([obs[k] for k in sorted(obs)])]
    rng = np.random.default_rng(seed)
    for _ in range(steps):
        obs, reward, *_ = env.step(rng.uniform(-1, 1, env.action_space.shape).astype(np.float32))
        out.append(np.concatenate([[reward]] + [obs[k] for k in sorted(obs)]))
    return out


@pytest.mark.parametrize("name", ["RockyRoadCommand", "MovingBarCommand"])
def test_reused_diagram_gives_the_fresh_builds_episode_bit_for_bit(name):
    reused = gym.make(f"pr2_drake/{name}-v0").unwrapped
    first = _rollout(reused, 11)  # the diagram built for seed 0, reset in place
    assert reused.episode.testbed.config.seed == 11
    again = _rollout(reused, 12), _rollout(reused, 11)
    fresh = gym.make(f"pr2_drake/{name}-v0", reuse=False).unwrapped
    rebuilt = _rollout(fresh, 11)
    assert fresh.episode is not None and fresh.episode.testbed.config.seed == 11
    for x, y, z in zip(first, again[1], rebuilt):
        assert np.array_equal(x, y) and np.array_equal(x, z)


def test_async_vector_env_runs_20_steps():
    envs = gym.vector.AsyncVectorEnv(
        [lambda: gym.make("pr2_drake/SlopeCommand-v0", seconds=1.5)] * 2)
    obs, info = envs.reset(seed=[3, 4])
    assert obs["body"].shape == (2, 13) and list(info["seed"]) == [3, 4]
    envs.action_space.seed(0)
    for _ in range(20):
        obs, reward, terminated, truncated, info = envs.step(envs.action_space.sample())
        assert reward.shape == (2,) and np.all(np.isfinite(reward))
    envs.close()


def test_camera_observation_and_render():
    env = gym.make("pr2_drake/SlopeCommand-v0", seconds=0.5, camera=True, camera_scale=0.25,
                   render_mode="rgb_array")
    obs, _ = env.reset(seed=0)
    assert obs["rgb"].shape == (120, 160, 3) and obs["rgb"].dtype == np.uint8
    assert obs["depth"].shape == (120, 160, 1) and obs["rgb"].std() > 5.0
    assert env.observation_space.contains(obs)
    picture = env.render()
    assert picture.shape == (240, 320, 3) and picture.std() > 5.0


def test_jump_trigger_makes_the_robot_jump():
    env = gym.make("pr2_drake/MovingBarCommand-v0", seconds=3.0)
    env.reset(seed=0)
    names = env.unwrapped.action_names
    action = np.zeros(len(names), np.float32)
    z = []
    for k in range(25):
        action[names.index("jump_trigger")] = 1.0 if k >= 3 else -1.0
        action[names.index("jump_apex")] = 0.0
        action[names.index("jump_delay")] = -1.0
        obs, *_ = env.step(action)
        z.append(obs["body"][2])
    controller = env.unwrapped.episode.blocks.controller
    assert controller.jump.jumps == 1  # one trigger edge, one jump
    assert max(z) - z[0] > 0.05  # the base rose in flight


def test_zero_leg_torques_fall_and_the_episode_terminates():
    env = gym.make("pr2_drake/Slope-v0", legs_mode="effort")
    env.reset(seed=0)
    for steps in range(1, 251):
        _, reward, terminated, truncated, info = env.step(np.zeros(21, np.float32))
        if terminated or truncated:
            break
    assert terminated and not truncated and info["termination"] == "fell"
    assert info["reward_terms"]["fall"] < 0.0 and steps < 250


def test_joint_level_zero_action_holds_the_standing_pose():
    env = gym.make("pr2_drake/Slope-v0", seconds=1.0)
    obs, _ = env.reset(seed=0)
    for _ in range(100):
        obs, _, terminated, truncated, info = env.step(np.zeros(21, np.float32))
    assert truncated and not terminated and info["termination"] == "timeout"


def test_a_step_must_be_a_whole_number_of_physics_steps():
    """The joint level's 100 Hz runs on a 2 ms plant (10 ms is not a whole number of the tasks'
    4 ms steps); a control_dt that is not a whole number of steps is refused by name."""
    from pr2_drake.learning.envs import CommandEnv, JointEnv
    from pr2_drake.scenario import Scenario, ScenarioError

    env = JointEnv(1)
    assert env.episode.testbed.config.time_step == 0.002
    env.close()
    with pytest.raises(ScenarioError, match=r"control_dt \(0\.01 s\) must be a whole number of "
                                            r"physics steps \(0\.004 s\)"):
        CommandEnv(1, control_dt=0.01)
    with pytest.raises(ScenarioError, match="whole number of physics steps"):
        JointEnv(1, scenario=Scenario(plant=replace(Scenario().plant, time_step=0.004)))

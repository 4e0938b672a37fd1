"""The gymnasium wrapper conforms to the gymnasium API and reports falls as terminations."""

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")

from pr2_drake.gym_env import Pr2GymEnv  # noqa: E402


def test_passes_gymnasium_env_checker():
    from gymnasium.utils.env_checker import check_env

    env = Pr2GymEnv(control_dt=0.02, time_limit=0.5)
    check_env(env, skip_render_check=True)


def test_zero_torque_episode_terminates_by_falling():
    env = Pr2GymEnv(control_dt=0.02, time_limit=5.0)
    obs, _ = env.reset(seed=0)
    assert obs.shape == env.observation_space.shape
    terminated = truncated = False
    steps = 0
    while not (terminated or truncated):
        obs, reward, terminated, truncated, info = env.step(np.zeros(10, np.float32))
        steps += 1
    assert terminated and not truncated
    assert info["termination"] == "fell"
    assert steps < 250

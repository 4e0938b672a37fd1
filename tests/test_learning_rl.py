"""Learning with the optional extras: a short SB3 PPO run ([rl]) and Ray rollouts ([ray])."""

from pathlib import Path

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")

import pr2_drake  # noqa: E402,F401  (registers the ids)
from pr2_drake.learning.wrappers import PolicyView  # noqa: E402

SHIPPED = Path(__file__).resolve().parents[1] / "examples" / "learning" / "slope_policy.npz"


def test_short_ppo_run_trains_exports_and_runs_as_an_agent(tmp_path):
    pytest.importorskip("stable_baselines3", reason="stable-baselines3 is the [rl] extra")
    from stable_baselines3 import PPO

    from pr2_drake.learning.policy import load_policy, save_policy
    from pr2_drake.run import run_episode
    from pr2_drake.scenario import Scenario

    env = PolicyView(gym.make("pr2_drake/SlopeCommand-v0", seconds=3.0), ("body", "target"),
                     ("vx", "yaw_rate"))
    model = PPO("MlpPolicy", env, n_steps=64, batch_size=32, n_epochs=2, seed=0, device="cpu",
                policy_kwargs={"net_arch": [16, 16]})
    model.learn(total_timesteps=128)
    assert model.num_timesteps == 128
    linears = [m for m in model.policy.mlp_extractor.policy_net if hasattr(m, "weight")]
    linears.append(model.policy.action_net)
    path = tmp_path / "policy.npz"
    save_policy(path, [(m.weight.detach().numpy(), m.bias.detach().numpy()) for m in linears],
                env.keys, "slope", env.action_index, env.action_names, 0.1)
    policy = load_policy(path)
    x = np.random.default_rng(0).normal(size=(4, 16)).astype(np.float32)
    expected, _ = model.predict(x, deterministic=True)
    got = np.array([policy["mlp"].act(row) for row in x])
    np.testing.assert_allclose(got, expected, atol=1e-5)
    report = run_episode(Scenario(task="slope", seed=1000, seconds=0.5,
                                  agent="pr2_drake.learning.policy:PolicyAgent",
                                  agent_params={"policy": str(path)}))
    assert report["termination"] == "timeout" and report["sim_time"] == 0.5


def test_shipped_policy_walks_onto_the_slope():
    from pr2_drake.run import run_episode
    from pr2_drake.scenario import Scenario

    report = run_episode(Scenario(task="slope", seed=1001, seconds=8.0,
                                  agent="pr2_drake.learning.policy:PolicyAgent",
                                  agent_params={"policy": str(SHIPPED)}))
    assert [e["item"] for e in report["items"]][:1] == ["task_region"]


def test_ray_rollouts_match_the_local_ones():
    pytest.importorskip("ray", reason="Ray is the optional [ray] extra")
    from pr2_drake.learning.rollouts import collect_rollouts, rollout

    kwargs = {"seconds": 0.3}
    episodes = collect_rollouts("pr2_drake/SlopeCommand-v0", [5, 6], env_kwargs=kwargs,
                                workers=2)
    local = gym.make("pr2_drake/SlopeCommand-v0", **kwargs).unwrapped
    for e in episodes:
        mine = rollout(local, e["seed"])
        assert e["truncated"] and len(e["actions"]) == 3
        for key in ("observations", "actions", "rewards"):
            assert np.array_equal(e[key], mine[key])

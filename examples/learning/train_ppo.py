"""Train a PPO policy (stable-baselines3) on the slope at the command level, then evaluate it.

    pip install -e '.[rl]'
    nice -n 10 python examples/learning/train_ppo.py --minutes 55 --envs 2
    python examples/learning/train_ppo.py --evaluate-only        # the shipped policy
    pr2-drake run --task slope --seed 1000 --agent pr2_drake.learning.policy:PolicyAgent \\
        --set agent_params.policy=examples/learning/slope_policy.npz

The policy sees the base state relative to the goal and the goal in the heading frame (keys
``body`` and ``target``, 16 numbers) and commands the walking controller's forward speed and
yaw rate (``vx``, ``yaw_rate``) at 10 Hz: the SlopeAgent's controller (footholds on the
incline) executes them. Reward: the dense reward (progress to the goal, rubric points, fall,
small costs). Training episodes end after ``--seconds`` (25 s); evaluation runs the task's
full 120 s on unseen seeds through ``run_episode`` (the same path as ``pr2-drake run``), for
the trained policy, a random policy over the same two commands, and the reference agent.

Writes (beside this file unless ``--out``): ``slope_policy.npz`` (the policy, numpy only),
``learning_curve.csv`` and ``learning_curve.png`` (score and return per training episode
against environment steps and wall time), ``evaluation.json``.
"""

from __future__ import annotations

import argparse
import csv
import json
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

import pr2_drake  # noqa: F401  (registers the gymnasium ids)
from pr2_drake.learning.wrappers import PolicyView

ENV_ID = "pr2_drake/SlopeCommand-v0"
KEYS = ("body", "target")
ACTIONS = ("vx", "yaw_rate")
HERE = Path(__file__).resolve().parent


def make_env(seconds: float = 25.0) -> gym.Env:
    """The training env: the slope's command level through the policy's view."""
    return PolicyView(gym.make(ENV_ID, seconds=seconds), KEYS, ACTIONS)


def train(args) -> None:
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import SubprocVecEnv

    vec = make_vec_env(make_env, n_envs=args.envs, seed=args.seed,
                       env_kwargs={"seconds": args.seconds},
                       vec_env_cls=SubprocVecEnv if args.envs > 1 else None)
    model = PPO("MlpPolicy", vec, n_steps=args.n_steps, batch_size=64, n_epochs=10,
                learning_rate=3e-4, gamma=0.98, gae_lambda=0.95, ent_coef=0.0,
                policy_kwargs={"net_arch": [64, 64], "log_std_init": -0.5},
                seed=args.seed, verbose=0, device="cpu")
    rows: list[dict] = []
    start = time.perf_counter()
    budget = 60.0 * args.minutes

    class Log(BaseCallback):
        """Records each finished episode; stops at the wall-clock budget."""

        returns = [0.0] * args.envs

        def _on_step(self) -> bool:
            for i, (r, done, info) in enumerate(zip(self.locals["rewards"], self.locals["dones"],
                                                   self.locals["infos"])):
                self.returns[i] += float(r)
                if done:
                    rows.append({"steps": self.num_timesteps,
                                 "wall_s": round(time.perf_counter() - start, 1),
                                 "return": round(self.returns[i], 3), "score": info["score"],
                                 "termination": info["termination"], "seed": info["seed"]})
                    self.returns[i] = 0.0
                    print(rows[-1], flush=True)
            return time.perf_counter() - start < budget

    model.learn(total_timesteps=args.steps, callback=Log())
    wall = time.perf_counter() - start
    vec.close()
    out = Path(args.out)
    export(model, out / "slope_policy.npz")
    model.save(out / "slope_ppo.zip")
    write_curve(rows, out, wall)


def export(model, path: Path) -> None:
    """The SB3 policy's mean action network as a policy file (numpy only)."""
    from pr2_drake.learning.policy import save_policy

    env = make_env()
    linears = [m for m in model.policy.mlp_extractor.policy_net if hasattr(m, "weight")]
    linears.append(model.policy.action_net)
    layers = [(m.weight.detach().numpy(), m.bias.detach().numpy()) for m in linears]
    save_policy(path, layers, env.keys, "slope", env.action_index, env.action_names,
                env.unwrapped.control_dt)
    env.close()


def write_curve(rows: list[dict], out: Path, wall: float) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if not rows:
        print("no training episode finished: no learning curve")
        return
    with open(out / "learning_curve.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    steps = np.array([r["steps"] for r in rows])
    k = min(10, len(rows))
    smooth = lambda x: np.convolve(x, np.ones(k) / k, mode="valid")  # noqa: E731
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    for ax, key, label in ((axes[0], "score", "rubric points (of 10)"),
                           (axes[1], "return", "dense return")):
        y = np.array([r[key] for r in rows], float)
        ax.plot(steps, y, ".", alpha=0.35, label="episode")
        ax.plot(steps[k - 1:], smooth(y), "-", label=f"mean of {k}")
        ax.set_xlabel("environment steps (10 Hz)")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend()
    fig.suptitle(f"PPO on {ENV_ID} ({len(rows)} episodes, {wall / 60:.0f} min wall clock)")
    fig.tight_layout()
    fig.savefig(out / "learning_curve.png", dpi=110)


def evaluate(args) -> dict:
    """Trained policy, random policy and reference agent on unseen seeds (full time limit)."""
    from pr2_drake.run import run_episode
    from pr2_drake.scenario import Scenario

    lo, hi = (int(x) for x in args.eval_seeds.split(":"))
    seeds = list(range(lo, hi))
    policy_file = str(Path(args.out) / "slope_policy.npz")
    results: dict[str, list] = {"trained": [], "random": [], "reference": []}
    for seed in seeds:
        trained = run_episode(Scenario(task="slope", seed=seed,
                                       agent="pr2_drake.learning.policy:PolicyAgent",
                                       agent_params={"policy": policy_file}))
        reference = run_episode(Scenario(task="slope", seed=seed))
        results["trained"].append(_row(trained))
        results["reference"].append(_row(reference))
        results["random"].append(_random_episode(seed))
        print(seed, {k: v[-1] for k, v in results.items()}, flush=True)
    summary = {k: {"mean_score": float(np.mean([r["score"] for r in v])),
                   "episodes": v} for k, v in results.items()}
    summary["seeds"] = seeds
    Path(args.out, "evaluation.json").write_text(json.dumps(summary, indent=1))
    print({k: summary[k]["mean_score"] for k in results})
    return summary


def _row(report: dict) -> dict:
    return {"seed": report["seed"], "score": report["score"], "termination":
            report["termination"], "sim_time": report["sim_time"]}


def _random_episode(seed: int) -> dict:
    """Uniform random (vx, yaw_rate) at 10 Hz for the task's whole time limit."""
    env = PolicyView(gym.make(ENV_ID), KEYS, ACTIONS)
    env.action_space.seed(seed)
    env.reset(seed=seed)
    while True:
        _, _, terminated, truncated, info = env.step(env.action_space.sample())
        if terminated or truncated:
            env.close()
            return {"seed": seed, "score": info["score"], "termination": info["termination"],
                    "sim_time": round(info["time"], 3)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--minutes", type=float, default=55.0, help="wall-clock budget")
    parser.add_argument("--steps", type=int, default=200_000, help="at most this many steps")
    parser.add_argument("--envs", type=int, default=2, help="env processes")
    parser.add_argument("--n-steps", type=int, default=256, help="PPO rollout per env")
    parser.add_argument("--seconds", type=float, default=25.0, help="training episode length")
    parser.add_argument("--seed", type=int, default=0, help="training seeds start here")
    parser.add_argument("--eval-seeds", default="1000:1005", help="unseen seeds, lo:hi")
    parser.add_argument("--evaluate-only", action="store_true")
    parser.add_argument("--out", default=str(HERE))
    args = parser.parse_args()
    if not args.evaluate_only:
        train(args)
    evaluate(args)


if __name__ == "__main__":
    main()

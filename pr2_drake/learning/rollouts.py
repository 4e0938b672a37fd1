"""Rollouts on Ray: episodes of any learning env collected by workers across machines.

    from pr2_drake.learning.rollouts import FilePolicy, collect_rollouts
    episodes = collect_rollouts("pr2_drake/SlopeCommand-v0", seeds=range(100, 164),
                                policy=FilePolicy("examples/learning/slope_policy.npz"),
                                workers=8, address="auto")

Ray is the optional ``[ray]`` extra (``pip install 'pr2-drake[ray]'``), as for ``pr2-drake
compete --backend ray``. ``address`` None starts a local Ray with ``workers`` CPUs; ``"auto"``
or ``"ray://head:10001"`` joins a running cluster (every node needs pr2-drake installed, and
the policy file at the same path). Each worker is a Ray actor that builds its env once and
runs its share of the seeds, resetting in place (:mod:`pr2_drake.learning.envs`); an episode
is the same, bit for bit, wherever it runs (:func:`rollout` is what each worker calls).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Callable, Iterable

import numpy as np


class FilePolicy:
    """A policy file (:mod:`pr2_drake.learning.policy`) as ``policy(obs) -> action`` on the
    env's Dict observation; picklable (it holds the path, and loads on first use)."""

    def __init__(self, path: str | Path):
        self.path = str(path)
        self._policy = None

    def __getstate__(self):
        return {"path": self.path, "_policy": None}

    def __call__(self, obs: dict[str, np.ndarray], action_size: int) -> np.ndarray:
        from pr2_drake.learning.policy import load_policy

        if self._policy is None:
            self._policy = load_policy(self.path)
        p = self._policy
        action = np.zeros(action_size, np.float32)
        action[p["action_index"]] = p["mlp"].act(
            np.concatenate([obs[k].reshape(-1) for k in p["keys"]]))
        return action


def rollout(env, seed: int, policy: Callable | None = None,
            max_steps: int | None = None) -> dict[str, Any]:
    """One episode of ``env`` from ``reset(seed=seed)``: ``policy(obs, action_size)`` (None:
    uniform random actions seeded by ``seed``). Returns the flat observations (the vector
    keys in order, :class:`pr2_drake.learning.observe.Observer`), actions, rewards, and
    ``seed``, ``score``, ``termination``, ``terminated``, ``truncated``."""
    obs, _ = env.reset(seed=seed)
    size = env.action_space.shape[0]
    rng = np.random.default_rng(seed)
    keys = [k for k in obs if k not in ("rgb", "depth")]
    flat = lambda o: np.concatenate([o[k].reshape(-1) for k in keys])  # noqa: E731
    observations, actions, rewards = [flat(obs)], [], []
    terminated = truncated = False
    info: dict[str, Any] = {"score": 0.0, "termination": ""}
    while not (terminated or truncated) and (max_steps is None or len(actions) < max_steps):
        action = (rng.uniform(-1.0, 1.0, size).astype(np.float32) if policy is None
                  else np.asarray(policy(obs, size), np.float32))
        obs, reward, terminated, truncated, info = env.step(action)
        observations.append(flat(obs))
        actions.append(action)
        rewards.append(reward)
    return {"seed": int(seed), "observations": np.array(observations, np.float32),
            "actions": np.array(actions, np.float32).reshape(-1, size),
            "rewards": np.array(rewards), "score": float(info["score"]),
            "termination": info["termination"], "terminated": bool(terminated),
            "truncated": bool(truncated)}


class RolloutWorker:
    """One env, built once (made a Ray actor by :func:`collect_rollouts`)."""

    def __init__(self, env_id: str, env_kwargs: dict[str, Any]):
        import gymnasium as gym

        import pr2_drake  # noqa: F401  (registers the ids in the worker)

        self.env = gym.make(env_id, **env_kwargs).unwrapped

    def run(self, seeds: list[int], policy, max_steps: int | None) -> list[dict[str, Any]]:
        return [rollout(self.env, s, policy, max_steps) for s in seeds]


def collect_rollouts(env_id: str, seeds: Iterable[int], policy: Callable | None = None, *,
                     env_kwargs: dict[str, Any] | None = None, workers: int = 2,
                     address: str | None = None, max_steps: int | None = None
                     ) -> list[dict[str, Any]]:
    """Episodes of ``env_id`` for ``seeds`` (in that order) on ``workers`` Ray actors (see
    the module docstring; :func:`rollout` for an episode's contents).

    Raises:
        ImportError: Ray is not installed (naming the extra).
    """
    try:
        import ray
    except ImportError:
        raise ImportError("collect_rollouts needs Ray: pip install 'pr2-drake[ray]'") from None
    seeds = [int(s) for s in seeds]
    if not ray.is_initialized():
        if address is None:
            ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False)
        else:
            ray.init(address=address, log_to_driver=False)
    actor = ray.remote(num_cpus=1)(RolloutWorker)
    pool = [actor.remote(env_id, dict(env_kwargs or {})) for _ in range(max(1, workers))]
    shares = [seeds[k::len(pool)] for k in range(len(pool))]
    results = ray.get([w.run.remote(share, policy, max_steps) for w, share in zip(pool, shares)])
    for w in pool:
        ray.kill(w)
    by_seed = {}
    for share, episodes in zip(shares, results):
        for s, e in zip(share, episodes):
            by_seed.setdefault(s, []).append(e)
    return [by_seed[s].pop(0) for s in seeds]

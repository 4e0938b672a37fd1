"""PolicyView: the part of a learning env a policy sees and drives (a gymnasium wrapper).

``PolicyView(env, keys=("body", "target"), actions=("vx", "yaw_rate"))`` flattens the chosen
observation keys (in :class:`pr2_drake.learning.observe.Observer` order) into one float32
vector and takes an action of the chosen entries of the env's action (by name,
``env.unwrapped.action_names``), the others 0. A policy trained through it is saved with the
same keys and entries (:func:`pr2_drake.learning.policy.save_policy`), so
:class:`pr2_drake.learning.policy.PolicyAgent` feeds it exactly what it was trained on.
"""

from __future__ import annotations

from typing import Sequence

import gymnasium as gym
import numpy as np
from gymnasium import spaces


class PolicyView(gym.Wrapper):
    """See the module docstring. ``keys`` None: every vector key; ``actions`` None: all."""

    def __init__(self, env: gym.Env, keys: Sequence[str] | None = None,
                 actions: Sequence[str] | None = None):
        super().__init__(env)
        obs_space = env.observation_space
        vector_keys = [k for k in obs_space.spaces if k not in ("rgb", "depth")]
        self.keys = tuple(k for k in vector_keys if keys is None or k in keys)
        unknown = set(keys or ()) - set(vector_keys)
        if unknown:
            raise ValueError(f"PolicyView: no observation keys {sorted(unknown)}; the env has "
                             f"{vector_keys}")
        names = tuple(env.unwrapped.action_names)
        unknown = set(actions or ()) - set(names)
        if unknown:
            raise ValueError(f"PolicyView: no actions {sorted(unknown)}; the env has {names}")
        self.action_index = np.array([i for i, n in enumerate(names)
                                      if actions is None or n in actions], dtype=int)
        self.action_names = names
        n_obs = sum(int(np.prod(obs_space[k].shape)) for k in self.keys)
        self.observation_space = spaces.Box(-np.inf, np.inf, (n_obs,), np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, (len(self.action_index),), np.float32)

    def _flat(self, obs) -> np.ndarray:
        return np.concatenate([np.asarray(obs[k], np.float32).reshape(-1) for k in self.keys])

    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        return self._flat(obs), info

    def step(self, action):
        full = np.zeros(len(self.action_names), np.float32)
        full[self.action_index] = np.asarray(action, np.float32).reshape(-1)
        obs, reward, terminated, truncated, info = self.env.step(full)
        return self._flat(obs), reward, terminated, truncated, info

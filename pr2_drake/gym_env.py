"""A gymnasium-conformant wrapper of :class:`pr2_drake.env.Env` for learning.

Needs the optional ``gymnasium`` package (``pip install -e '.[rl]'``).

- Observation: a float32 vector [joint_state (54) | body_state (13)] in the testbed's layouts
  (:mod:`pr2_drake.ports`).
- Action: leg torques normalised to [-1, 1] (scaled by each joint's peak torque, effort mode);
  the arms hold the nominal pose in position mode.
- Reward: the change of the task score, plus an optional ``alive_bonus`` per step.
- ``terminated`` when the referee ends the episode for any reason but the time limit;
  ``truncated`` at the time limit.
"""

from __future__ import annotations

from typing import Any

import numpy as np

try:
    import gymnasium as gym
    from gymnasium import spaces
except ImportError as e:  # pragma: no cover - exercised only without the extra
    raise ImportError("pr2_drake.gym_env needs gymnasium: pip install -e '.[rl]'") from e

from pr2_drake.env import Env
from pr2_drake.observation import state_vectors
from pr2_drake.ports import BODY_STATE_SIZE, JOINT_STATE_SIZE, N_LEGS
from pr2_drake.robot.params import load_robot_params


class Pr2GymEnv(gym.Env):
    """The testbed as a gymnasium environment.

    Args:
        task: task id or name (None: flat ground with ``time_limit``).
        control_dt: simulated seconds per step [s].
        time_limit: episode length without a task [s].
        alive_bonus: reward added per step while the episode runs.
    """

    metadata = {"render_modes": ["rgb_array"]}

    def __init__(self, task: int | str | None = None, control_dt: float = 0.01,
                 time_limit: float = 10.0, alive_bonus: float = 0.0,
                 render_mode: str | None = None):
        super().__init__()
        self._env = Env(task=task, seed=0, control_dt=control_dt, time_limit=time_limit)
        self._limits = load_robot_params().effort_limits("legs")
        self._arms = load_robot_params().default_positions("arms")
        self.alive_bonus = float(alive_bonus)
        self.render_mode = render_mode
        n = JOINT_STATE_SIZE + BODY_STATE_SIZE
        self.observation_space = spaces.Box(-np.inf, np.inf, shape=(n,), dtype=np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(N_LEGS,), dtype=np.float32)
        self._obs: dict[str, Any] | None = None
        self._score = 0.0

    def _vector(self, obs: dict[str, Any]) -> np.ndarray:
        joint_state, body_state = state_vectors(obs, check_finite=False)
        return np.concatenate([joint_state, body_state]).astype(np.float32)

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        self._obs = self._env.reset(seed=seed)
        self._score = self._env.status.score
        return self._vector(self._obs), {"time": self._obs["time"]}

    def step(self, action):
        a = np.clip(np.asarray(action, dtype=float).reshape(N_LEGS), -1.0, 1.0)
        done, success, self._obs = self._env.step({
            "legs": {"ctrl_mode": "effort", "joint_values": a * self._limits},
            "arms": {"ctrl_mode": "position", "joint_values": self._arms},
        })
        status = self._env.status
        reward = status.score - self._score + (0.0 if done else self.alive_bonus)
        self._score = status.score
        truncated = done and status.termination == "timeout"
        terminated = done and not truncated
        info = {"time": self._obs["time"], "success": success, "termination": status.termination}
        return self._vector(self._obs), float(reward), terminated, truncated, info

    def render(self):
        if self._obs is None or "cam" not in self._obs:
            return None
        return self._obs["cam"]["rgb"]

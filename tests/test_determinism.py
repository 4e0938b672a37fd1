"""The same task, seed and agent give the same trajectory and report, bit for bit."""

import numpy as np
import pytest

from pr2_drake.agents.standing import StandingAgent
from pr2_drake.env import Env


class ScriptedAgent(StandingAgent):
    """Stands, waves the right arm on a fixed schedule and asks to pick at t = 0.3 s."""

    def next_action(self, obs):
        action = super().next_action(obs)
        arms = action["arms"]["joint_values"].copy()
        arms[4] = 0.8 * np.sin(4.0 * obs["time"])
        action["arms"]["joint_values"] = arms
        action["pick"] = "right_hand" if abs(obs["time"] - 0.3) < 0.006 else None
        return action


def _episode(task: int, seed: int):
    env = Env(task=task, seed=seed, control_dt=0.005)
    agent = ScriptedAgent()
    obs = env.reset()
    for _ in range(120):  # 0.6 s
        done, _, obs = env.step(agent.next_action(obs))
        if done:
            break
    report = env.report()
    state = env.testbed.GetOutputPort("plant_state").Eval(env.episode.tb_context).copy()
    return report, state, obs


@pytest.mark.parametrize("task", [2, 3])
def test_same_seed_same_result(task):
    r1, x1, o1 = _episode(task, seed=11)
    r2, x2, o2 = _episode(task, seed=11)
    assert r1 == r2
    np.testing.assert_array_equal(x1, x2)
    np.testing.assert_array_equal(o1["agent"]["joint_state"]["arms_positions"],
                                  o2["agent"]["joint_state"]["arms_positions"])


def test_different_seeds_differ():
    _, x1, _ = _episode(2, seed=1)
    _, x2, _ = _episode(2, seed=2)
    assert not np.array_equal(x1, x2)

"""Agents for tests/test_controller_server.py: they check the original platform's observation
keys (run in the competition sandbox, so a missing key ends the episode ``agent_error``)."""

import numpy as np

from pr2_drake.testbed import DEFAULT_TIME_STEP  # the tasks' physics step (task 3's here)


class OriginalKeysAgent:
    """Raises unless the observation carries the original's keys with consistent values."""

    control_dt = 0.01

    def next_action(self, obs):
        agent = obs["agent"]
        step = obs["current_sim_step"]
        if step != round(obs["time"] / DEFAULT_TIME_STEP):
            raise AssertionError(f"current_sim_step {step} at time {obs['time']}")
        if not np.allclose(agent["start_pos"], obs["start_pos"]) or \
                not np.allclose(agent["start_orient"], obs["start_orient"]):
            raise AssertionError("agent start pose differs from the top-level one")
        if agent["stiffness"].shape != (18,) or agent["dampings"].shape != (18,):
            raise AssertionError(f"gains shapes {agent['stiffness'].shape}")
        if not np.allclose(obs["obstacle"]["position"], obs["bar_position"]):
            raise AssertionError("obstacle position is not the bar's")
        if obs["obstacle"]["orientation"].shape != (4,):
            raise AssertionError("obstacle orientation is not a quaternion")
        q = agent["joint_state"]["legs_positions"]
        return {"legs": {"ctrl_mode": "position", "joint_values": q, "stiffness": [],
                         "dampings": []}}


class InProcessWalker:
    """An original-style solver that gets its torques from
    :class:`pr2_drake.porting.clients.InProcessClient` (no socket: the sandbox
    refuses them)."""

    def __init__(self):
        from pr2_drake.porting.clients import InProcessClient

        self.client = InProcessClient()

    def next_action(self, obs):
        reply = self.client.get_cmd(obs, 0.2, 0.0, 0.0, -1)
        return {"legs": {"ctrl_mode": reply["mode"], "joint_values": reply["effort"],
                         "stiffness": [], "dampings": []}}

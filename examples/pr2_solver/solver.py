"""A task solver in the original PR2 platform's style, run by ``pr2-drake run``.

The original's solvers subclass ``pr2.solver.TaskSolverBase``, get the observation dictionary
every physics step in ``next_action(obs)`` and ask the walking-controller server (TCP, port
8800) for the leg torques through ``pr2.tcp``. This one walks to ``obs["goal"]`` (task 1's goal
centre). A whole original ``examples/`` folder runs with ``pr2-drake pr2-launch``; a single
solver class runs as any agent, beside a server::

    pr2-drake controller-server --task 1 &
    pr2-drake run --task 1 --agent examples/pr2_solver/solver.py:TaskSolver --seconds 10
"""

import json
import math

import numpy as np

from pr2.solver import TaskSolverBase
from pr2.tcp import PersistentTcpClient, json2bin


class WalkingCtrlClient(PersistentTcpClient):
    """Asks the walking-controller server for leg torques (the original's request)."""

    def get_cmd(self, obs: dict, vx: float, vy: float, theta: float, state) -> dict:
        js = obs["agent"]["joint_state"]
        bs = obs["agent"]["body_state"]
        msg = {
            "q_leg": js["legs_positions"].tolist(),
            "dq_leg": js["legs_velocities"].tolist(),
            "q_arm": js["arms_positions"].tolist(),
            "dq_arm": js["arms_velocities"].tolist(),
            "p_wb": bs["world_pos"].tolist(),
            "quat_wb": bs["world_orient"].tolist(),
            "v_wb": bs["linear_velocities"].tolist(),
            "w_wb": bs["angular_velocities"].tolist(),
            "command": [vx, vy, theta],
            "change_state": state,
        }
        return json.loads(self.send(json2bin(msg)).decode("ascii"))


class TaskSolver(TaskSolverBase):
    """Walk to ``obs["goal"]``: turn towards it, walk forward, stop near it."""

    def __init__(self, ip: str = "127.0.0.1", port: int = 8800, speed: float = 0.25):
        self.client = WalkingCtrlClient(ip, port)
        self.speed = speed
        self.steps = 0

    def plan(self, obs: dict) -> list:
        pos = obs["agent"]["body_state"]["world_pos"]
        w, x, y, z = obs["agent"]["body_state"]["world_orient"]
        yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
        goal = np.asarray(obs["goal"], dtype=float)
        dx, dy = goal[0] - pos[0], goal[1] - pos[1]
        err = (math.atan2(dy, dx) - yaw + math.pi) % (2 * math.pi) - math.pi
        theta = float(np.clip(1.2 * err, -0.4, 0.4))
        vx = self.speed if abs(err) < 0.6 and math.hypot(dx, dy) > 0.15 else 0.0
        return [vx, 0.0, theta, -1]  # -1: keep walking (2 would ask for a jump)

    def next_action(self, obs: dict) -> dict:
        vx, vy, theta, state = self.plan(obs)
        joint_efforts = self.client.get_cmd(obs, vx, vy, theta, state)
        self.steps += 1
        return {
            "legs": {
                "ctrl_mode": joint_efforts["mode"],
                "joint_values": joint_efforts["effort"],
                "stiffness": [],
                "dampings": [],
            }
        }

"""Task 1 in the original's solver style: walk straight ahead, asking the walking-controller
server (port 8800) for the leg torques every physics step."""

import json

from pr2.solver import TaskSolverBase
from pr2.tcp import PersistentTcpClient, json2bin

FORWARD_SPEED = 0.2  # [m/s]


class WalkingServerClient(PersistentTcpClient):
    """One request per call: the observed state and a velocity command."""

    def get_cmd(self, obs, vx, vy, yaw_rate, change_state):
        joints, body = obs["agent"]["joint_state"], obs["agent"]["body_state"]
        request = {
            "q_leg": joints["legs_positions"].tolist(),
            "dq_leg": joints["legs_velocities"].tolist(),
            "q_arm": joints["arms_positions"].tolist(),
            "dq_arm": joints["arms_velocities"].tolist(),
            "p_wb": body["world_pos"].tolist(),
            "quat_wb": body["world_orient"].tolist(),
            "v_wb": body["linear_velocities"].tolist(),
            "w_wb": body["angular_velocities"].tolist(),
            "command": [vx, vy, yaw_rate],
            "change_state": change_state,
        }
        reply = json.loads(self.send(json2bin(request)).decode("ascii"))
        if "error" in reply:
            raise RuntimeError(f"controller server: {reply['error']}")
        return reply


class TaskSolver(TaskSolverBase):
    def __init__(self):
        super().__init__()
        self.client = WalkingServerClient(ip="0.0.0.0", port=8800)

    def next_action(self, obs):
        legs = self.client.get_cmd(obs, FORWARD_SPEED, 0.0, 0.0, -1)
        return {"legs": {"ctrl_mode": legs["mode"], "joint_values": legs["effort"],
                         "stiffness": None, "dampings": None}}

"""Task 5 in the original's solver style: walk slowly with ``change_state`` 3 (the original's
task-5 state for walking with an arm raised to press the button), the left arm raised."""

import numpy as np

from pr2.solver import TaskSolverBase
from pr2.tcp import PersistentTcpClient, bin2json, json2bin

ARM_STATE = 3
#: Arm joint targets [rad], original order: left shoulder y, z, x, elbow, then the right arm.
LEFT_ARM_RAISED = np.array([-0.8, -0.5, 0.0, -0.8, 0.8, 0.0, 0.0, -2.1])
KEYS = (("q_leg", "joint_state", "legs_positions"), ("dq_leg", "joint_state", "legs_velocities"),
        ("q_arm", "joint_state", "arms_positions"), ("dq_arm", "joint_state", "arms_velocities"),
        ("p_wb", "body_state", "world_pos"), ("quat_wb", "body_state", "world_orient"),
        ("v_wb", "body_state", "linear_velocities"),
        ("w_wb", "body_state", "angular_velocities"))


class TaskSolver(TaskSolverBase):
    def __init__(self):
        super().__init__()
        self.server = PersistentTcpClient(ip="0.0.0.0", port=8800)

    def next_action(self, obs):
        request = {key: list(map(float, obs["agent"][group][name])) for key, group, name in KEYS}
        request.update(command=[0.1, 0.0, 0.0], change_state=ARM_STATE)
        reply = bin2json(self.server.send(json2bin(request)))
        if "error" in reply:
            raise RuntimeError(f"controller server: {reply['error']}")
        return {"legs": {"ctrl_mode": reply["mode"], "joint_values": reply["effort"]},
                "arms": {"ctrl_mode": "position", "joint_values": LEFT_ARM_RAISED}}

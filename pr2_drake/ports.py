"""The testbed's port contract: names, vector layouts and the command type.

Every block that talks to the testbed (agents, built-in controllers, user systems) uses these
names and layouts, so blocks can be swapped by rewiring ports.

Vector output ports
-------------------
``joint_state`` (size 54), joints in the original platform's order (arms then legs, see
:data:`pr2_drake.robot.params.ARM_JOINTS` / :data:`LEG_JOINTS`)::

    [ q_arms(8) | q_legs(10) | v_arms(8) | v_legs(10) | effort_arms(8) | effort_legs(10) ]

positions in rad, velocities in rad/s, applied efforts in Nm (what the actuation adapter sent to
the plant on the last step, after clamping to the peak torque).

``body_state`` (size 13), the floating base ``base_link`` (frame B) in world W::

    [ p_WB(3) | quat_WB w,x,y,z (4) | v_WB(3) | w_WB(3) ]

in m, unit quaternion, m/s and rad/s, all expressed in W.

Abstract input ports
--------------------
``arms_command`` and ``legs_command`` carry a :class:`JointGroupCommand`; ``pick`` carries a
``str`` ("" for none, "left_hand" or "right_hand"); ``release`` a ``bool``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pr2_drake.robot.params import ARM_JOINTS, LEG_JOINTS

N_ARMS = len(ARM_JOINTS)
N_LEGS = len(LEG_JOINTS)
N_JOINTS = N_ARMS + N_LEGS
JOINT_STATE_SIZE = 3 * N_JOINTS
BODY_STATE_SIZE = 13
CONTROL_MODES = ("position", "velocity", "effort")
PICK_VALUES = ("", "left_hand", "right_hand")

# Slices into the joint_state vector.
Q_ARMS = slice(0, N_ARMS)
Q_LEGS = slice(N_ARMS, N_JOINTS)
V_ARMS = slice(N_JOINTS, N_JOINTS + N_ARMS)
V_LEGS = slice(N_JOINTS + N_ARMS, 2 * N_JOINTS)
EFFORT_ARMS = slice(2 * N_JOINTS, 2 * N_JOINTS + N_ARMS)
EFFORT_LEGS = slice(2 * N_JOINTS + N_ARMS, 3 * N_JOINTS)
Q_ALL = slice(0, N_JOINTS)
V_ALL = slice(N_JOINTS, 2 * N_JOINTS)

# Slices into the body_state vector.
P_WB = slice(0, 3)
QUAT_WB = slice(3, 7)
V_WB = slice(7, 10)
W_WB = slice(10, 13)


@dataclass
class JointGroupCommand:
    """A command for one joint group (arms or legs), as in the original platform's action.

    Attributes:
        mode: "position" (values in rad), "velocity" (rad/s) or "effort" (Nm).
        values: one value per joint of the group, in the original order.
        stiffness: per-joint spring constant [Nm/rad] for position mode; None = defaults.
        damping: per-joint damping [Nm s/rad] for position/velocity modes; None = defaults.

    Position mode applies ``stiffness * (values - q) - damping * v``; velocity mode applies
    ``damping * (values - v)``; effort mode applies ``values``. The result is clamped to each
    joint's peak torque.
    """

    mode: str = "effort"
    values: np.ndarray = field(default_factory=lambda: np.zeros(0))
    stiffness: np.ndarray | None = None
    damping: np.ndarray | None = None

    def __deepcopy__(self, memo) -> "JointGroupCommand":
        # Drake copies abstract values often (state updates, output caches): keep it cheap.
        return JointGroupCommand(
            self.mode,
            np.array(self.values, dtype=float),
            None if self.stiffness is None else np.array(self.stiffness, dtype=float),
            None if self.damping is None else np.array(self.damping, dtype=float),
        )

    @staticmethod
    def effort(values) -> "JointGroupCommand":
        return JointGroupCommand("effort", np.asarray(values, dtype=float))

    @staticmethod
    def position(values, stiffness=None, damping=None) -> "JointGroupCommand":
        return JointGroupCommand(
            "position",
            np.asarray(values, dtype=float),
            None if stiffness is None else np.asarray(stiffness, dtype=float),
            None if damping is None else np.asarray(damping, dtype=float),
        )

    @staticmethod
    def velocity(values, damping=None) -> "JointGroupCommand":
        return JointGroupCommand(
            "velocity",
            np.asarray(values, dtype=float),
            None,
            None if damping is None else np.asarray(damping, dtype=float),
        )


def validate_command(port: str, cmd: object, n: int) -> JointGroupCommand:
    """Check a command arriving on ``port`` for a group of ``n`` joints.

    Raises:
        ValueError: naming the port and the fault (type, mode, length, NaN/inf, negative gains).
    """
    if not isinstance(cmd, JointGroupCommand):
        raise ValueError(f"{port}: expected a JointGroupCommand, got {type(cmd).__name__}")
    if cmd.mode not in CONTROL_MODES:
        raise ValueError(f"{port}: unknown mode {cmd.mode!r}; expected one of {CONTROL_MODES}")
    for name in ("values", "stiffness", "damping"):
        arr = getattr(cmd, name)
        if arr is None:
            continue
        arr = np.asarray(arr, dtype=float)
        if arr.shape != (n,):
            raise ValueError(f"{port}: {name} must have {n} entries, got shape {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"{port}: {name} contains NaN or inf: {arr}")
        if name != "values" and np.any(arr < 0):
            raise ValueError(f"{port}: {name} must be non-negative, got {arr}")
    return cmd

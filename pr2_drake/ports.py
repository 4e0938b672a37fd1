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


def real_vector(value: object, n: int, name: str, *, non_negative: bool = False) -> np.ndarray:
    """``value`` as a float64 vector of exactly ``n`` finite reals, or a ValueError naming it.

    Accepted: float64/float32/integer numpy arrays of shape (n,), and flat lists or tuples of
    ints and floats. Refused, with ``name`` and the fault in the message: None, strings and
    bytes (also numeric ones such as "1.0"), booleans (a bool is not a joint value, even in a
    list of floats), complex numbers, object arrays, any other shape (scalars, nested lists,
    (n, 1) arrays), NaN and inf, and numbers beyond the float range (such as ``10**400``).
    Finite values are kept however large (efforts are clamped to the peak torque, gains capped
    to the stable limits, downstream). ``non_negative`` also refuses negative entries (gains).

    Args:
        name: what to call the value in messages, e.g. ``"action['legs']['joint_values']"``.
    """
    if type(value) is np.ndarray and value.dtype is _F64 and value.shape == (n,):
        arr = value  # the common case, kept cheap: the actuation adapter validates every tick
    else:
        arr = _real_array(value, n, name)
        if arr.shape != (n,):
            raise ValueError(f"{name} must have {n} entries, got shape {arr.shape}")
    if not _ISFINITE(arr).all():
        if value is not arr and np.all(np.isfinite(np.asarray(value))):
            raise ValueError(f"{name} has a value beyond the float range (|x| > 1.8e308)")
        raise ValueError(f"{name} contains NaN or inf: {arr}")
    if non_negative and n and _MIN(arr) < 0:
        raise ValueError(f"{name} must be non-negative, got {arr}")
    return arr


_F64 = np.dtype(np.float64)
_ISFINITE = np.isfinite
_MIN = np.minimum.reduce


def _real_array(value: object, n: int, name: str) -> np.ndarray:
    """The slow path of :func:`real_vector`: type checks and conversion to float64."""
    if value is None:
        raise ValueError(f"{name} is None; expected {n} real numbers")
    if isinstance(value, (str, bytes)):
        raise ValueError(f"{name} is not numeric: got {type(value).__name__} {value!r:.40}")
    if isinstance(value, (list, tuple)) and any(isinstance(x, (bool, np.bool_)) for x in value):
        raise ValueError(f"{name} is not numeric: booleans are not accepted as numbers")
    try:
        arr = np.asarray(value)
    except (TypeError, ValueError) as e:  # e.g. ragged nested lists
        raise ValueError(f"{name} is not a numeric vector of shape ({n},): "
                         f"{type(e).__name__}: {str(e)[:100]}") from None
    kind = arr.dtype.kind
    if kind in "iuf":
        with np.errstate(over="ignore"):  # float128 beyond the float range: caught as inf
            return arr.astype(np.float64, copy=False)
    if kind == "b":
        raise ValueError(f"{name} is not numeric: booleans are not accepted as numbers")
    if kind == "c":
        raise ValueError(f"{name} is complex; expected real numbers")
    if kind in "US":
        raise ValueError(f"{name} is not numeric: got text ({arr.dtype})")
    if kind == "O":
        for x in arr.flat:
            if isinstance(x, int) and not isinstance(x, bool):
                try:
                    float(x)
                except OverflowError:
                    raise ValueError(
                        f"{name} has a value beyond the float range (|x| > 1.8e308)") from None
        kinds = sorted({type(x).__name__ for x in arr.flat})
        raise ValueError(f"{name} is not numeric: an object array of {', '.join(kinds[:4])}")
    raise ValueError(f"{name} is not numeric: dtype {arr.dtype}")


def check_mode(mode: object, where: str) -> str:
    """``mode`` as a plain str among :data:`CONTROL_MODES`, or a ValueError naming ``where``."""
    if not isinstance(mode, str):
        raise ValueError(f"{where}: mode must be a str, one of {CONTROL_MODES}; "
                         f"got {type(mode).__name__}")
    if mode not in CONTROL_MODES:
        raise ValueError(f"{where}: unknown mode {mode!r}; expected one of {CONTROL_MODES}")
    return str(mode)


def validate_command(port: str, cmd: object, n: int) -> JointGroupCommand:
    """Check a command arriving on ``port`` for a group of ``n`` joints; returns it unchanged.

    The mode must be a str among :data:`CONTROL_MODES`; ``values`` (never None), ``stiffness``
    and ``damping`` (None = defaults) must pass :func:`real_vector` (gains non-negative).

    Raises:
        ValueError: naming the port and the fault (type, mode, length, NaN/inf, negative gains).
    """
    if not isinstance(cmd, JointGroupCommand):
        raise ValueError(f"{port}: expected a JointGroupCommand, got {type(cmd).__name__}")
    mode = cmd.mode
    if mode.__class__ is not str or mode not in CONTROL_MODES:
        check_mode(mode, port)
    real_vector(cmd.values, n, f"{port}: values")
    if cmd.stiffness is not None:
        real_vector(cmd.stiffness, n, f"{port}: stiffness", non_negative=True)
    if cmd.damping is not None:
        real_vector(cmd.damping, n, f"{port}: damping", non_negative=True)
    return cmd

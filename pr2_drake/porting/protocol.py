"""The original PR2 platform's walking-controller protocol: frames, requests, ``change_state``.

Framing, both ways: a 4-byte big-endian unsigned length, then that many bytes of JSON (one
object; replies are ASCII, as the original's clients decode them). A zero-length frame from the
client is its "exit" signal (the original's ``PersistentTcpClient.close``): the server closes
that connection without a reply.

Request (world frame, original joint order; rad, m, s)::

    {"q_leg": [10], "dq_leg": [10], "q_arm": [8], "dq_arm": [8],
     "p_wb": [3], "quat_wb": [4] (w, x, y, z), "v_wb": [3], "w_wb": [3],
     "command": [vx, vy, theta],     # heading frame [m/s, m/s, rad/s]
     "change_state": see below,      # optional, default walk
     "time": t,                      # optional: simulation time [s]
     "current_arm": [8]}             # optional: applied arm efforts [Nm]

``change_state``, the values the original's files use:

- -1 (also 0, false or null): walk with ``command``;
- 2: jump (task 3): on the first 2 after a non-2, one jump taking off as soon as possible with
  ``command``'s horizontal velocity;
- 3 (task 5): the solver raises an arm to press the button while it keeps walking with
  ``command``. The original's controller binary is closed; its files show only that the task-5
  solver keeps sending walking commands in state 3 and drives the arm itself, so the server
  walks with ``command`` as for -1, the whole-body controller balancing with the arm posture
  the request reports.

Any other value is refused, named.
"""

from __future__ import annotations

import json
import math
import socket
import threading
import time
from typing import Any, Mapping

import numpy as np

from pr2_drake.framing import LENGTH, frame
from pr2_drake.ports import N_ARMS, N_LEGS, real_vector

#: Longest request frame [bytes]; a longer one closes the connection (after an error reply).
MAX_REQUEST_BYTES = 1 << 20
#: Required request keys and their sizes.
REQUEST_KEYS: dict[str, int] = {
    "q_leg": N_LEGS, "dq_leg": N_LEGS, "q_arm": N_ARMS, "dq_arm": N_ARMS,
    "p_wb": 3, "quat_wb": 4, "v_wb": 3, "w_wb": 3, "command": 3,
}
OPTIONAL_KEYS = ("change_state", "time", "current_arm")
WALK_STATES = (-1, 0)
JUMP_STATE = 2
ARM_STATE = 3  # task 5: walk on while the solver raises an arm (see the module docstring)
KNOWN_STATES = WALK_STATES + (JUMP_STATE, ARM_STATE)


class ProtocolError(ValueError):
    """A request the server refuses; the message names the fault."""


class IdleTimeout(ConnectionError):
    """No complete frame arrived within the idle limit."""


def parse_request(request: Any) -> tuple[dict[str, Any], np.ndarray, int, float | None]:
    """(observation dict for the controller, command (3), change_state, time or None) from a
    decoded request.

    Raises:
        ProtocolError: naming the key and the fault.
    """
    if not isinstance(request, dict):
        raise ProtocolError(f"request: expected a JSON object, got {type(request).__name__}")
    missing = [k for k in REQUEST_KEYS if k not in request]
    if missing:
        raise ProtocolError(f"request: missing key(s) {missing}; required: {list(REQUEST_KEYS)}")
    unknown = sorted(set(request) - set(REQUEST_KEYS) - set(OPTIONAL_KEYS), key=str)
    if unknown:
        raise ProtocolError(f"request: unknown key(s) {unknown}; expected "
                            f"{list(REQUEST_KEYS) + list(OPTIONAL_KEYS)}")
    v: dict[str, np.ndarray] = {}
    try:
        for key, n in REQUEST_KEYS.items():
            v[key] = real_vector(request[key], n, f"request[{key!r}]")
        arm_effort = (None if request.get("current_arm") is None
                      else real_vector(request["current_arm"], N_ARMS, "request['current_arm']"))
    except ValueError as e:
        raise ProtocolError(str(e)) from None
    norm = float(np.linalg.norm(v["quat_wb"]))
    if not 0.9 < norm < 1.1:
        raise ProtocolError(f"request['quat_wb'] must be a unit quaternion (w, x, y, z), "
                            f"got norm {norm:.3g}")
    state = parse_change_state(request.get("change_state"))
    t = request.get("time")
    if t is not None:
        if isinstance(t, bool) or not isinstance(t, (int, float)) or not math.isfinite(t) \
                or t < 0:
            raise ProtocolError(f"request['time'] must be a finite time >= 0 [s], got {t!r}")
        t = float(t)
    joint_state = {"legs_positions": v["q_leg"], "legs_velocities": v["dq_leg"],
                   "arms_positions": v["q_arm"], "arms_velocities": v["dq_arm"]}
    if arm_effort is not None:
        joint_state["arms_applied_effort"] = arm_effort
    obs = {"agent": {"joint_state": joint_state, "body_state": {
        "world_pos": v["p_wb"], "world_orient": v["quat_wb"] / norm,
        "linear_velocities": v["v_wb"], "angular_velocities": v["w_wb"]}}}
    return obs, v["command"], state, t


def parse_change_state(value: Any) -> int:
    """``change_state`` as -1/0 (walk), 2 (jump) or 3 (arm raised, walk); None/false walk.

    Raises:
        ProtocolError: any other value, named.
    """
    if value is None or value is False:
        return 0
    if isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value) \
            and float(value).is_integer() and int(value) in KNOWN_STATES:
        return int(value)
    raise ProtocolError(f"request['change_state']: unknown value {value!r}; expected -1, 0, "
                        f"false or null (walk), 2 (jump) or 3 (walk, arm raised: task 5)")


def encode(message: Mapping[str, Any]) -> bytes:
    """A framed message: 4-byte big-endian length + ASCII JSON."""
    data = json.dumps(message, separators=(",", ":"), allow_nan=False).encode("ascii")
    return frame(data)


def decode(payload: bytes) -> Any:
    """A request's JSON value.

    Raises:
        ProtocolError: not UTF-8 or not valid JSON.
    """
    try:
        return json.loads(payload.decode("utf-8"))
    except UnicodeDecodeError as e:
        raise ProtocolError(f"request: not UTF-8: {e}") from None
    except json.JSONDecodeError as e:
        raise ProtocolError(f"request: not valid JSON: {e}") from None


def recv_exact(sock: socket.socket, n: int, stop: threading.Event | None = None,
               deadline: float | None = None) -> bytes | None:
    """n bytes, or None when the peer closed (or ``stop`` was set) before the first byte.
    ``sock`` needs a timeout (the polling period of ``stop`` and ``deadline``).

    Args:
        deadline: ``time.monotonic()`` after which waiting raises :class:`IdleTimeout`.
    Raises:
        ConnectionError: the peer closed in the middle.
        IdleTimeout: the deadline passed.
    """
    chunks, got = [], 0
    while got < n:
        try:
            chunk = sock.recv(n - got)
        except socket.timeout:
            if stop is not None and stop.is_set():
                return None
            if deadline is not None and time.monotonic() > deadline:
                raise IdleTimeout(f"idle: {got} of {n} bytes before the time limit") from None
            continue
        if not chunk:
            if got == 0:
                return None
            raise ConnectionError(f"connection closed after {got} of {n} bytes")
        chunks.append(chunk)
        got += len(chunk)
    return b"".join(chunks)


def read_frame(sock: socket.socket, stop: threading.Event | None = None,
               deadline: float | None = None) -> bytes | None:
    """One frame's payload (b"" for a zero-length frame), or None when the peer closed.

    Raises:
        ProtocolError: the length is over :data:`MAX_REQUEST_BYTES`.
        ConnectionError, IdleTimeout: see :func:`recv_exact`.
    """
    header = recv_exact(sock, LENGTH.size, stop, deadline)
    if header is None:
        return None
    (n,) = LENGTH.unpack(header)
    if n > MAX_REQUEST_BYTES:
        raise ProtocolError(f"request: frame length {n} bytes exceeds {MAX_REQUEST_BYTES}; "
                            f"closing the connection")
    if n == 0:
        return b""
    return recv_exact(sock, n, stop, deadline)

"""Clients of the walking-controller server: :class:`ControllerClient` (TCP) and
:class:`InProcessClient` (the same calls answered without a socket, for sandboxed competition
runs, where sockets are refused). Both take the original client's call
``get_cmd(obs, vx, vy, theta, change_state)``."""

from __future__ import annotations

import json
import socket
from typing import Any, Mapping

import numpy as np

from pr2_drake.framing import LENGTH, frame
from pr2_drake.porting.protocol import ProtocolError, encode, recv_exact
from pr2_drake.porting.session import ControllerServerConfig, WalkingSession


class ControllerError(RuntimeError):
    """The server answered with an error (its message)."""


def request_from_obs(obs: Mapping[str, Any], vx: float, vy: float, theta: float,
                     change_state: Any = 0, time: float | None = None) -> dict[str, Any]:
    """The request the original's client builds from a PR2 observation dict."""
    agent = obs["agent"]
    js, bs = agent["joint_state"], agent["body_state"]

    def lst(x):
        return np.asarray(x, dtype=float).tolist()

    msg = {"q_leg": lst(js["legs_positions"]), "dq_leg": lst(js["legs_velocities"]),
           "q_arm": lst(js["arms_positions"]), "dq_arm": lst(js["arms_velocities"]),
           "p_wb": lst(bs["world_pos"]), "quat_wb": lst(bs["world_orient"]),
           "v_wb": lst(bs["linear_velocities"]), "w_wb": lst(bs["angular_velocities"]),
           "command": [float(vx), float(vy), float(theta)], "change_state": change_state}
    if time is not None:
        msg["time"] = float(time)
    return msg


def _checked(reply: dict[str, Any]) -> dict[str, Any]:
    if "error" in reply:
        raise ControllerError(reply["error"])
    return reply


class ControllerClient:
    """A client of :class:`pr2_drake.porting.controller_server.ControllerServer` (one
    persistent connection; :meth:`close` sends the original's zero-length "exit" frame).

    >>> client = ControllerClient("127.0.0.1", 8800)          # doctest: +SKIP
    >>> reply = client.get_cmd(obs, 0.2, 0.0, 0.0, -1)        # doctest: +SKIP
    >>> action = {"legs": {"ctrl_mode": reply["mode"], "joint_values": reply["effort"]}}

    Args:
        host, port: the server.
        timeout: [s] for connecting and for each reply.
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 8800, timeout: float = 30.0):
        self.sock = socket.create_connection((host, port), timeout=timeout)
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)

    def request(self, message: Mapping[str, Any] | bytes) -> dict[str, Any]:
        """Send one message (a dict, or an already encoded JSON payload) and return the reply
        as it came (errors included).

        Raises:
            ConnectionError: the server closed the connection.
        """
        self.sock.sendall(frame(message) if isinstance(message, bytes) else encode(message))
        header = recv_exact(self.sock, LENGTH.size)
        if header is None:
            raise ConnectionError("the controller server closed the connection")
        (n,) = LENGTH.unpack(header)
        body = recv_exact(self.sock, n) if n else b""
        if body is None:
            raise ConnectionError("the controller server closed the connection")
        return json.loads(body.decode("utf-8"))

    def get_cmd(self, obs: Mapping[str, Any], vx: float, vy: float, theta: float,
                change_state: Any = 0, time: float | None = None) -> dict[str, Any]:
        """Leg torques for a PR2 observation and a velocity command: ``{"mode", "effort",
        ...}`` (the original client's call).

        Raises:
            ControllerError: the server's error reply.
        """
        return _checked(self.request(request_from_obs(obs, vx, vy, theta, change_state, time)))

    def close(self) -> None:
        """Send the "exit" frame (zero length) and close."""
        try:
            self.sock.sendall(frame(b""))
        except OSError:
            pass
        self.sock.close()

    def __enter__(self) -> "ControllerClient":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class InProcessClient:
    """:class:`ControllerClient`'s calls answered in this process, without a socket (for a
    sandboxed competition run, where sockets are forbidden). Same requests, same replies."""

    def __init__(self, config: ControllerServerConfig | None = None):
        self.session = WalkingSession(config)

    def request(self, message: Mapping[str, Any]) -> dict[str, Any]:
        try:
            return self.session.answer(json.loads(json.dumps(message)))
        except ProtocolError as e:
            return {"error": str(e)}

    def get_cmd(self, obs: Mapping[str, Any], vx: float, vy: float, theta: float,
                change_state: Any = 0, time: float | None = None) -> dict[str, Any]:
        return _checked(self.request(request_from_obs(obs, vx, vy, theta, change_state, time)))

    def close(self) -> None:
        pass

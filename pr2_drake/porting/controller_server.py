"""The original PR2 platform's walking-controller TCP protocol, answered by our controllers.

A solver written for the original platform gets its leg torques from a walking-controller
server over TCP (port 8800). :class:`ControllerServer` (``pr2-drake controller-server --port
8800``) speaks that protocol with the built-in whole-body controller
(:class:`pr2_drake.controllers.jumping.JumpController`: walking, plus jumps on request), so
such a solver runs unchanged against this testbed.

Framing, both ways: a 4-byte big-endian unsigned length, then that many bytes of UTF-8 JSON
(one object).

Request (one per call; world frame, original joint order, rad, m, s)::

    {"q_leg": [10], "dq_leg": [10], "q_arm": [8], "dq_arm": [8],
     "p_wb": [3], "quat_wb": [4] (w, x, y, z), "v_wb": [3], "w_wb": [3],
     "command": [vx, vy, theta],     # heading frame [m/s, m/s, rad/s]
     "change_state": -1 | 0 | false | null (walk) or 2 (jump),   # optional, default walk
     "time": t,                      # optional: simulation time [s]
     "current_arm": [8]}             # optional: applied arm efforts [Nm]

Reply: ``{"mode": "effort", "effort": [10 leg torques, Nm], "time": t, "jump_phase": name,
"jumps": n}`` (the original's clients read ``mode`` and ``effort``), or ``{"error": "..."}``
naming the fault (malformed JSON, a missing or malformed key, an unknown ``change_state``...);
after an error reply the connection stays open and the controller state is unchanged. Only an
impossible frame (a length over :data:`MAX_REQUEST_BYTES`) gets an error reply and then closes
the connection, as the stream cannot be resynchronised.

Time: the controller needs the simulation time. A request's ``time`` field, when present, is
it; otherwise the server counts the connection's valid requests: the n-th (from 0) is at
``n * request_period`` (default one physics step, 2 ms: the original's solvers call the
server once per step). The control law runs every ``control_period`` of that time (4 ms,
params/controllers/walking.yaml) and the torques are held in between. A time earlier than the last
one restarts the controller (a new episode).

Sessions: one client at a time; each connection is one episode (the controller restarts when a
connection opens). Later connections are served in turn.

``change_state``: -1, 0, false or null walk with ``command``. 2 asks for a jump: on the first
request with 2 after one without (a rising edge), the server requests a jump taking off as
soon as possible (crouch first) with the horizontal velocity ``command[0:2]`` (clipped to the
jump controller's ``max_speed``) and the apex ``jump_apex`` (0.18 m); while that jump is
pending or under way the walking command is held at zero (the robot must stand to crouch) and
further 2s are ignored; walking resumes after the landing. Any other value gets an error reply.

:class:`ControllerClient` is the client side (the original's ``get_cmd(obs, vx, vy, theta,
state)``); :class:`InProcessClient` answers the same calls without a socket (for sandboxed
competition runs, where sockets are forbidden).
"""

from __future__ import annotations

import json
import math
import socket
import sys
import threading
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from pr2_drake.framing import LENGTH, frame
from pr2_drake.ports import N_ARMS, N_LEGS, real_vector
from pr2_drake.testbed import DEFAULT_TIME_STEP

MAX_REQUEST_BYTES = 1 << 20
#: Required request keys and their sizes.
REQUEST_KEYS: dict[str, int] = {
    "q_leg": N_LEGS, "dq_leg": N_LEGS, "q_arm": N_ARMS, "dq_arm": N_ARMS,
    "p_wb": 3, "quat_wb": 4, "v_wb": 3, "w_wb": 3, "command": 3,
}
OPTIONAL_KEYS = ("change_state", "time", "current_arm")
WALK_STATES = (-1, 0)
JUMP_STATE = 2


class ProtocolError(ValueError):
    """A request the server refuses; the message names the fault."""


@dataclass
class ControllerServerConfig:
    """How the server's controller is built and timed.

    Attributes:
        walking: walking parameters (YAML; relative paths also in the data root).
        overrides: a partial walking YAML applied on top (e.g. params/controllers/walking_rough.yaml).
        terrain: footholds: "flat", or "rough" (unknown stones: the swing sole aims
            ``rough_drop`` below the stance sole and touches down on contact, as the task-1
            reference agent does).
        rough_drop: [m] see ``terrain``.
        jumping: jump parameters (YAML).
        jump_apex: [m] CoM rise of a jump asked for with ``change_state`` 2.
        request_period: [s] simulated time between two requests without a ``time`` field.
    """

    walking: str = "params/controllers/walking.yaml"
    overrides: str | None = None
    terrain: str = "flat"
    rough_drop: float = 0.025
    jumping: str = "params/controllers/jumping.yaml"
    jump_apex: float = 0.18
    request_period: float = DEFAULT_TIME_STEP

    def validate(self) -> None:
        if self.terrain not in ("flat", "rough"):
            raise ValueError(f"terrain must be 'flat' or 'rough', got {self.terrain!r}")
        if not (math.isfinite(self.request_period) and 0 < self.request_period <= 1.0):
            raise ValueError(f"request_period must be in (0, 1] s, got {self.request_period!r}")
        if not (math.isfinite(self.jump_apex) and self.jump_apex > 0):
            raise ValueError(f"jump_apex must be > 0 m, got {self.jump_apex!r}")
        if not (math.isfinite(self.rough_drop) and self.rough_drop >= 0):
            raise ValueError(f"rough_drop must be >= 0 m, got {self.rough_drop!r}")


class WalkingSession:
    """One episode's controller behind the protocol: :meth:`answer` takes a decoded request
    and returns the reply (see the module docstring). Build once, :meth:`reset` per episode."""

    def __init__(self, config: ControllerServerConfig | None = None):
        from pr2_drake.controllers.planning.terrain import RoughTerrain
        from pr2_drake.controllers.jumping import JumpController
        from pr2_drake.controllers.walking_params import WalkingParams

        self.config = config or ControllerServerConfig()
        self.config.validate()
        params = WalkingParams.load(self.config.walking)
        if self.config.overrides:
            params = params.with_overrides(self.config.overrides)
        terrain = RoughTerrain(self.config.rough_drop) if self.config.terrain == "rough" else None
        self.controller = JumpController(params, self.config.jumping, terrain=terrain)
        self.reset()

    def reset(self) -> None:
        """Start a new episode: the controller's gait, jump and clock restart."""
        self.controller.reset()
        self.requests = 0  # valid requests answered in this episode
        self.last_time: float | None = None
        self.last_state = 0

    def answer(self, request: Any) -> dict[str, Any]:
        """The reply to one decoded request.

        Raises:
            ProtocolError: the request is malformed (nothing changed).
        """
        obs, command, state, t = parse_request(request)
        if t is None:
            t = self.requests * self.config.request_period
        if self.last_time is not None and t < self.last_time - 1e-9:
            self.reset()  # the simulation restarted
        jumper = self.controller.jump
        busy = jumper.pending is not None or jumper.planner.active
        jump = None
        if state == JUMP_STATE and self.last_state != JUMP_STATE and not busy:
            v = command[:2].copy()
            speed = float(np.hypot(*v))
            if speed > jumper.params.max_speed:
                v *= jumper.params.max_speed / speed
            jump = (t, v[0], v[1], self.config.jump_apex)
            busy = True
        if busy:
            command = np.zeros(3)
        try:
            action = self.controller.command(obs, *command, t=t, jump=jump)
        except ValueError as e:
            raise ProtocolError(str(e)) from None
        self.requests += 1
        self.last_time = t
        self.last_state = state
        return {"mode": "effort", "effort": [float(x) for x in action["joint_values"]],
                "time": t, "jump_phase": jumper.phase.name, "jumps": int(jumper.jumps)}


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
    """``change_state`` as -1/0 (walk) or 2 (jump); None/false walk.

    Raises:
        ProtocolError: any other value, named.
    """
    if value is None or value is False:
        return 0
    if isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value) \
            and float(value).is_integer() and int(value) in WALK_STATES + (JUMP_STATE,):
        return int(value)
    raise ProtocolError(f"request['change_state']: unknown value {value!r}; expected -1, 0, "
                        f"false or null (walk) or 2 (jump)")


# -- framing ------------------------------------------------------------------------------------
def encode(message: Mapping[str, Any]) -> bytes:
    """A framed message: 4-byte big-endian length + UTF-8 JSON."""
    data = json.dumps(message, separators=(",", ":"), allow_nan=False).encode("utf-8")
    return frame(data)


def _recv_exact(sock: socket.socket, n: int, stop: threading.Event | None = None) -> bytes | None:
    """n bytes, or None when the peer closed (or ``stop`` was set) before the first byte.

    Raises:
        ConnectionError: the peer closed in the middle.
    """
    chunks, got = [], 0
    while got < n:
        try:
            chunk = sock.recv(n - got)
        except socket.timeout:
            if stop is not None and stop.is_set():
                return None
            continue
        if not chunk:
            if got == 0:
                return None
            raise ConnectionError(f"connection closed after {got} of {n} bytes")
        chunks.append(chunk)
        got += len(chunk)
    return b"".join(chunks)


# -- server -------------------------------------------------------------------------------------
class ControllerServer:
    """The walking-controller server (see the module docstring).

    Args:
        host, port: where to listen (port 0: a free port, see :attr:`address`).
        config: the controller (default :class:`ControllerServerConfig`).
        session: an already built session to serve (instead of ``config``).
        log: where one line per connection goes (None: nowhere).
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 8800,
                 config: ControllerServerConfig | None = None, *,
                 session: WalkingSession | None = None, log=sys.stderr):
        if not isinstance(port, int) or isinstance(port, bool) or not 0 <= port <= 65535:
            raise ValueError(f"port must be an int in 0..65535, got {port!r}")
        self.session = session or WalkingSession(config)
        self.log = log
        self.requests = 0  # replies sent, errors included, over all connections
        self.errors = 0
        self.connections = 0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self._sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            self._sock.bind((host, port))
        except OSError as e:
            self._sock.close()
            raise ValueError(f"controller server: cannot listen on {host}:{port}: {e}") from None
        self._sock.listen(1)
        self._sock.settimeout(0.2)

    @property
    def address(self) -> tuple[str, int]:
        return self._sock.getsockname()[:2]

    def serve_forever(self) -> None:
        """Serve connections one after the other until :meth:`close`."""
        while not self._stop.is_set():
            try:
                conn, peer = self._sock.accept()
            except socket.timeout:
                continue
            except OSError:
                if self._stop.is_set():
                    return
                raise
            with conn:
                self._serve(conn, peer)

    def start(self) -> "ControllerServer":
        """Serve in a background thread (returns self)."""
        self._thread = threading.Thread(target=self.serve_forever, name="controller-server",
                                        daemon=True)
        self._thread.start()
        return self

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        self._sock.close()

    def __enter__(self) -> "ControllerServer":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _serve(self, conn: socket.socket, peer) -> None:
        self.connections += 1
        self.session.reset()
        conn.settimeout(0.5)
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        served = 0
        self._say(f"controller-server: connection {self.connections} from {peer[0]}:{peer[1]}")
        try:
            while not self._stop.is_set():
                header = _recv_exact(conn, LENGTH.size, self._stop)
                if header is None:
                    break
                (n,) = LENGTH.unpack(header)
                if n > MAX_REQUEST_BYTES:
                    self._reply(conn, {"error": f"request: frame length {n} bytes exceeds "
                                                f"{MAX_REQUEST_BYTES}; closing the connection"})
                    break
                payload = _recv_exact(conn, n, self._stop) if n else b""
                if payload is None:
                    break
                self._reply(conn, self._answer(payload))
                served += 1
        except (ConnectionError, OSError) as e:
            self._say(f"controller-server: connection {self.connections} dropped: {e}")
        self._say(f"controller-server: connection {self.connections} closed after {served} "
                  f"requests")

    def _answer(self, payload: bytes) -> dict[str, Any]:
        try:
            try:
                request = json.loads(payload.decode("utf-8"))
            except UnicodeDecodeError as e:
                raise ProtocolError(f"request: not UTF-8: {e}") from None
            except json.JSONDecodeError as e:
                raise ProtocolError(f"request: not valid JSON: {e}") from None
            return self.session.answer(request)
        except ProtocolError as e:
            self.errors += 1
            return {"error": str(e)}
        except Exception as e:  # a controller failure: say so, keep serving
            self.errors += 1
            return {"error": f"controller: {type(e).__name__}: {' '.join(str(e).split())}"}

    def _reply(self, conn: socket.socket, reply: dict[str, Any]) -> None:
        try:
            data = encode(reply)
        except (ValueError, TypeError) as e:  # e.g. a non-finite torque: say so, keep serving
            self.errors += 1
            data = encode({"error": f"controller: reply not encodable: {e}"})
        conn.sendall(data)
        self.requests += 1

    def _say(self, line: str) -> None:
        if self.log is not None:
            print(line, file=self.log, flush=True)


# -- clients ------------------------------------------------------------------------------------
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


class ControllerClient:
    """A client of :class:`ControllerServer` (one persistent connection).

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
        as it came (errors included)."""
        payload = message if isinstance(message, bytes) else None
        data = frame(payload) if payload is not None else encode(message)
        self.sock.sendall(data)
        header = _recv_exact(self.sock, LENGTH.size)
        if header is None:
            raise ConnectionError("the controller server closed the connection")
        (n,) = LENGTH.unpack(header)
        body = _recv_exact(self.sock, n) if n else b""
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
        reply = self.request(request_from_obs(obs, vx, vy, theta, change_state, time))
        if "error" in reply:
            raise ControllerError(reply["error"])
        return reply

    def close(self) -> None:
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
        reply = self.request(request_from_obs(obs, vx, vy, theta, change_state, time))
        if "error" in reply:
            raise ControllerError(reply["error"])
        return reply

    def close(self) -> None:
        pass

"""The original PR2 platform's walking-controller TCP server, answered by our controllers.

A solver written for the original platform gets its leg torques from a walking-controller
server over TCP (port 8800). :class:`ControllerServer` (``pr2-drake controller-server [--task
N]``) speaks that protocol (:mod:`pr2_drake.porting.protocol`: frames, requests,
``change_state``) with the built-in whole-body controller, one
:class:`pr2_drake.porting.session.WalkingSession` per connection, so such a solver runs
unchanged against this testbed.

Replies: ``{"mode": "effort", "effort": [10 leg torques, Nm], "time": t, "jump_phase": name,
"jumps": n}`` (the original's clients read ``mode`` and ``effort``), or ``{"error": "..."}``
naming the fault (malformed JSON, a missing or malformed key, an unknown ``change_state``...);
after an error reply the connection stays open and the controller state is unchanged. An
impossible frame (a length over ``MAX_REQUEST_BYTES``) gets an error reply and then closes the
connection, as the stream cannot be resynchronised.

Connections (:class:`ServerLimits`): each is one episode with its own controller, served in its
own thread, up to ``max_clients`` at once; one more gets an error reply at once and is closed.
A connection closes when the client closes it, sends the zero-length "exit" frame (the
original's ``PersistentTcpClient.close``), or sends no complete request for ``idle_timeout``
seconds (closed without a reply, so that no stale reply waits for the client's next request).

Clients: :mod:`pr2_drake.porting.clients`.
"""

from __future__ import annotations

import math
import socket
import sys
import threading
import time
from dataclasses import dataclass
from typing import Any

from pr2_drake.porting.protocol import (
    IdleTimeout,
    ProtocolError,
    decode,
    encode,
    read_frame,
)
from pr2_drake.porting.session import ControllerServerConfig, WalkingSession

#: [s] how often blocked sockets look at the stop flag and the idle deadline.
POLL_PERIOD = 0.2


@dataclass
class ServerLimits:
    """How many clients, and for how long.

    Attributes:
        max_clients: connections served at once; one more gets an error reply and is closed.
        idle_timeout: [s] a connection without a complete request for this long is closed.
        backlog: connections the kernel queues before they are accepted.
    """

    max_clients: int = 16
    idle_timeout: float = 60.0
    backlog: int = 128

    def validate(self) -> None:
        if isinstance(self.max_clients, bool) or not isinstance(self.max_clients, int) \
                or self.max_clients < 1:
            raise ValueError(f"max_clients must be an int >= 1, got {self.max_clients!r}")
        if not (isinstance(self.idle_timeout, (int, float)) and math.isfinite(self.idle_timeout)
                and self.idle_timeout > 0):
            raise ValueError(f"idle_timeout must be a finite time > 0 s, got "
                             f"{self.idle_timeout!r}")
        if isinstance(self.backlog, bool) or not isinstance(self.backlog, int) \
                or self.backlog < 1:
            raise ValueError(f"backlog must be an int >= 1, got {self.backlog!r}")


class ControllerServer:
    """The walking-controller server (see the module docstring).

    Args:
        host, port: where to listen (port 0: a free port, see :attr:`address`).
        config: the controller of every connection (default :class:`ControllerServerConfig`).
        session: an already built session for the first connection (its config for others).
        limits: clients at once, idle time, backlog (default :class:`ServerLimits`).
        log: where one line per connection goes (None: nowhere).
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 8800,
                 config: ControllerServerConfig | None = None, *,
                 session: WalkingSession | None = None, limits: ServerLimits | None = None,
                 log=sys.stderr):
        if not isinstance(port, int) or isinstance(port, bool) or not 0 <= port <= 65535:
            raise ValueError(f"port must be an int in 0..65535, got {port!r}")
        self.limits = limits or ServerLimits()
        self.limits.validate()
        first = session or WalkingSession(config)  # a bad config fails here, before listening
        self.config = first.config
        self._idle_sessions = [first]
        self.log = log
        self.requests = 0  # replies sent, errors included, over all connections
        self.errors = 0
        self.connections = 0  # connections accepted (refused ones included)
        self.refused = 0
        self._active = 0
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._workers: set[threading.Thread] = set()
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self._sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            self._sock.bind((host, port))
        except OSError as e:
            self._sock.close()
            raise ValueError(f"controller server: cannot listen on {host}:{port}: {e}") from None
        self._sock.listen(self.limits.backlog)
        self._sock.settimeout(POLL_PERIOD)

    @property
    def address(self) -> tuple[str, int]:
        return self._sock.getsockname()[:2]

    @property
    def active(self) -> int:
        """Connections being served now."""
        return self._active

    def serve_forever(self) -> None:
        """Accept connections, each served in its own thread, until :meth:`close`."""
        while not self._stop.is_set():
            try:
                conn, peer = self._sock.accept()
            except socket.timeout:
                continue
            except OSError:
                if self._stop.is_set():
                    return
                raise
            self._admit(conn, peer)

    def start(self) -> "ControllerServer":
        """Serve in a background thread (returns self)."""
        self._thread = threading.Thread(target=self.serve_forever, name="controller-server",
                                        daemon=True)
        self._thread.start()
        return self

    def close(self) -> None:
        """Stop accepting, end every connection, and close the socket."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        with self._lock:
            workers = list(self._workers)
        for w in workers:
            w.join(timeout=5.0)
        self._sock.close()

    def __enter__(self) -> "ControllerServer":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- connections ------------------------------------------------------------------------
    def _admit(self, conn: socket.socket, peer) -> None:
        with self._lock:
            self.connections += 1
            number = self.connections
            full = self._active >= self.limits.max_clients
            if not full:
                self._active += 1
        conn.settimeout(POLL_PERIOD)
        if full:
            with self._lock:
                self.refused += 1
            self._say(f"controller-server: connection {number} from {peer[0]}:{peer[1]} "
                      f"refused: {self.limits.max_clients} clients already served")
            try:
                conn.sendall(encode({"error": f"controller server busy: "
                                              f"{self.limits.max_clients} clients already "
                                              f"connected (max_clients); try again later"}))
            except OSError:
                pass
            conn.close()
            return
        worker = threading.Thread(target=self._serve, args=(conn, peer, number),
                                  name=f"controller-connection-{number}", daemon=True)
        with self._lock:
            self._workers.add(worker)
        worker.start()

    def _take_session(self) -> WalkingSession:
        with self._lock:
            session = self._idle_sessions.pop() if self._idle_sessions else None
        return session or WalkingSession(self.config)

    def _serve(self, conn: socket.socket, peer, number: int) -> None:
        session = None
        served, reason = 0, "closed by the client"
        self._say(f"controller-server: connection {number} from {peer[0]}:{peer[1]}")
        try:
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            session = self._take_session()
            session.reset()
            while True:
                deadline = time.monotonic() + self.limits.idle_timeout
                try:
                    payload = read_frame(conn, self._stop, deadline)
                except ProtocolError as e:  # an impossible length: cannot resynchronise
                    self._reply(conn, {"error": str(e)})
                    reason = "impossible frame length"
                    break
                if payload is None:
                    reason = "server stopped" if self._stop.is_set() else reason
                    break
                if not payload:
                    reason = "the client's exit frame"
                    break
                self._reply(conn, self._answer(session, payload))
                served += 1
        except IdleTimeout:
            reason = f"idle for {self.limits.idle_timeout:g} s"
        except (ConnectionError, OSError) as e:
            reason = f"dropped: {e}"
        finally:
            conn.close()
            with self._lock:
                self._active -= 1
                self._workers.discard(threading.current_thread())
                if session is not None:
                    self._idle_sessions.append(session)
        self._say(f"controller-server: connection {number} closed after {served} requests "
                  f"({reason})")

    def _answer(self, session: WalkingSession, payload: bytes) -> dict[str, Any]:
        try:
            return session.answer(decode(payload))
        except ProtocolError as e:
            self._count_error()
            return {"error": str(e)}
        except Exception as e:  # a controller failure: say so, keep serving
            self._count_error()
            return {"error": f"controller: {type(e).__name__}: {' '.join(str(e).split())}"}

    def _reply(self, conn: socket.socket, reply: dict[str, Any]) -> None:
        try:
            data = encode(reply)
        except (ValueError, TypeError) as e:  # e.g. a non-finite torque: say so, keep serving
            self._count_error()
            data = encode({"error": f"controller: reply not encodable: {e}"})
        conn.sendall(data)
        with self._lock:
            self.requests += 1

    def _count_error(self) -> None:
        with self._lock:
            self.errors += 1

    def _say(self, line: str) -> None:
        if self.log is not None:
            print(line, file=self.log, flush=True)

"""The original's persistent client: one connection for every message."""

from __future__ import annotations

import socket

from pr2.tcp.tcp_client import TcpClient
from pr2.tcp.utils import int2bin


class PersistentTcpClient(TcpClient):
    """Keeps one connection (opened here) and sends every message on it.

    As the original's: :meth:`close` (also on garbage collection) sends the zero-length "exit"
    message, which the server answers by closing the connection; a failed exchange (an error,
    or the server closing instead of replying) reconnects. Unlike the original's, which then
    returned the message itself, the message is sent once more on the new connection and its
    reply returned (the server starts a new episode there); a second failure raises
    ConnectionError.
    """

    def __init__(self, ip: str, port: int):
        super().__init__(ip, port)
        self.connect()

    def __del__(self):
        try:
            self.close()
        except Exception:  # interpreter shutdown: nothing left to tell the server
            pass

    def connect(self) -> None:
        """(Re)open the connection."""
        self.sock_ = self.create_connection()

    def close(self) -> None:
        """Send the "exit" message, wait for the server to close, and close."""
        sock, self.sock_ = getattr(self, "sock_", None), None
        if sock is None:
            return
        try:
            sock.settimeout(5.0)
            sock.sendall(int2bin(0))
            self.recv_all_(sock, 1)  # b"" once the server closed
        except OSError:
            pass
        sock.close()

    def send(self, data_bin: bytes) -> bytes:
        """The reply's payload to one message (b"" for the "exit" message, which closes the
        connection; the next message reconnects)."""
        if not data_bin:
            self.close()
            return b""
        for attempt in (1, 2):
            if self.sock_ is None:
                self.connect()
            try:
                self.sock_.sendall(int2bin(len(data_bin)) + data_bin)
                reply = self.recv_response_(self.sock_)
                if reply:
                    return reply
                error: Exception = ConnectionError("the server closed the connection")
            except (OSError, ConnectionError) as e:
                error = e
            self._drop()
        raise ConnectionError(f"controller server {self.ip_}:{self.port_}: exchange failed "
                              f"twice: {error}")

    def _drop(self) -> None:
        if self.sock_ is not None:
            try:
                self.sock_.close()
            except OSError:
                pass
        self.sock_ = None

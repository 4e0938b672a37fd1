"""The original's one-shot client: a new connection per message."""

from __future__ import annotations

import os
import socket
import sys
import time

from pr2.tcp.utils import bin2int, int2bin

#: The controller port the original's solvers connect to.
ORIGINAL_PORT = 8800
#: [s] between two connection attempts while the server is not up.
RETRY_PERIOD = 1.0


def server_address(ip: str, port: int) -> tuple[str, int]:
    """Where a client asking for (ip, port) connects: ``pr2-drake pr2-launch`` sends the
    original's controller port to the server it started; anything else is as asked."""
    from pr2_drake.porting.launch import CONTROLLER_ENV

    started = os.environ.get(CONTROLLER_ENV)
    if started and int(port) == ORIGINAL_PORT:
        host, _, started_port = started.rpartition(":")
        return host, int(started_port)
    return ip, int(port)


class TcpClient:
    """Sends each message on a new connection and returns the reply's payload.

    Args:
        ip, port: the server (``"0.0.0.0"``, as the original's solvers give, is this host).
    """

    def __init__(self, ip: str, port: int):
        self.ip_ = ip
        self.port_ = port
        self.sock_: socket.socket | None = None

    def send(self, data_bin: bytes) -> bytes:
        """One exchange on a new connection: the reply's payload (b"" if the server closed
        without one)."""
        sock = self.create_connection()
        try:
            sock.sendall(int2bin(len(data_bin)) + data_bin)
            return self.recv_response_(sock)
        finally:
            sock.close()

    def create_connection(self) -> socket.socket:
        """A connection to the server, trying again every second until it is up."""
        address = server_address(self.ip_, self.port_)
        waited = 0
        while True:
            try:
                sock = socket.create_connection(address)
                sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                return sock
            except OSError:
                print(f"Waiting for server {waited}s ...", end="\r", file=sys.stderr, flush=True)
                time.sleep(RETRY_PERIOD)
                waited += 1

    def recv_response_(self, sock: socket.socket) -> bytes:
        """One reply's payload; b"" when the server closed the connection first."""
        header = self.recv_all_(sock, 4)
        if len(header) < 4:
            return b""
        n = bin2int(header)
        payload = self.recv_all_(sock, n)
        if len(payload) < n:
            raise ConnectionError(f"the server closed the connection after {len(payload)} of "
                                  f"{n} bytes")
        return payload

    def recv_all_(self, sock: socket.socket, n: int) -> bytes:
        """Up to ``n`` bytes: fewer only when the server closed the connection."""
        chunks, got = [], 0
        while got < n:
            chunk = sock.recv(n - got)
            if not chunk:
                break
            chunks.append(chunk)
            got += len(chunk)
        return b"".join(chunks)

"""``pr2.tcp``: the original platform's TCP clients and framing helpers (a 4-byte big-endian
length, then the payload; JSON payloads in ASCII).

Run by ``pr2-drake pr2-launch``, a client asking for the original's controller port
(:data:`ORIGINAL_PORT`, 8800) on any host reaches the server that command started, whatever
port it listens on (see :func:`pr2.tcp.tcp_client.server_address`).
"""

from pr2.tcp.persistent_tcp_client import PersistentTcpClient
from pr2.tcp.tcp_client import ORIGINAL_PORT, TcpClient
from pr2.tcp.utils import bin2int, bin2json, int2bin, json2bin

__all__ = ["ORIGINAL_PORT", "PersistentTcpClient", "TcpClient", "bin2int", "bin2json",
           "int2bin", "json2bin"]

"""Framing and JSON helpers of the original platform's TCP protocol."""

import json
from typing import Any

from pr2_drake.framing import LENGTH


def json2bin(data: Any) -> bytes:
    """A JSON value as ASCII bytes (non-ASCII characters escaped)."""
    return json.dumps(data).encode("ascii")


def bin2json(data: bytes) -> Any:
    """The JSON value in ``data`` (bytes or str)."""
    return json.loads(data)


def int2bin(n: int) -> bytes:
    """``n`` as the 4-byte big-endian unsigned length of a frame."""
    return LENGTH.pack(n)


def bin2int(data: bytes) -> int:
    """The frame length in 4 big-endian bytes."""
    return LENGTH.unpack(data)[0]

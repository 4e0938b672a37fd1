"""Length-prefixed frames: a 4-byte big-endian byte count, then the payload.

The original platform's walking-controller protocol frames its JSON this way
(pr2_drake.porting.controller_server), and so does the competition sandbox's pipe between the
simulator and an agent (pr2_drake.compete.sandbox and .child).
"""

from __future__ import annotations

import struct

#: The byte count before every payload (unsigned 32-bit, big-endian).
LENGTH = struct.Struct(">I")


def frame(payload: bytes) -> bytes:
    """``payload`` preceded by its length."""
    return LENGTH.pack(len(payload)) + payload

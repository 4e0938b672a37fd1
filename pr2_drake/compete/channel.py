"""The channel between the harness and an agent's sandbox: frames, answers, camera memory.

Messages are frames: a 4-byte big-endian length, then the payload. The harness sends pickles
(the child trusts the harness); the child answers JSON with raw float64 arrays after it, which
the harness decodes with :func:`decode_reply` (nothing an agent wrote is unpickled or
executed; any byte string either decodes or raises :class:`ChannelError`). Camera frames
travel through a shared-memory block (:func:`camera_block`: a memfd sealed against shrinking
and growing, so an agent cannot truncate it under the harness).
"""

from __future__ import annotations

import fcntl
import json
import math
import mmap
import os
import time
from typing import Any

import numpy as np

from pr2_drake.framing import LENGTH

MAX_REPLY_BYTES = 1 << 20  # a longer answer from the agent is garbage [bytes]
CAMERA_BYTES = 64 << 20  # shared-memory block for camera frames [bytes]
SHARED_MIN_BYTES = 1 << 16  # arrays this large go through shared memory [bytes]


class ChannelError(ValueError):
    """What the agent wrote is not an answer (the message says why)."""


def camera_block() -> tuple[int, mmap.mmap]:
    """A shared-memory block for camera frames: (its file descriptor, the harness's mapping).
    Sealed: nobody can shrink, grow or reseal it (no SIGBUS in the harness)."""
    fd = os.memfd_create("pr2_camera", os.MFD_CLOEXEC | os.MFD_ALLOW_SEALING)
    try:
        os.ftruncate(fd, CAMERA_BYTES)
        fcntl.fcntl(fd, fcntl.F_ADD_SEALS,
                    fcntl.F_SEAL_SHRINK | fcntl.F_SEAL_GROW | fcntl.F_SEAL_SEAL)
        return fd, mmap.mmap(fd, CAMERA_BYTES)
    except BaseException:
        os.close(fd)
        raise


def decode_reply(payload: bytes) -> dict[str, Any]:
    """An answer of the child (see ``Child.send``): a JSON object header, float64 arrays
    after it (``{"__f8__": [offset, count]}`` in the header).

    Raises:
        ChannelError: anything else (whatever the bytes).
    """
    try:
        reply = _decode(payload)
    except ChannelError:
        raise
    except Exception as e:  # noqa: BLE001 (any byte string: never more than this error)
        raise ChannelError(f"not a framed JSON answer ({type(e).__name__})") from None
    if not isinstance(reply, dict):
        raise ChannelError("not a JSON object")
    return reply


def _decode(payload: bytes) -> Any:
    if len(payload) < 4:
        raise ChannelError("shorter than its header")
    (n,) = LENGTH.unpack_from(payload, 0)
    if n > len(payload) - 4:
        raise ChannelError("header longer than the answer")
    head = json.loads(payload[4:4 + n].decode("utf-8"))
    blob = memoryview(payload)[4 + n:]

    def arrays(x):
        if isinstance(x, dict):
            ref = x.get("__f8__")
            if ref is not None and len(x) == 1:
                if not (isinstance(ref, list) and len(ref) == 2 and all(
                        type(v) is int for v in ref)):
                    raise ChannelError("bad array reference")
                offset, count = ref
                if offset < 0 or count < 0 or offset + 8 * count > len(blob):
                    raise ChannelError("array reference outside the answer")
                return np.frombuffer(blob, "<f8", count, offset).copy()
            return {k: arrays(v) for k, v in x.items()}
        if isinstance(x, list):
            return [arrays(v) for v in x]
        return x

    return arrays(head)


def to_shared(x: Any, block: mmap.mmap, used: list[int], key: str) -> Any:
    """``x`` with every numpy array of at least :data:`SHARED_MIN_BYTES` written into
    ``block`` (after ``used[0]`` bytes) and replaced by a reference
    ``{"__shm__": (key, offset, shape, dtype)}``; dataclasses (an ``RgbdFrame``) are copied
    with their fields replaced."""
    if isinstance(x, np.ndarray) and x.nbytes >= SHARED_MIN_BYTES:
        a = np.ascontiguousarray(x)
        offset = used[0]
        if offset + a.nbytes > len(block):
            raise ValueError(f"arrays exceed the {len(block) >> 20} MiB shared block")
        block[offset:offset + a.nbytes] = memoryview(a).cast("B")
        used[0] = offset + (a.nbytes + 63) // 64 * 64
        return {"__shm__": (key, offset, a.shape, a.dtype.str)}
    if isinstance(x, dict):
        return {k: to_shared(v, block, used, f"{key}/{k}") for k, v in x.items()}
    if hasattr(x, "__dataclass_fields__") and any(
            isinstance(getattr(x, f), np.ndarray) for f in x.__dataclass_fields__):
        from dataclasses import replace

        return replace(x, **{f: to_shared(getattr(x, f), block, used, f"{key}.{f}")
                             for f in x.__dataclass_fields__})
    return x


def write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view):]


def finite_seconds(value: Any, upper: float) -> float | None:
    """``value`` as seconds if it is a finite number in [0, upper], else None."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    try:
        v = float(value)
    except OverflowError:
        return None
    return v if math.isfinite(v) and 0.0 <= v <= upper else None


class Budget:
    """What one request may use: ``seconds`` of wall clock, or, given a CPU clock, ``seconds``
    of the agent's CPU time within ``wall_cap`` seconds of wall clock."""

    def __init__(self, seconds: float, wall_cap: float | None, clock: int | None, t0: float):
        self.seconds, self.t0, self.clock = float(seconds), t0, clock
        self.wall_cap = float(wall_cap) if clock is not None and wall_cap else self.seconds
        self.cpu0 = cpu_time(clock)

    def left(self) -> float:
        """Seconds left: the smaller of the CPU budget left and the wall-clock cap left."""
        wall_left = self.wall_cap - (time.perf_counter() - self.t0)
        if self.clock is None:
            return wall_left
        cpu = cpu_time(self.clock)
        if cpu is None or self.cpu0 is None:  # the process is gone: the read sees its end
            return max(wall_left, 0.0)
        return min(self.seconds - (cpu - self.cpu0), wall_left)

    def wait(self) -> float:
        """How long to wait for the agent before looking at its budget again [s] (its CPU time
        cannot grow faster than the wall clock, so waiting what is left never overspends it
        by more than its other threads use)."""
        return max(0.0, self.left())

    def spent(self) -> str:
        """Why the request ran out, for the report."""
        wall = time.perf_counter() - self.t0
        if self.clock is None:
            return f"no answer within the budget of {self.seconds:g} s (wall clock)"
        cpu = (cpu_time(self.clock) or self.cpu0 or 0.0) - (self.cpu0 or 0.0)
        if cpu >= self.seconds:
            return (f"no answer within the budget of {self.seconds:g} s of CPU time "
                    f"({wall:.1f} s wall clock)")
        return (f"no answer within the wall-clock cap of {self.wall_cap:g} s (it used "
                f"{cpu:.2f} s of CPU time: sleeping or blocked)")


def cpu_time(clock: int | None) -> float | None:
    if clock is None:
        return None
    try:
        return time.clock_gettime(clock)
    except OSError:
        return None


def process_cpu_clock(pid: int) -> int:
    """The clock id of ``pid``'s CPU time (all its threads), or -1."""
    import ctypes

    try:
        libc = ctypes.CDLL(None, use_errno=True)
        clock = ctypes.c_int()
        if libc.clock_getcpuclockid(int(pid), ctypes.byref(clock)) != 0:
            return -1
        time.clock_gettime(clock.value)
        return clock.value
    except (OSError, AttributeError):
        return -1

"""The agent's sandboxed process and the channel to it.

The agent runs in ``python -m pr2_drake.compete.child`` started under bubblewrap where the
``bwrap`` binary works (no network, every file system read-only but a scratch folder, own PID
namespace, killed with its parent), with resource limits: data memory (``RLIMIT_DATA``), CPU
time (``RLIMIT_CPU``) and processes (a cgroup ``pids.max`` where cgroups are writable, else
``RLIMIT_NPROC``). The submission folder is copied into the scratch folder and put on the
import path.

Messages are frames: a 4-byte big-endian length, then the payload. The parent sends pickles
(the child trusts the parent); the child answers JSON only (the parent never unpickles what an
agent wrote). Camera frames travel through a shared-memory block (a memfd) instead of the pipe.
"""

from __future__ import annotations

import itertools
import json
import mmap
import os
import pickle
import resource
import select
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pr2_drake.framing import LENGTH, frame

MAX_REPLY_BYTES = 1 << 20  # a longer answer from the agent is garbage [bytes]
CAMERA_BYTES = 64 << 20  # shared-memory block for camera frames [bytes]
_PROJECT_ROOT = Path(__file__).resolve().parents[2]
_COUNTER = itertools.count()
NOBODY = 65534  # the uid an agent runs as when the harness is root and bubblewrap is missing


@dataclass
class SandboxLimits:
    """What an agent may use (YAML: the ``limits`` of a competition).

    Attributes:
        memory_mb: data memory of the agent's process [MiB] (``RLIMIT_DATA``).
        processes: processes and threads at once in the sandbox.
        cpu_seconds: CPU time of the agent's process per episode [s].
        step_seconds: budget for one action [s], charged in the agent process's CPU time:
            a busy machine that starves the agent does not use it up.
        step_wall_seconds: wall-clock cap of one action [s] (catches an agent that sleeps
            or blocks instead of computing); None: ten times ``step_seconds``.
        startup_seconds: wall-clock budget to import and build the agent [s].
        episode_seconds: wall-clock limit of an episode once the agent is built (simulation
            included) [s].
        isolation: "auto" (bubblewrap when it works), "bwrap" (required) or "none".
    """

    memory_mb: int = 4096
    processes: int = 64
    cpu_seconds: int = 3600
    step_seconds: float = 2.0
    step_wall_seconds: float | None = None
    startup_seconds: float = 120.0
    episode_seconds: float = 3600.0
    isolation: str = "auto"

    @property
    def step_wall_cap(self) -> float:
        """The wall-clock cap of one action [s]."""
        if self.step_wall_seconds is not None:
            return max(float(self.step_wall_seconds), float(self.step_seconds))
        return 10.0 * float(self.step_seconds)


class AgentFault(Exception):
    """The agent ended its episode: ``termination`` (one of the agent_* names or
    invalid_action) and a one-line ``message``."""

    def __init__(self, termination: str, message: str):
        super().__init__(message)
        self.termination = termination
        self.message = message


_BWRAP_OK: bool | None = None


def bwrap_available() -> bool:
    """Whether bubblewrap can start a sandbox here (checked once per process)."""
    global _BWRAP_OK
    if _BWRAP_OK is None:
        exe = shutil.which("bwrap")
        _BWRAP_OK = False
        if exe:
            try:
                r = subprocess.run([exe, "--ro-bind", "/", "/", "--dev", "/dev", "--proc", "/proc",
                                    "--unshare-all", "--die-with-parent", "true"],
                                   capture_output=True, timeout=20)
                _BWRAP_OK = r.returncode == 0
            except (OSError, subprocess.TimeoutExpired):
                _BWRAP_OK = False
    return _BWRAP_OK


def _pids_cgroup_root() -> Path | None:
    """A writable cgroup (v1 pids controller or v2) to cap the sandbox's processes."""
    for root in (Path("/sys/fs/cgroup/pids"), Path("/sys/fs/cgroup")):
        if (root / "cgroup.procs").exists() and os.access(root, os.W_OK):
            if root.name == "pids" or "pids" in _read(root / "cgroup.subtree_control"):
                return root
    return None


def _read(p: Path) -> str:
    try:
        return p.read_text()
    except OSError:
        return ""


class AgentProcess:
    """One agent in its sandbox, for one episode.

    Args:
        submission: the submission folder (copied into the scratch folder, on the import path),
            or None for built-in agents only.
        limits: the resource limits.
        hide: folders the agent must not see (other submissions, the results).
    """

    def __init__(self, submission: Path | None, limits: SandboxLimits,
                 hide: tuple[Path, ...] = ()):
        self.limits = limits
        self.submission = None if submission is None else Path(submission).resolve()
        self.hide = tuple(Path(h).resolve() for h in hide)
        self.proc: subprocess.Popen | None = None
        self.isolated = False
        self.scratch: Path | None = None
        self._cgroup: Path | None = None
        self._cam_fd = -1
        self._cam: mmap.mmap | None = None
        self._clock: int | None = None

    # -- lifetime -----------------------------------------------------------------------------
    def start(self) -> None:
        limits = self.limits
        if limits.isolation not in ("auto", "bwrap", "none"):
            raise ValueError(f"limits.isolation must be auto, bwrap or none, got "
                             f"{limits.isolation!r}")
        use_bwrap = limits.isolation != "none" and bwrap_available()
        if limits.isolation == "bwrap" and not use_bwrap:
            raise RuntimeError("limits.isolation is 'bwrap' but bubblewrap does not work here "
                               "(apt-get install bubblewrap)")
        self.scratch = Path(tempfile.mkdtemp(prefix="pr2_agent_"))
        work = self.scratch / "work"
        work.mkdir()
        sub_inside = ""
        if self.submission is not None:
            shutil.copytree(self.submission, self.scratch / "submission", symlinks=False,
                            ignore=shutil.ignore_patterns("__pycache__", ".git"))
        to_child_r, to_child_w = os.pipe()
        from_child_r, from_child_w = os.pipe()
        self._cam_fd = os.memfd_create("pr2_camera")
        os.ftruncate(self._cam_fd, CAMERA_BYTES)
        self._cam = mmap.mmap(self._cam_fd, CAMERA_BYTES)
        fds = (to_child_r, from_child_w, self._cam_fd)
        inner = "/tmp/sandbox" if use_bwrap else str(self.scratch)
        if self.submission is not None:
            sub_inside = f"{inner}/submission"
        pythonpath = os.pathsep.join(p for p in (sub_inside, str(_PROJECT_ROOT)) if p)
        child = [sys.executable, "-B", "-m", "pr2_drake.compete.child",
                 *map(str, fds), f"{inner}/work"]
        env = {"PATH": os.environ.get("PATH", "/usr/bin:/bin"), "PYTHONPATH": pythonpath,
               "HOME": f"{inner}/work", "TMPDIR": f"{inner}/work", "PYTHONUNBUFFERED": "1",
               "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
               "PR2_DRAKE_SANDBOX": "1"}
        if use_bwrap:
            argv = ["bwrap", "--ro-bind", "/", "/", "--dev", "/dev", "--proc", "/proc",
                    "--tmpfs", "/tmp", "--tmpfs", "/dev/shm"]
            # The project and its Python may themselves live under /tmp (a CI clone): bind
            # them back, read-only, over the empty /tmp.
            for keep in sorted({_PROJECT_ROOT, Path(sys.prefix), Path(sys.base_prefix)}):
                if any(_contains(Path(t), (keep,)) for t in ("/tmp", "/dev/shm")):
                    argv += ["--ro-bind", str(keep), str(keep)]
            for h in self.hide:
                if h.is_dir() and not _contains(h, (_PROJECT_ROOT, Path(sys.prefix),
                                                    Path(sys.base_prefix))):
                    argv += ["--tmpfs", str(h)]
            cwd = f"{inner}/submission" if self.submission is not None else f"{inner}/work"
            argv += ["--bind", str(self.scratch), inner, "--chdir", cwd,
                     "--unshare-all", "--uid", "65534", "--gid", "65534", "--die-with-parent",
                     "--new-session", "--", *child]
        else:
            argv = child
        self._cgroup = self._make_cgroup()
        self._drop_to = None
        if not use_bwrap and os.getuid() == 0 and _usable_by_others():
            self._drop_to = NOBODY
            for p in (self.scratch, *self.scratch.rglob("*")):
                os.chown(p, NOBODY, NOBODY)
        log = open(self.scratch / "agent.log", "wb")
        try:
            self.proc = subprocess.Popen(
                argv, pass_fds=fds, env=env,
                cwd=str(self.scratch / "submission" if self.submission is not None else work),
                stdin=subprocess.DEVNULL,
                stdout=log, stderr=subprocess.STDOUT, start_new_session=True,
                preexec_fn=self._limit_child)
        finally:
            log.close()
            os.close(to_child_r)
            os.close(from_child_w)
        self.isolated = use_bwrap
        self._w, self._r = to_child_w, from_child_r

    def _make_cgroup(self) -> Path | None:
        root = _pids_cgroup_root()
        if root is None:
            return None
        group = root / f"pr2_agent_{os.getpid()}_{next(_COUNTER)}"
        try:
            group.mkdir()
            (group / "pids.max").write_text(str(self.limits.processes))
            return group
        except OSError:
            return None

    def _limit_child(self) -> None:
        """Runs in the child between fork and exec."""
        mem = int(self.limits.memory_mb) << 20
        resource.setrlimit(resource.RLIMIT_DATA, (mem, mem))
        cpu = int(self.limits.cpu_seconds)
        resource.setrlimit(resource.RLIMIT_CPU, (cpu, cpu + 5))
        resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
        if self._cgroup is not None:
            with open(self._cgroup / "cgroup.procs", "w") as f:
                f.write(str(os.getpid()))
        elif os.getuid() != 0:
            n = self.limits.processes + _count_own_processes()
            resource.setrlimit(resource.RLIMIT_NPROC, (n, n))
        if self._drop_to is not None:  # root without bubblewrap: run as nobody
            os.setgroups([])
            os.setgid(self._drop_to)
            os.setuid(self._drop_to)
            if self._cgroup is None:
                resource.setrlimit(resource.RLIMIT_NPROC,
                                   (self.limits.processes, self.limits.processes))

    def close(self) -> None:
        """Kill the sandbox (SIGKILL: an agent ignoring SIGTERM goes too) and clean up."""
        if self.proc is not None:
            if self.proc.poll() is None:
                try:
                    os.killpg(self.proc.pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                pass
        self._kill_cgroup()
        for fd in ("_w", "_r"):
            if getattr(self, fd, -1) >= 0:
                os.close(getattr(self, fd))
                setattr(self, fd, -1)
        if self._cam is not None:
            self._cam.close()
            os.close(self._cam_fd)
            self._cam = None
        if self.scratch is not None:
            shutil.rmtree(self.scratch, ignore_errors=True)
            self.scratch = None

    def _kill_cgroup(self) -> None:
        group = self._cgroup
        if group is None:
            return
        for _ in range(50):  # a fork bomb may still be forking: repeat until empty
            pids = [int(p) for p in _read(group / "cgroup.procs").split()]
            if not pids:
                break
            for pid in pids:
                try:
                    os.kill(pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
            time.sleep(0.02)
        try:
            group.rmdir()
        except OSError:
            pass
        self._cgroup = None

    def log_tail(self, n: int = 4000) -> str:
        """The end of the agent's stdout and stderr."""
        if self.scratch is None:
            return ""
        p = self.scratch / "agent.log"
        try:
            with open(p, "rb") as f:
                f.seek(max(0, p.stat().st_size - n))
                return f.read().decode("utf-8", "replace")
        except OSError:
            return ""

    # -- messages -----------------------------------------------------------------------------
    def request(self, message: dict[str, Any], timeout: float, *,
                wall_cap: float | None = None) -> tuple[dict[str, Any], float]:
        """Send ``message`` and wait for the answer.

        Args:
            message: what the agent gets.
            timeout: the budget [s]: wall clock, or, with ``wall_cap``, the agent process's
                CPU time (so that a machine busy with other work does not use it up).
            wall_cap: the wall-clock cap [s] when ``timeout`` is CPU time (an agent that
                sleeps or blocks uses no CPU).
        Returns:
            (the answer, the round trip [s]).
        Raises:
            AgentFault: the agent hung, died, wrote garbage, raised or exited.
        """
        t0 = time.perf_counter()
        budget = _Budget(timeout, wall_cap, self._cpu_clock() if wall_cap else None, t0)
        data = pickle.dumps(self._pack_camera(message), protocol=pickle.HIGHEST_PROTOCOL)
        try:
            _write_all(self._w, frame(data))
        except (BrokenPipeError, OSError):
            raise self._death() from None
        header = self._read_exact(4, budget)
        (n,) = LENGTH.unpack(header)
        if n > MAX_REPLY_BYTES:
            raise AgentFault("agent_error", f"garbage on the agent channel: a {n}-byte answer")
        payload = self._read_exact(n, budget)
        rtt = time.perf_counter() - t0
        try:
            reply = decode_reply(payload)
        except (UnicodeDecodeError, ValueError, struct.error, RecursionError, TypeError):
            raise AgentFault("agent_error", "garbage on the agent channel: not a framed JSON "
                                            "answer") from None
        if not isinstance(reply, dict):
            raise AgentFault("agent_error", "garbage on the agent channel: not a JSON object")
        if "error" in reply:
            kind = str(reply.get("type", ""))
            text = " ".join(str(reply["error"]).split())[:500]
            raise AgentFault("agent_memory" if kind == "MemoryError" else "agent_error", text)
        if "forbidden" in reply:
            raise AgentFault("agent_error", "forbidden call: " + " ".join(
                str(reply["forbidden"]).split())[:500])
        if "exit" in reply:
            raise AgentFault("agent_exit", f"the agent called sys.exit({reply['exit']!r})")
        if "invalid" in reply:
            raise AgentFault("invalid_action", " ".join(str(reply["invalid"]).split())[:500])
        return reply, rtt

    def _cpu_clock(self) -> int | None:
        """The CPU-time clock of the agent's Python process (found once, inside bubblewrap's
        namespaces too), or None where the kernel does not give one."""
        if self._clock is None and self.proc is not None:
            pid = _agent_pid(self.proc.pid)
            self._clock = -1 if pid is None else _process_cpu_clock(pid)
        return None if self._clock in (None, -1) else self._clock

    def _pack_camera(self, message: dict[str, Any]) -> dict[str, Any]:
        """Move the large arrays of a message (camera frames) into the shared-memory block;
        the message carries references (see :func:`to_shared`)."""
        used = [0]
        return to_shared(message, self._cam, used, "")

    def _read_exact(self, n: int, budget: "_Budget") -> bytes:
        out = bytearray()
        while len(out) < n:
            ready, _, _ = select.select([self._r], [], [], budget.wait())
            if not ready:
                if budget.left() > 0.0:
                    continue  # starved by a busy machine, not out of budget
                self._terminate()
                raise AgentFault("agent_timeout", budget.spent())
            chunk = os.read(self._r, n - len(out))
            if not chunk:
                raise self._death()
            out += chunk
        return bytes(out)

    def _terminate(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            try:
                os.killpg(self.proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass

    def _death(self) -> AgentFault:
        """Name how the agent's process ended (it closed the channel)."""
        try:
            code = self.proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            self._terminate()
            return AgentFault("agent_exit", "the agent closed its channel")
        log = self.log_tail()
        if code in (-signal.SIGXCPU, 128 + signal.SIGXCPU) or "SIGXCPU" in log:
            return AgentFault("agent_timeout", f"CPU time limit of {self.limits.cpu_seconds} s")
        if any(s in log for s in ("MemoryError", "Cannot allocate memory", "bad_alloc",
                                  "out of memory")):
            return AgentFault("agent_memory",
                              f"the agent ran out of its {self.limits.memory_mb} MiB of memory")
        if code is not None and code < 0:
            return AgentFault("agent_exit",
                              f"the agent process died of signal {signal.Signals(-code).name}")
        return AgentFault("agent_exit", f"the agent process exited with code {code}")


class _Budget:
    """What one request may use: ``seconds`` of wall clock, or, given a CPU clock, ``seconds``
    of the agent's CPU time within ``wall_cap`` seconds of wall clock."""

    def __init__(self, seconds: float, wall_cap: float | None, clock: int | None, t0: float):
        self.seconds, self.t0, self.clock = float(seconds), t0, clock
        self.wall_cap = float(wall_cap) if clock is not None and wall_cap else self.seconds
        self.cpu0 = _cpu_time(clock)

    def left(self) -> float:
        """Seconds left: the smaller of the CPU budget left and the wall-clock cap left."""
        wall_left = self.wall_cap - (time.perf_counter() - self.t0)
        if self.clock is None:
            return wall_left
        cpu = _cpu_time(self.clock)
        if cpu is None:  # the process is gone: the read sees its end next
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
        cpu = (_cpu_time(self.clock) or self.cpu0) - self.cpu0
        if cpu >= self.seconds:
            return (f"no answer within the budget of {self.seconds:g} s of CPU time "
                    f"({wall:.1f} s wall clock)")
        return (f"no answer within the wall-clock cap of {self.wall_cap:g} s (it used "
                f"{cpu:.2f} s of CPU time: sleeping or blocked)")


def _cpu_time(clock: int | None) -> float | None:
    if clock is None:
        return None
    try:
        return time.clock_gettime(clock)
    except OSError:
        return None


def _agent_pid(root: int) -> int | None:
    """The agent's Python process among ``root`` and its descendants (bubblewrap runs it as a
    grandchild), by its command line."""
    stack, found = [root], None
    while stack:
        pid = stack.pop()
        if b"pr2_drake.compete.child" in _read_bytes(f"/proc/{pid}/cmdline") and \
                not _read_bytes(f"/proc/{pid}/cmdline").startswith(b"bwrap"):
            found = pid
        try:
            tasks = os.listdir(f"/proc/{pid}/task")
        except OSError:
            continue
        for t in tasks:
            stack += [int(c) for c in _read_bytes(f"/proc/{pid}/task/{t}/children").split()]
    return found


def _read_bytes(path: str) -> bytes:
    try:
        with open(path, "rb") as f:
            return f.read()
    except OSError:
        return b""


def _process_cpu_clock(pid: int) -> int:
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


def decode_reply(payload: bytes) -> Any:
    """An answer of the child (see ``Child.send``): JSON header, float64 arrays after it.
    Raises ValueError (or struct.error) on anything else; nothing in it is executed."""
    (n,) = LENGTH.unpack_from(payload, 0)
    if n > len(payload) - 4:
        raise ValueError("header longer than the answer")
    head = json.loads(payload[4:4 + n].decode("utf-8"))
    blob = memoryview(payload)[4 + n:]

    def arrays(x):
        if isinstance(x, dict):
            ref = x.get("__f8__")
            if ref is not None and len(x) == 1:
                offset, count = (int(v) for v in ref)
                if offset < 0 or count < 0 or offset + 8 * count > len(blob):
                    raise ValueError("array reference outside the answer")
                return np.frombuffer(blob, "<f8", count, offset).copy()
            return {k: arrays(v) for k, v in x.items()}
        if isinstance(x, list):
            return [arrays(v) for v in x]
        return x

    return arrays(head)


SHARED_MIN_BYTES = 1 << 16  # arrays this large go through shared memory [bytes]


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


def _usable_by_others() -> bool:
    """Whether another user can run this Python and read the project (every folder on the
    way searchable by others)."""
    for path in (Path(sys.executable).resolve(), Path(sys.prefix).resolve(), _PROJECT_ROOT):
        for p in (path, *path.parents):
            try:
                mode = p.stat().st_mode
            except OSError:
                return False
            if p.is_dir() and not mode & 0o001:
                return False
    return True


def isolation_note(limits: "SandboxLimits") -> str:
    """One line saying how agents are isolated here."""
    if limits.isolation != "none" and bwrap_available():
        return ("sandbox: bubblewrap (no network, read-only file system but a scratch folder, "
                "own PID namespace) + resource limits + timeouts")
    who = ("as user nobody" if os.getuid() == 0 and _usable_by_others() else
           "as the harness's user")
    return (f"sandbox: bubblewrap not available (apt-get install bubblewrap); falling back to "
            f"resource limits (memory, CPU time, processes), timeouts and audit hooks, {who}")


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view):]


def _contains(folder: Path, paths) -> bool:
    return any(p == folder or folder in p.parents for p in paths)


def _count_own_processes() -> int:
    uid = os.getuid()
    n = 0
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                if d.stat().st_uid == uid:
                    n += 1
            except OSError:
                pass
    return n

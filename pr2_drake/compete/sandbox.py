"""The agent's sandboxed process, for one episode, and the requests the harness sends it.

The agent runs in ``python -m pr2_drake.compete.child`` isolated as
:mod:`pr2_drake.compete.isolation` says (bubblewrap, else util-linux ``unshare``; never as
root), in a control group of its own where the machine allows (:mod:`.cgroups`: all its
memory, its processes), with resource limits (CPU time, file size, and address space or
processes where no group holds them). Its submission folder is bound read-only into the
sandbox, after a check that no symbolic link in it leads out of it. Its output goes to a file
the harness holds open and the agent cannot name. The channel (:mod:`.channel`) carries
frames both ways and camera frames through a sealed memfd.
"""

from __future__ import annotations

import ctypes
import os
import pickle
import resource
import select
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from pr2_drake.compete import isolation
from pr2_drake.compete.cgroups import AgentCgroup
from pr2_drake.compete.jail import JAIL_FAILED
from pr2_drake.compete.channel import (
    MAX_REPLY_BYTES,
    Budget,
    ChannelError,
    camera_block,
    decode_reply,
    process_cpu_clock,
    to_shared,
    write_all,
)
from pr2_drake.compete.limits import AgentFault, SandboxLimits
from pr2_drake.compete.submission import check_submission
from pr2_drake.framing import LENGTH, frame

LOG_BYTES = 4000  # the end of the agent's output kept for its report [bytes]
# Settings of the linear-algebra libraries the agent's process keeps from the harness's
# environment (OPENBLAS_CORETYPE picks OpenBLAS's kernels, whose roundings differ): the agent
# computes as it would in process.
NUMERIC_ENV = ("OPENBLAS_", "MKL_", "NPY_", "BLIS_", "GOTO_", "NVPL_")
AS_HEADROOM = 4 << 30
MEMORY_CHECK = 0.5  # while waiting for an answer, look this often whether the agent is stuck
# at its memory limit [s]  # address space beyond twice the memory limit, with a memory group [B]
_SANDBOXES = "pr2_drake_sandboxes"  # parent of every agent's scratch folder (hidden in each)
_LIBC = ctypes.CDLL(None)  # loaded here: nothing is imported between fork and exec
PR_SET_PDEATHSIG = 1


class AgentProcess:
    """One agent in its sandbox, for one episode.

    Args:
        submission: the submission folder (bound read-only into the sandbox, its cwd and on
            its import path), or None for built-in agents only.
        limits: the resource limits and the isolation.
        hide: folders the agent must not see (other submissions, the results).
    """

    def __init__(self, submission: Path | None, limits: SandboxLimits,
                 hide: tuple[Path, ...] = ()):
        self.limits = limits
        self.submission = None if submission is None else Path(os.path.abspath(submission))
        self.hide = tuple(Path(os.path.abspath(h)) for h in hide)
        self.proc: subprocess.Popen | None = None
        self.kind = isolation.choose(limits.isolation, limits.trust)
        self.scratch: Path | None = None
        self.cgroup: AgentCgroup | None = None
        self._log: Any = None
        self._w = self._r = self._cam_fd = -1
        self._cam = None
        self._clock: int | None = None

    @property
    def isolated(self) -> bool:
        return self.kind != "none"

    # -- lifetime -----------------------------------------------------------------------------
    def start(self) -> None:
        """Start the sandbox. Raises AgentFault when the submission is refused."""
        if self.submission is not None:
            problem = check_submission(self.submission, foreign_uid=self.isolated
                                       and os.getuid() == 0)
            if problem:
                raise AgentFault("agent_error", f"submission refused: {problem}")
        parent = Path(tempfile.gettempdir()) / _SANDBOXES
        parent.mkdir(mode=0o711, exist_ok=True)
        self.scratch = Path(tempfile.mkdtemp(prefix="agent_", dir=parent))
        to_child_r, to_child_w = os.pipe()
        from_child_r, from_child_w = os.pipe()
        self._cam_fd, self._cam = camera_block()
        fds = (to_child_r, from_child_w, self._cam_fd)
        self.cgroup = AgentCgroup(self.limits.memory_bytes, self.limits.processes)
        self._child_rlimits = self._rlimits()
        argv, env, cwd = self._command(fds, parent)
        self._log = tempfile.TemporaryFile(prefix="pr2_agent_log_")  # unlinked: unnamed
        try:
            self.proc = subprocess.Popen(argv, pass_fds=fds, env=env, cwd=cwd,
                                         stdin=subprocess.DEVNULL, stdout=self._log,
                                         stderr=subprocess.STDOUT, start_new_session=True,
                                         preexec_fn=self._in_child_before_exec)
        finally:
            os.close(to_child_r)
            os.close(from_child_w)
        self._w, self._r = to_child_w, from_child_r

    def _command(self, fds, parent: Path) -> tuple[list[str], dict[str, str], str]:
        """The command line, environment and working folder of the sandbox."""
        inside = isolation.INSIDE if self.isolated else str(self.scratch)
        sub = (f"{inside}/submission" if self.isolated else str(self.submission)) \
            if self.submission is not None else ""
        work = f"{inside}/work"
        if not self.isolated:
            os.mkdir(work)
        child = [sys.executable, "-B", "-m", "pr2_drake.compete.child", *map(str, fds), work]
        env = {"PATH": os.environ.get("PATH", "/usr/bin:/bin"), "HOME": work, "TMPDIR": work,
               "PYTHONPATH": os.pathsep.join(p for p in (sub, str(isolation.PROJECT_ROOT)) if p),
               "PYTHONUNBUFFERED": "1", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
               "MKL_NUM_THREADS": "1", "PR2_DRAKE_SANDBOX": "1"}
        env.update({k: v for k, v in os.environ.items()  # the same linear-algebra kernels
                    if k.startswith(NUMERIC_ENV) and not k.endswith("_NUM_THREADS")})
        cwd = sub or work
        if not self.isolated:
            return child, env, cwd
        plan = isolation.mount_plan(self.submission, (*self.hide, parent),
                                    self.limits.memory_bytes)
        root = self.scratch / "root"
        root.mkdir()
        argv = isolation.command(self.kind, child, plan=plan, root=root,
                                 uid=isolation.agent_uid(), rlimits=self._child_rlimits, cwd=cwd)
        return argv, env, "/"

    def _rlimits(self) -> dict[str, int]:
        """The agent process's resource limits (what no control group holds here)."""
        lim = self.limits
        out = {"RLIMIT_CPU": int(lim.cpu_seconds), "RLIMIT_CORE": 0,
               "RLIMIT_FSIZE": lim.memory_bytes}
        # The address space: the limit itself without a memory group; with one (which
        # counts what is used), a guard that refuses absurd reservations at once.
        out["RLIMIT_AS"] = lim.memory_bytes if not self.cgroup.limits_memory else \
            2 * lim.memory_bytes + AS_HEADROOM
        if not self.cgroup.limits_processes:
            own = 0 if os.getuid() == 0 else _count_own_processes()
            out["RLIMIT_NPROC"] = int(lim.processes) + own
        return out

    def _in_child_before_exec(self) -> None:
        """Runs in the forked child before exec: the control group, and for the unisolated
        set-up the resource limits (the isolated ones get theirs after dropping privileges)."""
        _LIBC.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
        self.cgroup.attach()
        if not self.isolated:
            for name, value in self._child_rlimits.items():
                resource.setrlimit(getattr(resource, name), (value, value))

    def close(self) -> None:
        """Kill the sandbox (SIGKILL: an agent ignoring SIGTERM goes too; its PID 1 takes
        every process in the namespace with it), wait until they are gone, clean up."""
        namespace = self._namespace()
        self._terminate()
        if self.proc is not None:
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                pass
        if self.cgroup is not None:
            self.cgroup.kill()
        if namespace:
            _wait_until_empty(namespace)
        for name in ("_w", "_r", "_cam_fd"):
            if getattr(self, name) >= 0:
                os.close(getattr(self, name))
                setattr(self, name, -1)
        if self._cam is not None:
            self._cam.close()
            self._cam = None
        if self._log is not None:
            self._log.close()
            self._log = None
        if self.scratch is not None:
            shutil.rmtree(self.scratch, ignore_errors=True)
            self.scratch = None

    def _namespace(self) -> str:
        """The sandbox's PID namespace ("" unisolated, or when it is gone already)."""
        if not self.isolated or self.proc is None:
            return ""
        pid = _sandbox_pid(self.proc.pid, 1)
        return _read_link(f"/proc/{pid}/ns/pid") if pid is not None else ""

    def log_tail(self, n: int = LOG_BYTES) -> str:
        """The end of the agent's stdout and stderr."""
        if self._log is None:
            return ""
        try:
            size = os.fstat(self._log.fileno()).st_size
            return os.pread(self._log.fileno(), n, max(0, size - n)).decode("utf-8", "replace")
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
        budget = Budget(timeout, wall_cap, self._cpu_clock() if wall_cap else None, t0)
        data = pickle.dumps(to_shared(message, self._cam, [0], ""),
                            protocol=pickle.HIGHEST_PROTOCOL)
        try:
            write_all(self._w, frame(data))
        except OSError:
            raise self._death() from None
        (n,) = LENGTH.unpack(self._read_exact(4, budget))
        if n > MAX_REPLY_BYTES:
            raise AgentFault("agent_error", f"garbage on the agent channel: a {n}-byte answer")
        payload = self._read_exact(n, budget)
        rtt = time.perf_counter() - t0
        try:
            reply = decode_reply(payload)
        except ChannelError as e:
            raise AgentFault("agent_error", f"garbage on the agent channel: {e}") from None
        _raise_reported_fault(reply)
        return reply, rtt

    def _cpu_clock(self) -> int | None:
        """The CPU-time clock of the agent's Python process, or None where the kernel does
        not give one (found once: PID 2 of the sandbox, or the child itself unisolated)."""
        if self._clock is None and self.proc is not None:
            pid = self.proc.pid if not self.isolated else _sandbox_pid(self.proc.pid, 2)
            self._clock = -1 if pid is None else process_cpu_clock(pid)
        return None if self._clock in (None, -1) else self._clock

    def _read_exact(self, n: int, budget: Budget) -> bytes:
        out = bytearray()
        while len(out) < n:
            ready, _, _ = select.select([self._r], [], [], min(budget.wait(), MEMORY_CHECK))
            if not ready:
                if self.cgroup is not None and self.cgroup.stuck_at_limit():
                    self._terminate()  # waiting in the kernel for memory it cannot have
                    raise AgentFault("agent_memory", self._over_memory())
                if budget.left() > 0.0:
                    continue  # starved by a busy machine, not out of budget
                self._terminate()
                if self.cgroup is not None and self.cgroup.hit_limit():
                    raise AgentFault("agent_memory", self._over_memory())
                raise AgentFault("agent_timeout", budget.spent())
            chunk = os.read(self._r, n - len(out))
            if not chunk:
                raise self._death()
            out += chunk
        return bytes(out)

    def _over_memory(self) -> str:
        return f"the agent exceeded its memory limit of {self.limits.memory_mb} MiB (killed)"

    def _terminate(self) -> None:
        """SIGKILL the sandbox: its PID 1 first (the kernel then kills the whole namespace,
        and bubblewrap or unshare, seeing it end, exits and reaps it: no orphan left),
        then the process group of what the harness started."""
        if self.proc is None or self.proc.poll() is not None:
            return
        init = _sandbox_pid(self.proc.pid, 1) if self.isolated else None
        if init is not None:
            try:
                os.kill(init, signal.SIGKILL)
                self.proc.wait(timeout=2)
            except (ProcessLookupError, subprocess.TimeoutExpired):
                pass
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
            code = None
        if self.cgroup is not None and self.cgroup.oom_killed():
            return AgentFault("agent_memory", self._over_memory())
        log = self.log_tail()
        if code == JAIL_FAILED and "sandbox: " in log:
            line = log[log.rindex("sandbox: "):].splitlines()[0]
            return AgentFault("agent_error", f"the sandbox could not start: {line[:500]}")
        signum = -code if code is not None and code < 0 else (
            code - 128 if code is not None and self.isolated and 128 < code < 160 else None)
        if signum == signal.SIGXCPU or "SIGXCPU" in log:
            return AgentFault("agent_timeout", f"CPU time limit of {self.limits.cpu_seconds} s")
        if any(s in log for s in ("MemoryError", "Cannot allocate memory", "bad_alloc",
                                  "out of memory")):
            return AgentFault("agent_memory",
                              f"the agent ran out of its {self.limits.memory_mb} MiB of memory")
        if code is None:
            return AgentFault("agent_exit", "the agent closed its channel")
        if signum is not None:
            return AgentFault("agent_exit",
                              f"the agent process died of signal {_signal_name(signum)}")
        return AgentFault("agent_exit", f"the agent process exited with code {code}")


def _raise_reported_fault(reply: dict[str, Any]) -> None:
    """The child's report of the agent's own fault, as an AgentFault."""
    def text(key):
        return " ".join(str(reply[key]).split())[:500]

    if "error" in reply:
        kind = str(reply.get("type", ""))
        raise AgentFault("agent_memory" if kind == "MemoryError" else "agent_error", text("error"))
    if "forbidden" in reply:
        raise AgentFault("agent_error", "forbidden call: " + text("forbidden"))
    if "exit" in reply:
        raise AgentFault("agent_exit", f"the agent called sys.exit({text('exit')})")
    if "invalid" in reply:
        raise AgentFault("invalid_action", text("invalid"))


def _signal_name(signum: int) -> str:
    try:
        return signal.Signals(signum).name
    except ValueError:
        return str(signum)


def _sandbox_pid(root: int, inner: int) -> int | None:
    """The process among ``root``'s descendants that is PID ``inner`` in its own PID
    namespace (the agent's Python is PID 2 in both isolated set-ups)."""
    stack = [root]
    while stack:
        pid = stack.pop()
        status = _read_text(f"/proc/{pid}/status")
        for line in status.splitlines():
            if line.startswith("NSpid:"):
                ids = line.split()[1:]
                if len(ids) > 1 and ids[-1] == str(inner):
                    return pid
        try:
            tasks = os.listdir(f"/proc/{pid}/task")
        except OSError:
            continue
        for t in tasks:
            stack += [int(c) for c in _read_text(f"/proc/{pid}/task/{t}/children").split()]
    return None


def _wait_until_empty(namespace: str, timeout: float = 5.0) -> None:
    """Wait until no process is left running in the PID namespace ``namespace`` (killed when
    its PID 1 died, they may take a moment to go; a zombie holds nothing)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if not any(_read_link(f"/proc/{p}/ns/pid") == namespace and _state(p) != "Z"
                   for p in os.listdir("/proc") if p.isdigit()):
            return
        time.sleep(0.02)


def _state(pid: str) -> str:
    """A process's state letter (R, S, Z...), "" when it is gone."""
    stat = _read_text(f"/proc/{pid}/stat")
    return stat.rpartition(")")[2].split()[0] if ")" in stat else ""


def _read_link(path: str) -> str:
    try:
        return os.readlink(path)
    except OSError:
        return ""


def _read_text(path: str) -> str:
    try:
        with open(path) as f:
            return f.read()
    except OSError:
        return ""


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


def isolation_note(limits: SandboxLimits) -> str:
    """One line saying how agents are isolated here (raises IsolationUnavailable where they
    cannot be and ``limits.trust`` is off)."""
    return isolation.describe(isolation.choose(limits.isolation, limits.trust))


def bwrap_available() -> bool:
    """Whether bubblewrap isolates agents here."""
    return isolation.works("bwrap")

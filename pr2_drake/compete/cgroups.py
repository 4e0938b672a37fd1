"""A control group per agent: its memory (all of it: heap, shared memory, tmpfs files) and its
number of processes, where this machine lets the harness make one.

cgroup v2 (``memory.max``, ``memory.swap.max``, ``pids.max``, ``cgroup.kill``) where the
harness's own group delegates the controllers; else cgroup v1 (``memory.limit_in_bytes``,
``memory.memsw.limit_in_bytes``, ``pids.max``) under the harness's own group in each
hierarchy. A group goes under the harness's own, so the limits the machine puts on the harness
still hold. Where no writable group exists (or ``PR2_DRAKE_NO_CGROUPS=1``, for the tests),
:class:`AgentCgroup` holds nothing and the sandbox falls back to ``RLIMIT_AS`` (memory) and
``RLIMIT_NPROC`` (processes).
"""

from __future__ import annotations

import itertools
import os
import signal
import time
from functools import lru_cache
from pathlib import Path

_COUNTER = itertools.count()


def _read(p: Path) -> str:
    try:
        return p.read_text()
    except OSError:
        return ""


@lru_cache(maxsize=1)
def _own_groups() -> dict[str, Path]:
    """Writable folders of this process's own cgroups, by controller ("memory", "pids")."""
    mounts: dict[str, Path] = {}
    v2: Path | None = None
    for line in _read(Path("/proc/self/mountinfo")).splitlines():
        fields = line.split()
        sep = fields.index("-")
        fstype, opts = fields[sep + 1], fields[sep + 3].split(",")
        if fstype == "cgroup2":
            v2 = Path(fields[4])
        elif fstype == "cgroup":
            for c in ("memory", "pids"):
                if c in opts:
                    mounts[c] = Path(fields[4])
    found: dict[str, Path] = {}
    for line in _read(Path("/proc/self/cgroup")).splitlines():
        num, controllers, path = line.split(":", 2)
        rel = path.lstrip("/")
        if num == "0" and v2 is not None:
            own = v2 / rel
            enabled = _read(own / "cgroup.subtree_control").split()
            for c in ("memory", "pids"):
                if c in enabled and os.access(own, os.W_OK):
                    found.setdefault(c, own)
        for c in controllers.split(","):
            if c in mounts and os.access(mounts[c] / rel, os.W_OK):
                found.setdefault(c, mounts[c] / rel)
    return found


NO_CGROUPS_ENV = "PR2_DRAKE_NO_CGROUPS"  # "1": behave as if no group were writable (tests)


def _usable_groups() -> dict[str, Path]:
    return {} if os.environ.get(NO_CGROUPS_ENV) == "1" else _own_groups()


def available() -> tuple[str, ...]:
    """The controllers the harness can limit an agent with here ("memory", "pids")."""
    return tuple(sorted(_usable_groups()))


class AgentCgroup:
    """The agent's groups (one per hierarchy) with its limits; empty where none is writable.

    Args:
        memory_bytes: the memory limit [bytes] (no swap beyond it).
        processes: processes and threads at once.
    """

    def __init__(self, memory_bytes: int, processes: int):
        self.groups: dict[str, Path] = {}
        name = f"pr2_agent_{os.getpid()}_{next(_COUNTER)}"
        for controller, parent in _usable_groups().items():
            group = parent / name
            try:
                group.mkdir(exist_ok=True)
                if controller == "memory":
                    self._limit_memory(group, memory_bytes)
                else:
                    (group / "pids.max").write_text(str(int(processes)))
                self.groups[controller] = group
            except OSError:
                _remove(group)

    @staticmethod
    def _limit_memory(group: Path, memory_bytes: int) -> None:
        if (group / "memory.max").exists():  # v2
            (group / "memory.max").write_text(str(memory_bytes))
            for name, value in (("memory.swap.max", "0"), ("memory.oom.group", "1")):
                if (group / name).exists():
                    (group / name).write_text(value)
        else:  # v1
            (group / "memory.limit_in_bytes").write_text(str(memory_bytes))
            if (group / "memory.memsw.limit_in_bytes").exists():
                try:
                    (group / "memory.memsw.limit_in_bytes").write_text(str(memory_bytes))
                except OSError:
                    pass  # swap accounting off: no swap to limit

    @property
    def limits_memory(self) -> bool:
        return "memory" in self.groups

    @property
    def limits_processes(self) -> bool:
        return "pids" in self.groups

    def attach(self) -> None:
        """Put the calling process in the groups (run in the child between fork and exec)."""
        for group in dict.fromkeys(self.groups.values()):
            with open(group / "cgroup.procs", "w") as f:
                f.write(str(os.getpid()))

    def oom_killed(self) -> bool:
        """Whether the kernel killed a process of the agent for exceeding its memory."""
        group = self.groups.get("memory")
        if group is None:
            return False
        for name in ("memory.events", "memory.oom_control"):
            for line in _read(group / name).splitlines():
                key, _, value = line.partition(" ")
                if key == "oom_kill":
                    return value.strip().isdigit() and int(value) > 0
        failcnt = _read(group / "memory.failcnt").strip()  # an old v1 kernel: the limit hit
        return failcnt.isdigit() and int(failcnt) > 0

    def hit_limit(self) -> bool:
        """Whether the agent's memory ever reached its limit (the kernel then reclaims, stalls
        or kills: an agent silent after that is out of memory, not slow)."""
        group = self.groups.get("memory")
        if group is None:
            return False
        for line in _read(group / "memory.events").splitlines():  # v2
            key, _, value = line.partition(" ")
            if key in ("max", "oom") and value.strip().isdigit() and int(value) > 0:
                return True
        failcnt = _read(group / "memory.failcnt").strip()  # v1
        return failcnt.isdigit() and int(failcnt) > 0

    def stuck_at_limit(self) -> bool:
        """Whether the agent's processes wait in the kernel for memory beyond the limit (a
        cgroup v1 group "under_oom" whose killer has not acted, or one already killed)."""
        group = self.groups.get("memory")
        if group is None:
            return False
        for line in _read(group / "memory.oom_control").splitlines():
            key, _, value = line.partition(" ")
            if key == "under_oom" and value.strip() == "1":
                return True
        return self.oom_killed()

    def kill(self) -> None:
        """SIGKILL every process in the groups (a fork bomb included), then remove them."""
        for group in dict.fromkeys(self.groups.values()):
            if (group / "cgroup.kill").exists():
                try:
                    (group / "cgroup.kill").write_text("1")
                except OSError:
                    pass
            for _ in range(100):  # a fork bomb may still be forking: repeat until empty
                pids = [int(p) for p in _read(group / "cgroup.procs").split()]
                if not pids:
                    break
                for pid in pids:
                    try:
                        os.kill(pid, signal.SIGKILL)
                    except ProcessLookupError:
                        pass
                time.sleep(0.01)
            _remove(group)
        self.groups = {}


def _remove(group: Path) -> None:
    for _ in range(50):
        try:
            group.rmdir()
            return
        except FileNotFoundError:
            return
        except OSError:
            time.sleep(0.01)  # the last process is still leaving

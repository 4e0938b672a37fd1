"""How an agent's process is isolated: which set-up works here, and the command that starts it.

Three set-ups (``SandboxLimits.isolation``; "auto" takes the first that works):

- ``bwrap``: bubblewrap makes PID, network, mount, IPC and UTS namespaces and the file system;
- ``unshare``: util-linux ``unshare`` makes the namespaces and :mod:`.jail` the file system;
- ``none``: no isolation (only with ``trust``: ``compete --trust-submissions``), the agent runs
  with resource limits and the audit hooks of :mod:`.child` only.

In both isolated set-ups the agent never runs as root: a harness running as root gives each
agent a uid of its own (:func:`agent_uid`) that owns nothing, with no capability and
``no_new_privs``; a harness running as a user gives it that user inside a user namespace, with
no capability. It sees its own processes only, no network but its own loopback, the whole
file system read-only (root-only files unreadable), a fresh ``/tmp``, ``/run`` and
``/dev/shm``, its submission read-only at ``/tmp/sandbox/submission`` and a writable
``/tmp/sandbox/work`` (tmpfs, as large as its memory limit); other submissions and the
results are hidden under empty folders. A seccomp filter (:func:`.jail.seccomp_program`)
refuses ptrace, mounts, new namespaces and non-Unix sockets. When the harness dies the
sandbox's PID 1 dies and the kernel kills every process left in it.

``PR2_DRAKE_NO_BWRAP=1`` in the environment makes this module behave as if bubblewrap were not
installed (the tests run the fallback so).
"""

from __future__ import annotations

import itertools
import json
import os
import shutil
import stat
import subprocess
import sys
import tempfile
from functools import lru_cache
from pathlib import Path

from pr2_drake.compete import cgroups

ISOLATIONS = ("auto", "bwrap", "unshare", "none")
NO_BWRAP_ENV = "PR2_DRAKE_NO_BWRAP"
INSIDE = "/tmp/sandbox"  # the agent's folders as it sees them
JAIL = Path(__file__).resolve().with_name("jail.py")
PROJECT_ROOT = Path(__file__).resolve().parents[2]
AGENT_UID_BASE, AGENT_UIDS = 1_200_000, 1 << 16  # uids given to agents by a root harness
_COUNTER = itertools.count()


class IsolationUnavailable(ValueError):
    """The isolation asked for does not work here (the message says what to install)."""


def agent_uid() -> int:
    """A uid for one agent (root harness): owns no file, differs between concurrent agents."""
    return AGENT_UID_BASE + (os.getpid() * 131 + next(_COUNTER)) % AGENT_UIDS


# -- the file system as the agent sees it --------------------------------------------------------
def _needed_paths() -> list[Path]:
    """What the agent's Python must read: the project, the interpreter and its libraries."""
    paths = {PROJECT_ROOT, Path(sys.prefix).resolve(), Path(sys.base_prefix).resolve(),
             Path(sys.executable).resolve().parent}
    for p in sys.path:
        if p and Path(p).is_dir() and "site-packages" in p:
            paths.add(Path(p).resolve())
    return sorted(paths)


def _first_closed_parent(path: Path) -> Path | None:
    """The outermost folder on the way to ``path`` that others cannot enter (mode o-x)."""
    for p in reversed(path.parents):
        try:
            if not p.stat().st_mode & stat.S_IXOTH:
                return p
        except OSError:
            return None
    return None


def mount_plan(submission: Path | None, hide: tuple[Path, ...], tmp_bytes: int) -> list[list]:
    """The agent's file system on top of a read-only ``/``: ``[op, source, dest, mode, size]``
    with ops ``dev``, ``proc``, ``tmpfs``, ``dir``, ``ro-bind`` (see :mod:`.jail`)."""
    plan: list[list] = [["dev", "", "/dev", 0, 0], ["proc", "", "/proc", 0, 0]]
    fresh = ("/tmp", "/var/tmp", "/run", "/dev/shm")
    for dest in fresh:
        run = dest == "/run"
        plan.append(["tmpfs", "", dest, 0o755 if run else 0o1777, 1 << 20 if run else tmp_bytes])
    needed = _needed_paths()
    covered: set[Path] = set()
    made: set[Path] = set()
    for path in [p for p in needed if not any(q in p.parents for q in needed)]:
        closed = _first_closed_parent(path)
        under_fresh = any(_within(path, Path(f)) for f in fresh)
        if closed is not None and not under_fresh and closed not in covered:
            covered.add(closed)  # an empty folder over it, then what is needed bound back
            plan.append(["tmpfs", "", str(closed), 0o755, 0])
        if under_fresh or closed is not None:
            # Under a fresh folder every folder on the way is made anew and opened, a private
            # one too (a project cloned into `mktemp -d`); elsewhere those below the tmpfs.
            top = next(Path(f) for f in fresh if _within(path, Path(f))) if under_fresh \
                else closed
            for parent in reversed(path.parents):  # folders on the way, open to the agent
                if top in parent.parents and parent not in made:
                    made.add(parent)
                    plan.append(["dir", "", str(parent), 0o755, 0])
            plan.append(["ro-bind", str(path), str(path), 0, 0])
    for h in hide:  # (what lies under a fresh folder is gone already)
        if h.is_dir() and not any(_within(n, h) for n in needed) and \
                not any(_within(h, Path(f)) for f in fresh):
            plan.append(["tmpfs", "", str(h), 0o000, 4096])
    plan.append(["dir", "", INSIDE, 0o755, 0])
    if submission is not None:
        plan.append(["ro-bind", str(submission), f"{INSIDE}/submission", 0, 0])
    plan.append(["tmpfs", "", f"{INSIDE}/work", 0o1777, tmp_bytes])
    return plan


def _within(path: Path, folder: Path) -> bool:
    return path == folder or folder in path.parents


def bwrap_args(plan: list[list]) -> list[str]:
    """``plan`` as bubblewrap options (after ``--ro-bind / /``)."""
    args = ["--ro-bind", "/", "/"]
    for op, source, dest, mode, size in plan:
        if op == "tmpfs":
            args += ["--perms", f"{mode:04o}"] + (["--size", str(size)] if size else []) + \
                ["--tmpfs", dest]
        elif op == "dir":
            args += ["--perms", f"{mode:04o}", "--dir", dest]
        else:
            args += {"dev": ["--dev", dest], "proc": ["--proc", dest],
                     "ro-bind": ["--ro-bind", source, dest]}[op]
    return args


# -- the commands --------------------------------------------------------------------------------
def command(kind: str, program: list[str], *, plan: list[list], root: Path, uid: int,
            rlimits: dict[str, int], cwd: str) -> list[str]:
    """The command that runs ``program`` isolated by ``kind`` ("bwrap" or "unshare").

    Args:
        plan: the file system (:func:`mount_plan`).
        root: an empty folder (the unshare set-up builds the new root on it).
        uid: the agent's uid when the harness is root (also its gid).
        rlimits: resource limits of the agent's process ({"RLIMIT_...": value}).
        cwd: the agent's working folder, as it sees it.
    """
    as_root = os.getuid() == 0
    config = {"uid": uid if as_root else os.getuid(), "gid": uid if as_root else os.getgid(),
              "rlimits": rlimits, "seccomp": True, "cwd": cwd}
    python = [sys.executable, "-I", "-S", str(JAIL)]
    if kind == "bwrap":
        users = [] if as_root else ["--unshare-user", "--disable-userns"]
        return ["bwrap", *bwrap_args(plan), "--unshare-pid", "--unshare-net", "--unshare-ipc",
                "--unshare-uts", "--unshare-cgroup-try", *users, "--die-with-parent",
                "--new-session", "--chdir", "/", "--", *python, json.dumps(config), "--",
                *program]
    if kind == "unshare":
        config.update(root=str(root), mounts=plan)
        users = [] if as_root else ["--user", "--map-root-user"]
        return ["unshare", "--pid", "--net", "--mount", "--ipc", "--uts", "--fork",
                "--kill-child", *users, "--", *python, json.dumps(config), "--", *program]
    raise ValueError(f"unknown isolation {kind!r}")


# -- what works here -----------------------------------------------------------------------------
def works(kind: str) -> bool:
    """Whether ``kind`` ("bwrap", "unshare") starts a sandbox here (checked once per process:
    a program run in it as the agent would be)."""
    if kind == "bwrap" and os.environ.get(NO_BWRAP_ENV) == "1":
        return False
    return _works(kind)


@lru_cache(maxsize=None)
def _works(kind: str) -> bool:
    if kind == "bwrap" and not shutil.which("bwrap"):
        return False
    if kind == "unshare" and not shutil.which("unshare"):
        return False
    if readability_problem():
        return False
    root = Path(tempfile.mkdtemp(prefix="pr2_probe_"))
    try:
        argv = command(kind, ["/bin/sh", "-c", "test ! -w / && test \"$(id -u)\" != 0"],
                       plan=mount_plan(None, (), 1 << 20), root=root, uid=agent_uid(),
                       rlimits={}, cwd="/")
        r = subprocess.run(argv, capture_output=True, timeout=30, stdin=subprocess.DEVNULL)
        return r.returncode == 0
    except (OSError, subprocess.TimeoutExpired):
        return False
    finally:
        shutil.rmtree(root, ignore_errors=True)


@lru_cache(maxsize=1)
def readability_problem() -> str:
    """Why an agent's uid (not the harness's) could not run this Python and project ("" when
    it can). Only a root harness gives agents a uid of their own."""
    if os.getuid() != 0:
        return ""
    for path in (Path(sys.executable).resolve(), JAIL, PROJECT_ROOT / "pr2_drake",
                 *[p for p in _needed_paths() if "site-packages" in str(p)]):
        mode = path.stat().st_mode
        need = stat.S_IROTH | (stat.S_IXOTH if path.is_dir() or os.access(path, os.X_OK) else 0)
        if mode & need != need:
            return (f"{path} is not readable by other users, and agents run as a user of "
                    f"their own: chmod -R o+rX {path}")
    return ""


def choose(isolation: str, trust: bool) -> str:
    """The set-up to use for ``isolation`` ("auto", "bwrap", "unshare", "none").

    Raises:
        IsolationUnavailable: the one asked for does not work here, or none works and
            ``trust`` is off (the message says what to install).
    """
    if isolation not in ISOLATIONS:
        raise ValueError(f"isolation must be one of {ISOLATIONS}, got {isolation!r}")
    if isolation == "none":
        if not trust:
            raise IsolationUnavailable("isolation 'none' runs submissions unisolated: pass "
                                       "--trust-submissions to allow it")
        return "none"
    for kind in ("bwrap", "unshare") if isolation == "auto" else (isolation,):
        if works(kind):
            return kind
    if trust and isolation == "auto":
        return "none"
    raise IsolationUnavailable(unavailable_message(isolation))


def unavailable_message(isolation: str) -> str:
    """One line: why agents cannot be isolated here and what to install."""
    why = readability_problem()
    if why:
        return f"cannot isolate agents: {why} (or pass --trust-submissions)"
    what = {"bwrap": "bubblewrap does not work here (apt-get install bubblewrap)",
            "unshare": "util-linux unshare cannot make namespaces here"}.get(
        isolation, "neither bubblewrap nor util-linux unshare can make namespaces here")
    return (f"cannot isolate agents: {what}; install bubblewrap (apt-get install bubblewrap) or "
            f"allow namespaces (sysctl kernel.unprivileged_userns_clone=1, or run as root), or "
            f"pass --trust-submissions to run them unisolated")


def describe(kind: str) -> str:
    """One line: the isolation ``kind`` gives, with this machine's memory and process limits."""
    controllers = cgroups.available()
    memory = ("cgroup memory limit (all memory)" if "memory" in controllers else
              "address-space limit (RLIMIT_AS)")
    procs = "cgroup pids limit" if "pids" in controllers else "RLIMIT_NPROC"
    who = "a uid of its own" if os.getuid() == 0 else "the harness's user in a user namespace"
    if kind == "none":
        return (f"sandbox: NONE (--trust-submissions): agents run unisolated, as the "
                f"harness's user, with {memory}, {procs}, timeouts and audit hooks only")
    tool = "bubblewrap" if kind == "bwrap" else "util-linux unshare"
    return (f"sandbox: {tool}: {who}, no capabilities, own PID/network/mount/IPC namespaces, "
            f"read-only file system but a tmpfs work folder, seccomp; {memory}, {procs}, "
            f"timeouts")

"""The first program inside an agent's namespaces: file system, privileges, limits, then exec.

Run as ``python -I -S jail.py CONFIG_JSON -- PROGRAM ARGS...`` (standard library only: it runs
before anything of the agent's, with the privileges the namespaces were made with) by
:mod:`pr2_drake.compete.isolation`, in one of two set-ups:

- ``bwrap``: bubblewrap made the namespaces and the file system; this program (PID 2 in the
  sandbox) only drops privileges and execs.
- ``unshare``: util-linux ``unshare --pid --net --mount --ipc --uts --fork --kill-child`` made
  the namespaces; this program is PID 1 of the new PID namespace. It builds the file system
  from ``mounts`` (the same plan bubblewrap gets as arguments) under ``root`` and pivots into
  it, then forks: the child drops privileges and execs, and PID 1 reaps until it ends (when
  PID 1 exits, the kernel kills every process left in the namespace).

Dropping privileges: as root, every capability out of the bounding set, no groups, the real,
effective and saved uid and gid set to ``uid`` (never 0); in a user namespace that maps only
one uid, the capabilities are dropped instead. Then ``no_new_privs``, resource limits and a
seccomp filter (:func:`seccomp_program`) that refuses ptrace, mounts, new namespaces, kernel
keyrings, BPF, perf and sockets other than Unix ones with EPERM.

CONFIG keys: ``uid``, ``gid``, ``rlimits`` ({name: value}), ``seccomp`` (bool), ``cwd``, and for
``unshare`` ``root`` (an empty folder to build the new root on) and ``mounts`` (a list of
``[op, source, destination, mode, size]``; ops: ro-bind, bind, tmpfs, dir, dev, proc).
"""

import ctypes
import json
import os
import resource
import signal
import struct
import sys

MS_RDONLY, MS_NOSUID, MS_NODEV, MS_NOEXEC = 1, 2, 4, 8
MS_REMOUNT, MS_BIND, MS_REC, MS_PRIVATE = 32, 4096, 16384, 1 << 18
MNT_DETACH = 2
CLONE_NEWUSER = 0x10000000
PR_SET_PDEATHSIG, PR_CAPBSET_DROP, PR_SET_SECUREBITS = 1, 24, 28
PR_SET_NO_NEW_PRIVS, PR_SET_SECCOMP, SECCOMP_MODE_FILTER = 38, 22, 2
SECBITS_LOCKED_NOROOT = 0x3 | 0xC  # SECBIT_NOROOT(+_LOCKED), SECBIT_NO_SETUID_FIXUP(+_LOCKED)
DEVICES = ("null", "zero", "full", "random", "urandom", "tty")
JAIL_FAILED = 125  # exit status when the sandbox could not be set up (the reason on stderr)

_libc = ctypes.CDLL(None, use_errno=True)


def _check(result: int, what: str) -> int:
    if result != 0:
        err = ctypes.get_errno()
        raise OSError(err, f"{what}: {os.strerror(err)}")
    return result


def mount(source, target, fstype, flags: int, data=None) -> None:
    enc = (lambda s: None if s is None else os.fsencode(s))
    _check(_libc.mount(enc(source), enc(target), enc(fstype), ctypes.c_ulong(flags),
                       enc(data)), f"mount {target}")


# -- the file system (unshare set-up) ------------------------------------------------------------
def _mount_points_under(top: str) -> list[tuple[str, int]]:
    """The mount points at or under ``top`` with their per-mount flags, outermost first."""
    out = []
    with open("/proc/self/mountinfo") as f:
        for line in f:
            fields = line.split()
            point = fields[4].encode().decode("unicode_escape")
            if point == top or point.startswith(top.rstrip("/") + "/"):
                opts = fields[5].split(",")
                flags = (MS_NOSUID if "nosuid" in opts else 0) | \
                    (MS_NODEV if "nodev" in opts else 0) | (MS_NOEXEC if "noexec" in opts else 0)
                out.append((point, flags))
    return sorted(out, key=lambda p: p[0].count("/"))


def _read_only(top: str) -> None:
    """Remount ``top`` and every mount under it read-only (per mount point)."""
    for point, flags in _mount_points_under(top):
        try:
            mount(None, point, None, MS_REMOUNT | MS_BIND | MS_RDONLY | flags)
        except OSError:
            if point == top:
                raise


def _make_path(path: str, file: bool = False) -> None:
    os.makedirs(os.path.dirname(path) if file else path, exist_ok=True)
    if file and not os.path.exists(path):
        open(path, "w").close()


def build_root(root: str, mounts: list) -> None:
    """The sandbox's file system on ``root``, then ``root`` becomes ``/``."""
    mount(None, "/", None, MS_REC | MS_PRIVATE)
    mount("/", root, None, MS_BIND | MS_REC)
    _read_only(root)
    for op, source, dest, mode, size in mounts:
        target = root + dest
        if op == "tmpfs":
            _make_path(target)
            data = f"mode={mode:o}" + (f",size={size}" if size else "")
            mount("tmpfs", target, "tmpfs", MS_NOSUID | MS_NODEV, data)
        elif op == "dir":
            os.makedirs(target, exist_ok=True)
            os.chmod(target, mode)
        elif op in ("ro-bind", "bind"):
            _make_path(target, file=not os.path.isdir(source))
            mount(source, target, None, MS_BIND | (MS_REC if op == "ro-bind" else 0))
            if op == "ro-bind":
                _read_only(target)
        elif op == "dev":
            mount("tmpfs", target, "tmpfs", MS_NOSUID, "mode=755")
            for name in DEVICES:
                if os.path.exists(f"/dev/{name}"):
                    _make_path(f"{target}/{name}", file=True)
                    mount(f"/dev/{name}", f"{target}/{name}", None, MS_BIND)
            for name, to in (("fd", "/proc/self/fd"), ("stdin", "/proc/self/fd/0"),
                             ("stdout", "/proc/self/fd/1"), ("stderr", "/proc/self/fd/2")):
                os.symlink(to, f"{target}/{name}")
        elif op == "proc":
            mount("proc", target, "proc", MS_NOSUID | MS_NODEV | MS_NOEXEC)
        else:
            raise ValueError(f"unknown mount operation {op!r}")
    os.chdir(root)
    _check(_libc.syscall(_PIVOT_ROOT, b".", b"."), "pivot_root")
    _check(_libc.umount2(b".", MNT_DETACH), "umount old root")
    os.chdir("/")


# -- privileges and limits -------------------------------------------------------------------------
def drop_privileges(uid: int, gid: int) -> None:
    """Never root: as root, switch to ``uid``/``gid`` with no capability left. As root of a
    user namespace that maps only the harness's (unprivileged) uid, first enter a user
    namespace of its own where that uid is ``uid`` (not 0); then drop the capabilities and
    lock root's special cases."""
    if os.getuid() == 0 and not _maps_other_uids():
        _check(_libc.unshare(CLONE_NEWUSER), "unshare(CLONE_NEWUSER)")
        for name, text in (("setgroups", "deny"), ("uid_map", f"{uid} 0 1"),
                           ("gid_map", f"{gid} 0 1")):
            with open(f"/proc/self/{name}", "w") as f:
                f.write(text)
    for cap in range(64):
        if _libc.prctl(PR_CAPBSET_DROP, cap, 0, 0, 0) != 0 and ctypes.get_errno() != 22:
            break  # EINVAL: past the last capability
    if os.getuid() == 0 and _maps_other_uids():
        os.setgroups([])
        os.setresgid(gid, gid, gid)
        os.setresuid(uid, uid, uid)
    else:
        _libc.prctl(PR_SET_SECUREBITS, SECBITS_LOCKED_NOROOT, 0, 0, 0)
        _clear_capabilities()
    if os.getuid() == 0:
        raise OSError("the agent would run as root")
    _check(_libc.prctl(PR_SET_NO_NEW_PRIVS, 1, 0, 0, 0), "no_new_privs")


def _maps_other_uids() -> bool:
    """Whether this user namespace maps more than one uid (uid 0 can become another)."""
    with open("/proc/self/uid_map") as f:
        return sum(int(line.split()[2]) for line in f if line.strip()) > 1


def _clear_capabilities() -> None:
    header = struct.pack("Ii", 0x20080522, 0)  # _LINUX_CAPABILITY_VERSION_3, this thread
    data = bytes(24)  # two {effective, permitted, inheritable} of 32 bits each: all zero
    _check(_libc.capget(header, ctypes.create_string_buffer(24)), "capget")
    _check(_libc.capset(header, data), "capset")


def set_limits(limits: dict) -> None:
    for name, value in limits.items():
        resource.setrlimit(getattr(resource, name), (int(value), int(value)))


# -- seccomp ---------------------------------------------------------------------------------------
_ARCH = {  # audit arch, pivot_root, clone, clone3, socket, refused system calls
    "x86_64": (0xC000003E, 155, 56, 435, 41, (
        101, 310, 311, 165, 166, 155, 272, 308, 248, 249, 250, 321, 298, 323, 246, 320, 175,
        313, 176, 169, 167, 168, 163, 172, 173, 303, 304, 428, 429, 430, 431, 432, 442, 425,
        426, 427, 438, 312)),
    "aarch64": (0xC00000B7, 41, 220, 435, 198, (
        117, 270, 271, 40, 39, 41, 97, 268, 217, 218, 219, 280, 241, 282, 104, 294, 105, 273,
        106, 142, 224, 225, 89, 264, 265, 428, 429, 430, 431, 432, 442, 425, 426, 427, 438,
        272)),
}
_MACHINE = os.uname().machine
_PIVOT_ROOT = _ARCH.get(_MACHINE, (0, 155))[1]
CLONE_NEW_ANY = 0x10000000 | 0x00020000 | 0x20000000 | 0x40000000 | 0x08000000 | 0x04000000 \
    | 0x02000000 | 0x00000080  # user, mount, pid, net, ipc, uts, cgroup, time namespaces
AF_UNIX = 1
RET_ALLOW, RET_KILL = 0x7FFF0000, 0x80000000
RET_EPERM, RET_ENOSYS = 0x00050000 | 1, 0x00050000 | 38


def seccomp_program(machine: str = _MACHINE) -> bytes | None:
    """A classic-BPF seccomp filter for ``machine`` (None where it has no table): refused
    system calls return EPERM; ``clone`` with a namespace flag and ``socket`` of any family
    but AF_UNIX too; ``clone3`` (whose flags it cannot read) ENOSYS, so that the C library
    falls back to ``clone``; another architecture's calls kill the process."""
    if machine not in _ARCH:
        return None
    arch, _, clone, clone3, socket, refused = _ARCH[machine]
    ld = lambda k: struct.pack("HBBI", 0x20, 0, 0, k)  # noqa: E731 (BPF_LD|W|ABS)
    jeq = lambda k, jt, jf: struct.pack("HBBI", 0x15, jt, jf, k)  # noqa: E731
    jset = lambda k, jt, jf: struct.pack("HBBI", 0x45, jt, jf, k)  # noqa: E731
    ret = lambda k: struct.pack("HBBI", 0x06, 0, 0, k)  # noqa: E731
    # The returns sit at the end: [ALLOW, EPERM, ENOSYS, KILL]; each jump counts to them.
    body = [("ld", 4), ("arch", arch), ("ld", 0)]
    if machine == "x86_64":
        body.append(("x32", 0))
    body += [("deny", n) for n in refused]
    body += [("clone", clone), ("socket", socket), ("clone3", clone3), ("allow", 0)]
    size = len(body) + 4 + 4  # + the clone and socket argument checks (2 each) + returns
    prog, pc = [], 0

    def to(target: str, at: int) -> int:
        return {"allow": size - 4, "eperm": size - 3, "enosys": size - 2,
                "kill": size - 1}[target] - at - 1

    for op, k in body:
        if op == "ld":
            prog.append(ld(k))
        elif op == "arch":
            prog.append(jeq(k, 0, to("kill", pc)))
        elif op == "x32":
            prog.append(struct.pack("HBBI", 0x35, to("kill", pc), 0, 0x40000000))  # JGE
        elif op == "deny":
            prog.append(jeq(k, to("eperm", pc), 0))
        elif op == "clone":  # jump over to its check (after the socket and clone3 tests)
            prog.append(jeq(k, 3, 0))
        elif op == "socket":
            prog.append(jeq(k, 4, 0))
        elif op == "clone3":
            prog.append(jeq(k, to("enosys", pc), 0))
        elif op == "allow":
            prog.append(ret(RET_ALLOW))
            pc += 1
            # clone: flags in args[0] (low word, offset 16); socket: the family likewise
            prog += [ld(16), jset(CLONE_NEW_ANY, to("eperm", pc + 1), to("allow", pc + 1))]
            pc += 2
            prog += [ld(16), jeq(AF_UNIX, to("allow", pc + 1), to("eperm", pc + 1))]
            pc += 2
            continue
        pc += 1
    prog += [ret(RET_ALLOW), ret(RET_EPERM), ret(RET_ENOSYS), ret(RET_KILL)]
    assert len(prog) == size
    return b"".join(prog)


class _SockFprog(ctypes.Structure):
    _fields_ = [("len", ctypes.c_ushort), ("filter", ctypes.c_char_p)]


def install_seccomp() -> bool:
    """Load the filter (after no_new_privs); False where this machine has no table."""
    code = seccomp_program()
    if code is None:
        return False
    prog = _SockFprog(len(code) // 8, code)
    _check(_libc.prctl(PR_SET_SECCOMP, SECCOMP_MODE_FILTER, ctypes.byref(prog), 0, 0),
           "seccomp")
    return True


# -- the program -----------------------------------------------------------------------------------
def become_agent(config: dict, argv: list[str]) -> None:
    """Drop privileges, set the limits and the filter, and exec ``argv`` (never returns)."""
    drop_privileges(int(config["uid"]), int(config["gid"]))
    _libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)  # cleared by the uid change
    set_limits(config.get("rlimits", {}))
    if config.get("seccomp", True):
        install_seccomp()
    try:
        os.chdir(config.get("cwd", "/"))
        os.execv(argv[0], argv)
    except PermissionError as e:
        raise PermissionError(e.errno, _unreachable(e.filename or argv[0])) from None


def _unreachable(path: str) -> str:
    """Name the folder above ``path`` the agent's uid cannot enter (after the privilege drop)."""
    folder = os.path.dirname(os.path.abspath(path))
    parts = folder.split(os.sep)
    for i in range(1, len(parts) + 1):
        above = os.sep.join(parts[:i]) or os.sep
        if not os.access(above, os.X_OK):
            return (f"the agent's uid {os.getuid()} cannot reach {path}: {above} is closed to "
                    f"other users (the project and its Python environment must be readable "
                    f"by every user: chmod o+rx {above}, or install them elsewhere)")
    return f"the agent's uid {os.getuid()} may not open or run {path}"


def init(config: dict, argv: list[str]) -> int:
    """PID 1 of the sandbox (unshare set-up): build the root, fork the agent, reap."""
    _libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    build_root(config["root"], config["mounts"])
    agent = os.fork()
    if agent == 0:
        try:
            os.setsid()
            become_agent(config, argv)
        except BaseException as e:  # noqa: BLE001 (report any failure, never run the agent)
            os.write(2, f"sandbox: {type(e).__name__}: {e}\n".encode())
        os._exit(JAIL_FAILED)
    while True:
        pid, status = os.waitpid(-1, 0)
        if pid == agent:
            return os.waitstatus_to_exitcode(status) if os.WIFEXITED(status) else \
                128 + os.WTERMSIG(status)


def main(args: list[str]) -> int:
    config, argv = json.loads(args[0]), args[args.index("--") + 1:]
    if "mounts" in config:
        return init(config, argv)
    try:
        become_agent(config, argv)
    except BaseException as e:  # noqa: BLE001
        os.write(2, f"sandbox: {type(e).__name__}: {e}\n".encode())
    return JAIL_FAILED


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

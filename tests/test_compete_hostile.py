"""The harness against submissions that attack it (issue 25), with bubblewrap and with the
util-linux fallback (bubblewrap hidden by PR2_DRAKE_NO_BWRAP=1).

One ``pr2-drake compete`` per set-up runs every attacker of tests/hostile/attackers.py and a
clean submission last; the harness must finish with status 0, every attacker score 0 with a
named end, nothing outside the sandboxes change (the package, another submission, the
results, a victim file), no process survive, no secret reach the results, and the clean
episode give the plant state of a clean run, bit for bit.
"""

import errno
import hashlib
import json
import os
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from pr2_drake.compete.isolation import NO_BWRAP_ENV, works
from pr2_drake.compete.ledger import read_rows, run_key
from pr2_drake.compete.limits import SandboxLimits
from pr2_drake.compete.proxy import run_sandboxed_episode
from pr2_drake.scenario import Scenario

HOSTILE = Path(__file__).with_name("hostile")
EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "submissions"
PACKAGE = Path(__file__).resolve().parents[1] / "pr2_drake"
SECONDS = 0.3
# attacker -> the ends it may get (all keep 0 points: they stand still)
ATTACKS = {
    "CtypesWrite": {"timeout"},
    "RewritesReferee": {"timeout"},
    "UnhooksAndWrites": {"timeout", "agent_error"},
    "SubinterpreterWrite": {"timeout"},
    "ForkExecSurvivor": {"timeout"},
    "DaemonSurvivor": {"timeout"},
    "ForkBombViaCtypes": {"timeout"},
    "KillsTheHarness": {"timeout"},
    "ReadsSecrets": {"agent_error"},
    "SocketViaCtypes": {"agent_error"},
    "FakesResultRow": {"timeout"},
    "ChannelFloatOverflow": {"agent_error"},
    "ChannelGarbage": {"agent_error"},
    # killed at its memory limit, or (seen under concurrent attacks, cause not established)
    # held blocked in the kernel at no CPU until the wall-clock cap: either way it never runs
    # on with the memory
    "SharedMemoryHog": {"agent_memory", "agent_timeout"},
}
SETUPS = [pytest.param("bwrap", marks=pytest.mark.skipif(
    not works("bwrap"), reason="bubblewrap does not work here")), "unshare"]


def _env(setup: str, secret: str) -> dict:
    env = {**os.environ, "PR2_TEST_TOKEN": secret}
    if setup == "unshare":
        env[NO_BWRAP_ENV] = "1"
    return env


def _digest(paths) -> str:
    h = hashlib.sha256()
    for p in sorted(paths):
        h.update(str(p).encode() + p.read_bytes())
    return h.hexdigest()


@pytest.fixture(scope="module")
def clean_digest():
    """The clean submission's plant state after a clean episode (nothing hostile before)."""
    r = run_sandboxed_episode(Scenario(task=1, seed=0, seconds=SECONDS, agent="stander:Stander"),
                              submission=EXAMPLES / "stand_still")
    assert r["termination"] == "timeout", r
    return r["state_digest"]


def _submissions(root: Path, out: Path, victim: Path, secret_file: Path, port: int) -> Path:
    subs = root / "subs"
    clean = subs / "zz_clean"
    shutil.copytree(EXAMPLES / "stand_still", clean)
    files = [str(victim), str(clean / "stander.py"), str(PACKAGE / "tasks" / "__init__.py"),
             str(out / "episodes.jsonl")]
    for name in ATTACKS:
        folder = subs / name.lower()
        folder.mkdir(parents=True)
        shutil.copy(HOSTILE / "attackers.py", folder)
        target = {"files": files, "results": str(out), "secrets": [str(secret_file)],
                  "port": port, "name": name.lower(), "seed": len(name)}
        (folder / "submission.yaml").write_text(json.dumps(
            {"agent": f"attackers:{name}", "agent_params": {"target": target}}))
    # A symbolic link out of the submission: refused, never followed.
    link = subs / "symlink_out"
    shutil.copytree(EXAMPLES / "stand_still", link)
    (link / "leak.txt").symlink_to(secret_file)
    return subs


def _survivors(marker: str, grace: float = 2.0) -> list[str]:
    """The processes left running: a namespace's processes get SIGKILL when its PID 1 dies,
    but the kernel ends them a few ms later, so look again for ``grace`` [s] before naming
    one (a process that truly survives is still there after it)."""
    deadline = time.monotonic() + grace
    while (found := _running(marker)) and time.monotonic() < deadline:
        time.sleep(0.05)
    return found


def _running(marker: str) -> list[str]:
    found = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                comm = (d / "comm").read_text().strip()
                cmd = (d / "cmdline").read_bytes().decode(errors="replace")
                zombie = (d / "stat").read_text().rpartition(")")[2].split()[0] == "Z"
            except (OSError, IndexError):
                continue
            if not zombie and (comm == "pr2survivor" or marker in cmd):
                found.append(f"{d.name} {comm} {cmd[:80]}")
    return found


@pytest.mark.parametrize("setup", SETUPS)
def test_every_attack_ends_only_its_own_episode(setup, tmp_path, clean_digest):
    secret = "s3cr3t-" + os.urandom(6).hex()
    secret_file = tmp_path / "root_only.txt"
    secret_file.write_text(secret)
    secret_file.chmod(0o600)
    victim = tmp_path / "victim.txt"
    victim.write_text("intact")
    out = tmp_path / "results"
    listener = socket.create_server(("127.0.0.1", 0))
    listener.setblocking(False)
    subs = _submissions(tmp_path, out, victim, secret_file, listener.getsockname()[1])
    package = list(PACKAGE.rglob("*.py"))
    before = _digest(package), _digest([subs / "zz_clean" / "stander.py"])

    r = subprocess.run([sys.executable, "-m", "pr2_drake.cli", "compete", str(subs),
                        "--tasks", "1", "--seeds", "0:1", "--seconds", str(SECONDS), "--jobs",
                        "2", "--out", str(out), "--memory-mb", "1024"], capture_output=True,
                       text=True, timeout=600, env=_env(setup, secret))
    assert r.returncode == 0, r.stderr[-3000:]
    assert ("bubblewrap" if setup == "bwrap" else "util-linux unshare") in r.stderr
    rows = {e["submission"]: e for e in json.loads((out / "results.json").read_text())[
        "episodes"]}
    for name, ends in ATTACKS.items():
        row = rows[name.lower()]
        assert row["sandbox"] == setup and row["score"] == 0, row
        assert row["termination"] in ends, (name, row["termination"], row.get("message"))
    assert rows["symlink_out"]["termination"] == "agent_error"
    assert "outside the submission" in rows["symlink_out"]["message"]
    assert rows["channelfloatoverflow"]["message"].startswith("garbage on the agent channel")
    hog = rows["sharedmemoryhog"]["message"]
    assert "memory limit" in hog or "0.00 s of CPU time: sleeping or blocked" in hog, hog
    # Nothing outside the sandboxes changed; no secret, no connection, no survivor.
    assert (_digest(package), _digest([subs / "zz_clean" / "stander.py"])) == before
    assert victim.read_text() == "intact"
    results_text = "".join(p.read_text() for p in out.iterdir() if p.is_file()
                           and p.suffix in (".json", ".csv", ".jsonl"))
    assert secret not in results_text and "pr2survivor" not in results_text
    with pytest.raises(BlockingIOError):
        listener.accept()
    assert not _survivors(str(out)), _survivors(str(out))
    done, rejected = read_rows(out / "episodes.jsonl", run_key(out))
    assert rejected == 0 and done[("fakesresultrow", 1, 0)]["score"] == 0
    # The clean episode after all of them: bit for bit a clean run's.
    assert rows["zz_clean"]["termination"] == "timeout"
    assert rows["zz_clean"]["state_digest"] == clean_digest


@pytest.mark.parametrize("setup", SETUPS)
def test_truncating_the_camera_memory_hurts_only_the_attacker(setup, monkeypatch):
    """Task 6 for 1 s: the attacker shrinks the camera's memfd (sealed) and scribbles on it;
    the harness goes on sending frames, and the next clean episode is bit-identical."""
    from pr2_drake.camera import CameraSettings

    if setup == "unshare":
        monkeypatch.setenv(NO_BWRAP_ENV, "1")
    limits = SandboxLimits(isolation=setup)
    camera = CameraSettings(enabled=True, width=160, height=120, fps=20)

    def clean():
        return run_sandboxed_episode(Scenario(task=6, seed=0, seconds=0.1, control_dt=0.01,
                                              agent=f"{HOSTILE / 'hostile_agents.py'}:"
                                                    "NeedsCamera", camera=camera), limits=limits)

    first = clean()
    # 100 Hz: the standing agent at 50 Hz falls at 0.84 s with the "similar" contact
    # approximation (it stood 1 s with "lagged").
    r = run_sandboxed_episode(Scenario(task=6, seed=0, seconds=1.0, control_dt=0.01,
                                       agent=f"{HOSTILE / 'attackers.py'}:TruncatesCamera",
                                       camera=camera), limits=limits)
    assert r["sandbox"] == setup and r["termination"] == "timeout", r.get("message")
    assert r["steps"] == 100 and r["score"] == 0
    again = clean()
    assert again["termination"] == "timeout", again.get("message")
    assert again["state_digest"] == first["state_digest"]


PROBE = r"""
import ctypes, errno, json, os, socket
libc = ctypes.CDLL(None, use_errno=True)
def err(rc):
    return 0 if rc >= 0 else ctypes.get_errno()
out = {"uid": os.getuid(), "euid": os.geteuid()}
status = dict(l.split(":", 1) for l in open("/proc/self/status"))
out["caps"] = [status[k].strip() for k in ("CapEff", "CapPrm", "CapBnd")]
out["nnp"], out["seccomp"] = status["NoNewPrivs"].strip(), status["Seccomp"].strip()
out["inet"] = err(libc.socket(socket.AF_INET, socket.SOCK_STREAM, 0))
out["unix"] = err(libc.socket(socket.AF_UNIX, socket.SOCK_STREAM, 0))
out["userns"] = err(libc.unshare(0x10000000))
out["ptrace"] = err(libc.ptrace(0x4206, 1, 0, 0))
out["pids"] = sorted(int(p) for p in os.listdir("/proc") if p.isdigit())
out["write_root"] = err(libc.open(b"/pr2_probe", os.O_WRONLY | os.O_CREAT, 0o644))
out["secret"] = err(libc.open(SECRET.encode(), os.O_RDONLY))
out["hidden"] = os.listdir(HIDDEN) if os.access(HIDDEN, os.R_OK) else "unreadable"
out["work"] = err(libc.open(b"/tmp/sandbox/work/f", os.O_WRONLY | os.O_CREAT, 0o644))
out["links"] = [l.split()[0] for l in open("/proc/net/dev").readlines()[2:]]
print(json.dumps(out))
"""


@pytest.mark.parametrize("setup", SETUPS)
def test_inside_the_sandbox(setup, tmp_path):
    """What a program in the sandbox can do: not root, no capability, no_new_privs and the
    seccomp filter, no network but loopback (no AF_INET socket at all), no user namespace,
    no ptrace, only its own processes, a read-only / with root-only files unreadable, hidden
    folders empty, its work folder writable."""
    import tempfile

    from pr2_drake.compete import isolation

    secret = tmp_path / "secret"
    secret.write_text("x")
    secret.chmod(0o600)
    # Outside /tmp (which the sandbox replaces anyway): in the project's ignored cache.
    cache = Path(__file__).resolve().parents[1] / ".pytest_cache"
    cache.mkdir(exist_ok=True)
    hidden = Path(tempfile.mkdtemp(prefix="others_", dir=cache))
    (hidden / "solver.py").write_text("x = 1\n")
    code = PROBE.replace("SECRET", repr(str(secret))).replace("HIDDEN", repr(str(hidden)))
    root = Path(tempfile.mkdtemp())
    try:
        argv = isolation.command(setup, [sys.executable, "-I", "-S", "-c", code],
                                 plan=isolation.mount_plan(None, (hidden,), 1 << 26),
                                 root=root, uid=isolation.agent_uid(), rlimits={}, cwd="/")
        r = subprocess.run(argv, capture_output=True, text=True, timeout=60)
    finally:
        shutil.rmtree(root, ignore_errors=True)
        shutil.rmtree(hidden, ignore_errors=True)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["uid"] != 0 and out["euid"] != 0
    assert out["caps"] == ["0000000000000000"] * 3 and out["nnp"] == "1" and out["seccomp"] == "2"
    assert out["inet"] == errno.EPERM and out["unix"] == 0
    assert out["userns"] == errno.EPERM and out["ptrace"] == errno.EPERM
    assert out["pids"] == [1, 2]
    assert out["write_root"] == errno.EROFS and out["secret"] in (errno.EACCES, errno.ENOENT)
    assert out["hidden"] == "unreadable" and out["work"] == 0
    assert out["links"] == ["lo:"]


@pytest.mark.parametrize("setup", SETUPS)
def test_the_agent_reads_the_project_from_a_private_folder_under_tmp(setup, tmp_path, monkeypatch):
    """A project (or virtual environment) cloned into a folder others cannot enter, under a
    folder the sandbox replaces (``mktemp -d`` makes /tmp/tmp.XXXX with mode 700): the agent,
    another uid, still reaches it read-only through folders made open on the way."""
    import tempfile

    from pr2_drake.compete import isolation

    private = Path(tempfile.mkdtemp())  # /tmp/tmpXXXX, mode 700
    assert private.parent == Path(tempfile.gettempdir())
    package = private / "repo"
    package.mkdir()
    (package / "module.py").write_text("ANSWER = 42\n")
    needed = isolation._needed_paths()
    monkeypatch.setattr(isolation, "_needed_paths", lambda: [*needed, package])
    code = f"import sys; sys.path.insert(0, {str(package)!r}); import module; print(module.ANSWER)"
    root = Path(tempfile.mkdtemp())
    try:
        argv = isolation.command(setup, [sys.executable, "-I", "-S", "-c", code],
                                 plan=isolation.mount_plan(None, (), 1 << 26),
                                 root=root, uid=isolation.agent_uid(), rlimits={}, cwd="/")
        r = subprocess.run(argv, capture_output=True, text=True, timeout=60)
    finally:
        shutil.rmtree(root, ignore_errors=True)
        shutil.rmtree(private, ignore_errors=True)
    assert r.returncode == 0 and r.stdout.strip() == "42", r.stderr


@pytest.mark.parametrize("setup", SETUPS)
def test_without_control_groups_the_address_space_and_process_limits_hold(setup, monkeypatch):
    """Where no cgroup is writable (simulated): RLIMIT_AS refuses the shared-memory hog,
    RLIMIT_NPROC (a uid per agent) stops the fork bomb, and the PID namespace takes its
    children when the episode ends."""
    from pr2_drake.compete import cgroups

    monkeypatch.setenv(cgroups.NO_CGROUPS_ENV, "1")
    if setup == "unshare":
        monkeypatch.setenv(NO_BWRAP_ENV, "1")
    limits = SandboxLimits(memory_mb=1024, processes=16, step_seconds=2.0)
    for attacker, end in (("SharedMemoryHog", "agent_memory"), ("ForkBombViaCtypes", "timeout")):
        r = run_sandboxed_episode(Scenario(task=1, seed=0, seconds=0.1,
                                           agent=f"{HOSTILE / 'attackers.py'}:{attacker}"),
                                  limits=limits)
        assert r["sandbox"] == setup and r["termination"] == end, r.get("message")
    assert not _survivors("pr2survivor")


def test_any_bytes_on_the_reply_channel_decode_or_raise_channel_error():
    """Random bytes, and valid answers cut, flipped and spliced with JSON's odd numbers:
    decode_reply gives a dict or raises ChannelError, never anything else."""
    import random

    import numpy as np

    from pr2_drake.compete.channel import ChannelError, decode_reply
    from pr2_drake.compete.child import _binary

    blob: list[bytes] = []
    head = json.dumps(_binary({"action": {"legs": {"joint_values": np.arange(10.0)}},
                               "compute": 1e-4}, blob, [0])).encode()
    valid = len(head).to_bytes(4, "big") + head + b"".join(blob)
    assert decode_reply(valid)["action"]["legs"]["joint_values"][3] == 3.0
    rng = random.Random(0)
    odd = [b"Infinity", b"-Infinity", b"NaN", b"1e999", b"9" * 5000, b"[" * 3000, b"null",
           b'{"__f8__": [1e300, 0]}', b'{"__f8__": [-8, 1]}', b'{"__f8__": "x"}', b"\xff\xfe"]
    for i in range(4000):
        kind = i % 4
        if kind == 0:
            data = bytes(rng.randrange(256) for _ in range(rng.randrange(0, 64)))
        elif kind == 1:
            data = bytearray(valid)
            for _ in range(rng.randrange(1, 6)):
                data[rng.randrange(len(data))] = rng.randrange(256)
        elif kind == 2:
            data = valid[:rng.randrange(len(valid))]
        else:
            at = rng.randrange(4, len(head) + 4)
            data = valid[:at] + rng.choice(odd) + valid[at + rng.randrange(0, 8):]
        try:
            assert isinstance(decode_reply(bytes(data)), dict)
        except ChannelError:
            pass

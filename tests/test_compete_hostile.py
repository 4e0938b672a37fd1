"""The harness against submissions that attack it (issue 25), with bubblewrap and with the
util-linux fallback (bubblewrap hidden by PR2_DRAKE_NO_BWRAP=1).

One ``pr2-drake compete`` per set-up runs every attacker of tests/hostile/attackers.py and a
clean submission last; the harness must finish with status 0, every attacker score 0 with a
named end, nothing outside the sandboxes change (the package, another submission, the
results, a victim file), no process survive, no secret reach the results, and the clean
episode give the plant state of a clean run, bit for bit.
"""

import hashlib
import json
import os
import shutil
import socket
import subprocess
import sys
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
    "KillsTheHarness": {"timeout"},
    "ReadsSecrets": {"agent_error"},
    "SocketViaCtypes": {"agent_error"},
    "FakesResultRow": {"timeout"},
    "ChannelFloatOverflow": {"agent_error"},
    "ChannelGarbage": {"agent_error"},
    "SharedMemoryHog": {"agent_memory"},
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


def _survivors(marker: str) -> list[str]:
    found = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                comm = (d / "comm").read_text().strip()
                cmd = (d / "cmdline").read_bytes().decode(errors="replace")
            except OSError:
                continue
            if comm == "pr2survivor" or marker in cmd:
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
                        "--tasks", "1", "--seeds", "0:1", "--seconds", str(SECONDS), "--out",
                        str(out), "--memory-mb", "1024", "--step-budget", "2", "--step-wall",
                        "4"], capture_output=True, text=True, timeout=600,
                       env=_env(setup, secret))
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
    assert "memory" in rows["sharedmemoryhog"]["message"]
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
        return run_sandboxed_episode(Scenario(task=6, seed=0, seconds=0.1, control_dt=0.02,
                                              agent=f"{HOSTILE / 'hostile_agents.py'}:"
                                                    "NeedsCamera", camera=camera), limits=limits)

    first = clean()
    r = run_sandboxed_episode(Scenario(task=6, seed=0, seconds=1.0, control_dt=0.02,
                                       agent=f"{HOSTILE / 'attackers.py'}:TruncatesCamera",
                                       camera=camera), limits=limits)
    assert r["sandbox"] == setup and r["termination"] == "timeout", r.get("message")
    assert r["steps"] == 50 and r["score"] == 0
    again = clean()
    assert again["termination"] == "timeout", again.get("message")
    assert again["state_digest"] == first["state_digest"]

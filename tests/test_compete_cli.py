"""pr2-drake compete and leaderboard, run as an organiser runs them."""

import csv
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "submissions"


def _cli(*args, env=None):
    return subprocess.run([sys.executable, "-m", "pr2_drake.cli", *args], capture_output=True,
                          text=True, timeout=600, env=env)


def test_two_submissions_compete_resume_and_leaderboard(tmp_path):
    out = tmp_path / "results"
    args = ("compete", str(EXAMPLES), "--tasks", "1", "--seeds", "0:1", "--seconds", "0.2",
            "--out", str(out))
    r = _cli(*args)
    assert r.returncode == 0, r.stderr
    assert "0 episodes done before, 2 to run" in r.stderr
    data = json.loads((out / "results.json").read_text())
    rows = data["episodes"]
    assert {(e["submission"], e["task"], e["seed"]) for e in rows} == {
        ("reference", 1, 0), ("stand_still", 1, 0)}
    for e in rows:
        assert e["termination"] == "timeout" and e["sim_time"] == 0.2
        assert e["agent_compute_mean"] > 0 and e["agent_compute_max"] >= e["agent_compute_mean"]
    with open(out / "results.csv") as f:
        table = list(csv.DictReader(f))
    assert len(table) == 2 and {"score", "max_score", "items", "wall_time",
                                "agent_compute_max_ms", "termination"} <= set(table[0])
    # A killed run: one episode's line lost (and a line cut in half) -> only it runs again.
    lines = (out / "episodes.jsonl").read_text().splitlines()
    (out / "episodes.jsonl").write_text(lines[0] + "\n" + lines[1][:20])
    r = _cli(*args)
    assert r.returncode == 0, r.stderr
    assert "1 episodes done before, 1 to run" in r.stderr
    assert len(json.loads((out / "results.json").read_text())["episodes"]) == 2

    r = _cli("leaderboard", str(out))
    assert r.returncode == 0, r.stderr
    assert "| 1 |" in r.stdout and "stand_still" in r.stdout
    for name in ("leaderboard.md", "leaderboard.html", "plots/score_distribution.png",
                 "plots/completion_times.png", "plots/category_points.png"):
        assert (out / name).is_file() and (out / name).stat().st_size > 0, name


def test_a_bad_submission_yaml_is_named(tmp_path):
    subs = tmp_path / "subs"
    shutil.copytree(EXAMPLES / "stand_still", subs / "ok")
    (subs / "bad").mkdir()
    (subs / "bad" / "submission.yaml").write_text("agents: {9: x:Y}\n")
    r = _cli("compete", str(subs), "--tasks", "1", "--seeds", "0:1", "--out",
             str(tmp_path / "o"))
    assert r.returncode == 2
    assert "bad/submission.yaml" in r.stderr


def test_leaderboard_ranks_by_total_then_completion_time(tmp_path):
    from pr2_drake.compete.leaderboard import write_leaderboard

    def row(sub, task, seed, score, t):
        top = {1: 15.0, 4: 10.0}[task]
        return {"submission": sub, "task": task, "seed": seed, "score": score, "max_score": top,
                "termination": "completed" if score == top else "timeout",
                "items": [], "sim_time": t, "wall_time": 1.0}

    rows = [row("slow", 1, 0, 15.0, 40.0), row("slow", 4, 0, 10.0, 30.0),
            row("fast", 1, 0, 15.0, 20.0), row("fast", 4, 0, 10.0, 30.0),
            row("half", 1, 0, 10.0, 50.0), row("half", 4, 0, 5.0, 120.0)]
    (tmp_path / "results.json").write_text(json.dumps({"competition": {}, "episodes": rows}))
    text = write_leaderboard(tmp_path)
    ranks = [line.split("|")[2].strip() for line in text.splitlines() if line.startswith("| ")
             and line.split("|")[1].strip().isdigit()]
    assert ranks == ["fast", "slow", "half"]
    assert "| 1 | fast | none | 25.0 | 15.0 (20.0 s) | 10.0 (30.0 s) |" in text
    assert (tmp_path / "plots" / "category_points.png").stat().st_size > 0
    assert "fast" in (tmp_path / "leaderboard.html").read_text()


# -- every flag checked ---------------------------------------------------------------------------
@pytest.mark.parametrize("args, flag", [
    *[(("compete", "x", "--out", "o", f, v), f) for f in (
        "--seconds", "--step-budget", "--step-wall", "--episode-wall")
      for v in ("-1", "0", "nan", "inf")],
    *[(("compete", "x", "--out", "o", f, v), f) for f in ("--memory-mb", "--jobs")
      for v in ("-1", "0", "nan", "1.5")],
    (("compete", "x", "--out", "o", "--memory-mb", "100"), "--memory-mb"),
    (("compete", "x", "--out", "o", "--isolation", "none"), "--trust-submissions"),
    (("compete", "x", "--out", "o", "--seeds", "a:b"), "--seeds"),
    (("compete", "x", "--out", "o", "--seeds", "4:4"), "--seeds"),
    (("compete", "x", "--out", "o", "--seeds", "-2:1"), "--seeds"),
    (("eval", "--task", "1", "--seeds", "x"), "--seeds"),
    (("eval", "--task", "1", "--jobs", "0"), "--jobs"),
    (("eval", "--seeds", "0:1"), "--task"),
    (("run", "--camera", "big"), "--camera"),
    (("eval", "--task", "1", "--camera", "0x10"), "--camera"),
    (("run", "--memory-mb", "600"), "--memory-mb"),
    (("bench", "camera", "--resolutions", "huge"), "--resolutions"),
])
def test_a_bad_flag_is_one_line_naming_it_with_status_2(args, flag):
    r = _cli(*args)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("pr2-drake: error:"), r.stderr
    assert flag in lines[0]


def test_a_control_period_below_one_physics_step_is_refused():
    r = _cli("run", "--task", "1", "--set", "control_dt=1e-9", "--seconds", "0.1")
    assert r.returncode == 2 and "control_dt must be at least one physics step" in r.stderr


def test_compete_out_on_a_file_is_a_clean_error(tmp_path):
    out = tmp_path / "results"
    out.write_text("not a folder")
    r = _cli("compete", str(EXAMPLES), "--tasks", "1", "--seeds", "0:1", "--out", str(out))
    assert r.returncode == 2 and "is a file" in r.stderr and "Traceback" not in r.stderr


def test_without_any_isolation_compete_refuses_unless_trusted(tmp_path):
    """No bwrap, no unshare on the PATH: one line saying what to install; with
    --trust-submissions it runs, and the results say so."""
    env = {**os.environ, "PATH": str(tmp_path)}  # an empty folder: no bwrap, no unshare
    args = ("compete", str(EXAMPLES / ".."), "--tasks", "1", "--seeds", "0:1", "--seconds",
            "0.05", "--out", str(tmp_path / "o"))
    subs = tmp_path / "subs"
    shutil.copytree(EXAMPLES / "stand_still", subs / "stand_still")
    args = (*args[:1], str(subs), *args[2:])
    r = _cli(*args, env=env)
    assert r.returncode == 2 and "install bubblewrap" in r.stderr, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
    r = _cli(*args, "--trust-submissions", env=env)
    assert r.returncode == 0, r.stderr
    meta = json.loads((tmp_path / "o" / "results.json").read_text())
    assert meta["competition"]["trust_submissions"] is True
    assert meta["episodes"][0]["sandbox"] == "none"


def test_a_resumed_run_trusts_only_rows_with_the_runs_mac(tmp_path):
    from pr2_drake.compete.ledger import append, read_rows, run_key

    key = run_key(tmp_path)
    row = {"submission": "a", "task": 1, "seed": 0, "score": 0.0}
    with open(tmp_path / "episodes.jsonl", "a") as f:
        append(f, row, key)
        f.write(json.dumps({**row, "submission": "b", "score": 15.0}) + "\n")  # no MAC
        f.write(json.dumps({**row, "submission": "c", "score": 15.0, "mac": "0" * 64}) + "\n")
        forged = {**row, "score": 15.0}
        f.write(json.dumps({**forged, "mac": json.loads(
            (tmp_path / "episodes.jsonl").read_text().splitlines()[0])["mac"]}) + "\n")
    done, rejected = read_rows(tmp_path / "episodes.jsonl", run_key(tmp_path))
    assert done == {("a", 1, 0): row} and rejected == 3


# -- run --isolate: the report survives any agent fault -------------------------------------------
ATTACKERS = Path(__file__).with_name("hostile") / "attackers.py"


@pytest.mark.parametrize("agent, termination, message, extra", [
    ("HardExit", "agent_exit", "exited with code 3", ()),
    ("Segfaults", "agent_exit", "signal SIGSEGV", ()),
    ("RaisesKeyboardInterrupt", "agent_error", "KeyboardInterrupt", ()),
    ("Hangs", "agent_timeout", "wall-clock cap", ("--step-budget", "0.5", "--step-wall", "1")),
    ("Leaks", "agent_memory", "memory", ("--memory-mb", "700")),
])
def test_run_isolate_keeps_the_report_through_any_agent_fault(agent, termination, message,
                                                               extra, tmp_path):
    report = tmp_path / "report.json"
    r = _cli("run", "--task", "1", "--agent", f"{ATTACKERS}:{agent}", "--seconds", "5",
             "--set", "start.x=1.0", "--isolate", *extra, "--report", str(report), "--quiet")
    assert r.returncode == 0, r.stderr
    rep = json.loads(report.read_text())
    assert rep["termination"] == termination and message in rep["message"], rep
    assert rep["score"] == 5 and [e["item"] for e in rep["items"]] == ["task_region"]


def test_the_users_ctrl_c_writes_the_report_as_interrupted(tmp_path):
    report = tmp_path / "report.json"
    proc = subprocess.Popen([sys.executable, "-m", "pr2_drake.cli", "run", "--task", "1",
                             "--agent", f"{ATTACKERS}:Slow", "--set", "start.x=1.0",
                             "--seconds", "20", "--isolate", "--report", str(report),
                             "--quiet"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, preexec_fn=_as_in_a_terminal)
    deadline = time.monotonic() + 120
    while not _steps_begun(proc.pid) and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.2)
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    rep = json.loads(report.read_text())
    assert rep["termination"] == "interrupted" and rep["score"] == 5, rep
    assert "ended: interrupted" in out


def _as_in_a_terminal() -> None:
    """The child takes Ctrl-C as a command typed in a terminal does: a suite run as a
    background job (``cmd &`` in a script) hands its children SIGINT ignored."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _steps_begun(pid: int) -> bool:
    """Whether ``pid``'s sandboxed agent has printed that it stepped three times (into the
    log file the harness holds open, unlinked)."""
    try:
        fds = list(Path(f"/proc/{pid}/fd").iterdir())
    except OSError:
        return False
    for fd in fds:
        try:
            if os.readlink(fd).endswith("(deleted)") and fd.read_text(
                    errors="replace").count("stepping") >= 3:
                return True
        except OSError:
            pass
    return False

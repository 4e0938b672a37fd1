"""The pr2-drake command line, run as a user runs it."""

import base64
import json
import re
import subprocess
import sys

import pytest


def _cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "pr2_drake.cli", *args], capture_output=True,
                          text=True, cwd=cwd, timeout=600)


def test_run_writes_report_and_replay(tmp_path):
    report, replay = tmp_path / "report.json", tmp_path / "replay.html"
    out = _cli("run", "--seconds", "0.5", "--report", str(report), "--record", str(replay))
    assert out.returncode == 0, out.stderr
    r = json.loads(report.read_text())
    for key in ("task", "seed", "score", "max_score", "success", "termination", "items",
                "sim_time", "wall_time"):
        assert key in r
    assert r["termination"] == "timeout" and r["sim_time"] == pytest.approx(0.5)
    html = replay.read_text()
    assert "<html" in html.lower() and "meshcat" in html.lower()
    assert "score 0 / 0" in out.stdout
    # No live viewer was asked for: no viewer URL. The replay opens framing the robot.
    assert "http://" not in out.stdout + out.stderr
    commands = [base64.b64decode(c) for c in
                re.findall(r"data:application/octet-binary;base64,([A-Za-z0-9+/=]+)", html)]
    assert any(b"set_target" in c for c in commands)
    assert any(b"/Cameras/default/rotated/<object>" in c and b"position" in c for c in commands)


def test_progress_lines_on_long_runs():
    out = _cli("run", "--seconds", "4")
    assert out.returncode == 0, out.stderr
    assert "real-time factor" in out.stderr


@pytest.mark.parametrize(
    "args, message",
    [
        (("run", "--agent", "nosuchmodule:Agent", "--seconds", "0.1"), "cannot import module 'nosuchmodule'"),
        (("run", "--agent", "pr2_drake.agents:Nope", "--seconds", "0.1"), "has no 'Nope'"),
        (("run", "--agent", "justaname", "--seconds", "0.1"), "module:Class"),
        (("run", "--task", "99"), "unknown task 99"),
        (("run", "--seconds", "-1"), "seconds must be a positive finite number"),
    ],
)
def test_bad_arguments_give_clear_errors(args, message):
    out = _cli(*args)
    assert out.returncode == 2
    assert message in out.stderr
    assert "Traceback" not in out.stderr


def test_eval_summarises_seeds_in_parallel(tmp_path):
    out_file = tmp_path / "results.json"
    out = _cli("eval", "--task", "4", "--seeds", "0:2", "--seconds", "0.3", "--jobs", "2",
               "--out", str(out_file))
    assert out.returncode == 0, out.stderr
    results = json.loads(out_file.read_text())
    assert [e["seed"] for e in results["episodes"]] == [0, 1]
    assert results["summary"]["episodes"] == 2
    assert results["summary"]["terminations"] == {"timeout": 2}
    failures = results["summary"]["failures"]  # 0.3 s: no rubric item earned
    assert list(failures) == ["out of time"]
    assert [(e["seed"], e["missed"]) for e in failures["out of time"]] == [
        (0, "task_region"), (1, "task_region")]
    assert "success rate" in out.stdout and "mean score" in out.stdout
    assert "out of time" in out.stdout and "0: task_region" in out.stdout


def test_run_task_prints_the_rubric():
    out = _cli("run", "--task", "5", "--seconds", "0.2", "--quiet")
    assert out.returncode == 0, out.stderr
    for item in ("onto_step", "over_steps", "touch_button", "touch_button_arm"):
        assert item in out.stdout
    assert "score 0 / 20" in out.stdout


def test_a_reader_that_leaves_early_gets_no_traceback():
    """``pr2-drake tasks | head -1``: the pipe is closed before the program writes."""
    proc = subprocess.Popen([sys.executable, "-m", "pr2_drake.cli", "tasks"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=60) == 141, err
    assert "Traceback" not in err and "BrokenPipe" not in err, err

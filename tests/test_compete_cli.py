"""pr2-drake compete and leaderboard, run as an organiser runs them."""

import csv
import json
import shutil
import subprocess
import sys
from pathlib import Path

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "submissions"


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "pr2_drake.cli", *args], capture_output=True,
                          text=True, timeout=600)


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
    assert "| 1 | fast | 25.0 | 15.0 (20.0 s) | 10.0 (30.0 s) |" in text
    assert (tmp_path / "plots" / "category_points.png").stat().st_size > 0
    assert "fast" in (tmp_path / "leaderboard.html").read_text()

"""The scenario switches (scene.variation, randomize) in eval, compete and the leaderboard:
every run states the switches it used."""

import csv
import json
import shutil
import subprocess
import sys
from pathlib import Path

from pr2_drake.compete.leaderboard import scenario_label, write_leaderboard
from pr2_drake.scenario import load_scenario

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "submissions"


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "pr2_drake.cli", *args], capture_output=True,
                          text=True, timeout=600)


def test_a_scenario_names_the_switches_it_turns_on():
    assert load_scenario(None).switches() == []
    assert load_scenario(None, ["scene.variation=true"]).switches() == ["scene.variation"]


def test_eval_states_the_switches_in_its_summary_and_reports(tmp_path):
    out = tmp_path / "eval.json"
    r = _cli("eval", "--task", "4", "--seeds", "0,1", "--seconds", "0.05", "--jobs", "1",
             "--set", "scene.variation=true", "--out", str(out))
    assert r.returncode == 0, r.stderr
    assert "scenario switches: scene.variation" in r.stdout
    data = json.loads(out.read_text())
    assert data["summary"]["scenario"] == ["scene.variation"]
    angles = set()
    for e in data["episodes"]:
        assert e["scenario"] == ["scene.variation"]
        angles.add(e["variation"]["slope_angle_deg"])
    assert len(angles) == 2  # each seed its own slope


def test_compete_runs_varied_scenes_and_the_leaderboard_says_so(tmp_path):
    subs, out = tmp_path / "subs", tmp_path / "results"
    shutil.copytree(EXAMPLES / "stand_still", subs / "stand_still")
    args = ("compete", str(subs), "--tasks", "4", "--seeds", "0:1", "--seconds", "0.05",
            "--out", str(out))
    r = _cli(*args, "--set", "scene.variation=true")
    assert r.returncode == 0, r.stderr
    data = json.loads((out / "results.json").read_text())
    assert data["competition"]["scenario"] == ["scene.variation"]
    row = data["episodes"][0]
    assert row["scenario"] == ["scene.variation"] and "slope_angle_deg" in row["variation"]
    with open(out / "results.csv") as f:
        assert next(csv.DictReader(f))["scenario"] == "scene.variation"
    text = write_leaderboard(out, plots=False)
    assert "| 1 | stand_still | scene.variation |" in text
    # One folder, one scenario: resuming without the switch is refused, naming both.
    r = _cli(*args)
    assert r.returncode == 2 and "scenario switches scene.variation" in r.stderr, r.stderr
    assert "this run has none" in r.stderr


def test_compete_takes_only_scenario_switches():
    for bad in ("seed=3", "scene.variation=maybe"):
        r = _cli("compete", str(EXAMPLES), "--out", "o", "--set", bad)
        lines = r.stderr.strip().splitlines()
        assert r.returncode == 2 and len(lines) == 1, r.stderr
        assert lines[0].startswith("pr2-drake: error:") and bad.split("=")[0] in lines[0]


def test_the_leaderboard_names_each_set_of_switches_seen():
    rows = [{"scenario": ["scene.variation", "randomize"]}, {}]
    assert scenario_label(rows[:1]) == "scene.variation+randomize"
    assert scenario_label(rows[1:]) == "none"
    assert scenario_label(rows) == "none, scene.variation+randomize"

"""Every fault ends the episode with a named termination and a report that keeps the points."""

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pr2_drake.controllers.standing import StandingController
from pr2_drake.episode import Episode, wire_system
from pr2_drake.run import run_episode
from pr2_drake.scenario import Scenario, ScenarioError
from pr2_drake.scene import StartPose

AGENTS = Path(__file__).with_name("fault_agents.py")
ON_THE_ROAD = StartPose(x=1.0, y=0.0, yaw=0.0)  # task 1: "task_region" (5 points) at once


def _run(agent: str, **kw):
    scenario = Scenario(task=1, seed=0, agent=f"{AGENTS}:{agent}", start=ON_THE_ROAD,
                        seconds=0.4, control_dt=0.01, **kw)
    return run_episode(scenario)


@pytest.mark.parametrize("agent, termination, message", [
    ("NaNAfterPoints", "invalid_action", "action['legs']"),
    ("RaisingPolicy", "agent_error", "ZeroDivisionError"),
    ("ExitingPolicy", "agent_exit", "sys.exit(3)"),
    ("RaisingSystem", "agent_error", "RuntimeError: controller exploded"),
    ("NaNSystem", "invalid_action", "legs_command"),
])
def test_agent_faults_end_the_episode_and_keep_the_score(agent, termination, message):
    r = _run(agent)
    assert r["termination"] == termination, r
    assert message in r["message"]
    assert r["score"] == 5 and [e["item"] for e in r["items"]] == ["task_region"]
    assert 0.1 <= r["sim_time"] < 0.4  # ended at the fault, not at the time limit
    assert not r["success"]


def _standing_episode(**kw) -> Episode:
    episode = Episode(Scenario(task=1, seed=0, start=ON_THE_ROAD, **kw),
                      wire_system(StandingController()))
    episode.initialize()
    episode.advance_to(0.05)
    assert episode.status.score == 5 and not episode.status.done
    return episode


def test_a_state_beyond_physical_bounds_is_diverged_not_fell():
    episode = _standing_episode()
    plant, ctx = episode.testbed.plant, episode.plant_context
    v = plant.GetVelocities(ctx)
    v[:] = 0.0
    v[3:6] = [0.0, 500.0, 0.0]  # the base flying sideways at 500 m/s: finite, not physical
    plant.SetVelocities(ctx, v)
    status = episode.advance_to(0.06)
    assert status.termination == "diverged" and status.score == 5
    assert "max_speed" in episode.message
    assert episode.report()["termination"] == "diverged"


def test_a_non_finite_state_is_diverged():
    episode = _standing_episode()
    ctx = episode.plant_context
    x = ctx.get_mutable_discrete_state_vector()  # (SetPositions refuses NaN)
    x.SetAtIndex(4, np.nan)
    status = episode.advance_to(0.1)
    assert status.termination == "diverged" and status.score == 5


def test_the_divergence_bound_is_a_scenario_setting():
    episode = _standing_episode()
    assert episode.state_fault() == ""
    episode.scenario.limits.max_speed = 1e-9  # the standing robot sways faster than that
    episode.advance_to(0.1)
    assert episode.status.termination == "diverged"


@pytest.mark.parametrize("agent, message", [
    ("NotAnAgent", "neither a Drake System nor has next_action"),
    ("NeedsArgument", "constructor failed: TypeError"),
    ("not_a_class", "is a int, not a class"),
    ("Missing", "has no 'Missing'"),
])
def test_agents_that_cannot_start_raise_a_named_error(agent, message):
    with pytest.raises(ScenarioError, match=message.replace("(", r"\(").replace(")", r"\)")):
        _run(agent)


def _cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "pr2_drake.cli", *args], capture_output=True,
                          text=True, cwd=cwd, timeout=600)


def test_cli_writes_the_report_of_a_faulty_agent_and_exits_0(tmp_path):
    report = tmp_path / "r.json"
    out = _cli("run", "--task", "Rocky_Road", "--agent", f"{AGENTS}:RaisingPolicy",
               "--set", "start={x: 1.0, y: 0.0, yaw: 0.0}", "--set", "control_dt=0.01",
               "--seconds", "0.3", "--quiet", "--report", str(report))
    assert out.returncode == 0, out.stderr
    r = json.loads(report.read_text())
    assert r["termination"] == "agent_error" and r["score"] == 5
    assert "ZeroDivisionError" in out.stdout


@pytest.mark.parametrize("make, args, message", [
    (lambda d: d.joinpath("bad.py").write_text("def broken(:\n"), ("--agent", "{d}/bad.py:A"),
     "SyntaxError"),
    (lambda d: d.joinpath("bad.yaml").write_text("blocks: [\n"), ("{d}/bad.yaml",),
     "bad.yaml: not valid YAML"),
    (lambda d: d.joinpath("s.yaml").write_text("sed: 3\n"), ("{d}/s.yaml",),
     "unknown to the schema"),
    (lambda d: d.joinpath("out").mkdir(), ("--record", "{d}/out"), "is a folder"),
    (lambda d: None, ("--report", "{d}/nowhere/r.json"), "does not exist"),
    (lambda d: None, ("--set", "plant.time_step=-1"), "time_step"),
    (lambda d: None, ("--set", "control_dt=.nan"), "control_dt"),
    (lambda d: None, ("--camera", "100000x100000"), "camera"),
])
def test_cli_refuses_bad_input_before_running_in_one_line(tmp_path, make, args, message):
    make(tmp_path)
    out = _cli("run", "--seconds", "0.1", *(a.format(d=tmp_path) for a in args))
    assert out.returncode == 2, out.stdout + out.stderr
    assert message in out.stderr
    assert "Traceback" not in out.stderr
    assert "t = " not in out.stderr  # nothing was simulated


def test_agent_from_a_file_path_and_task_names_in_any_case(tmp_path):
    agent = tmp_path / "my_agent.py"
    agent.write_text("from pr2_drake.agents.standing import StandingAgent as MyAgent\n")
    out = _cli("run", "--task", "SLOPE", "--agent", f"{agent}:MyAgent", "--seconds", "0.2",
               "--quiet")
    assert out.returncode == 0, out.stderr
    assert "task 4 (slope)" in out.stdout and "my_agent.py:MyAgent" in out.stdout


def test_env_time_limit_without_task_is_unlimited_by_default():
    from pr2_drake.env import Env

    env = Env(seed=0)
    assert math.isinf(env.episode.limit)

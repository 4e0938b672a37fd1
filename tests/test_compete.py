"""Competition harness: every agent in a sandboxed subprocess; cheats and faults end only
their own episode, with a name, and change no score."""

import json
from pathlib import Path

import pytest

from pr2_drake.compete.isolation import NO_BWRAP_ENV, IsolationUnavailable, works
from pr2_drake.compete.proxy import run_sandboxed_episode
from pr2_drake.compete.sandbox import SandboxLimits
from pr2_drake.run import run_episode
from pr2_drake.scenario import Scenario
from pr2_drake.scene import StartPose
from pr2_drake.testbed import DEFAULT_TIME_STEP

HOSTILE = Path(__file__).with_name("hostile") / "hostile_agents.py"
ON_THE_ROAD = StartPose(x=1.0, y=0.0, yaw=0.0)  # task 1: "task_region" (5 points) at once
LIMITS = SandboxLimits(step_seconds=1.0, step_wall_seconds=2.0, startup_seconds=60.0,
                       memory_mb=1024)


def _scenario(agent: str, seconds: float = 0.2, **params) -> Scenario:
    return Scenario(task=1, seed=0, agent=agent, start=ON_THE_ROAD, seconds=seconds,
                    control_dt=0.01, agent_params=params)


def _sandboxed(agent: str, **params) -> dict:
    return run_sandboxed_episode(_scenario(f"{HOSTILE}:{agent}", **params), limits=LIMITS)


@pytest.mark.parametrize("cheat", ["GcTeleport", "FrameReferee", "PatchReferee"])
def test_cheats_that_score_in_process_score_nothing_in_the_sandbox(cheat):
    r = _sandboxed(cheat)
    assert r["sandbox"] in ("bwrap", "unshare")
    assert r["score"] == 5 and [e["item"] for e in r["items"]] == ["task_region"], r
    assert r["termination"] == "timeout" and not r["success"]


def test_the_gc_cheat_is_real_in_process():
    """The same agent run in the referee's process does teleport the robot (why the
    sandbox exists)."""
    r = run_episode(_scenario(f"{HOSTILE}:GcTeleport"))
    assert r["score"] > 5, r


def test_an_exit_hook_cannot_rewrite_the_report(tmp_path):
    report = tmp_path / "report.json"
    report.write_text('{"score": 5.0}')
    r = _sandboxed("AtexitReport", target=str(report))
    assert r["termination"] == "agent_exit" and r["score"] == 5
    assert json.loads(report.read_text()) == {"score": 5.0}


@pytest.mark.parametrize("agent, termination, message", [
    ("WritesOutside", "agent_error", "forbidden call: open("),
    ("OpensSocket", "agent_error", "forbidden call: socket"),
    ("ForkBomb", "agent_error", "forbidden call: os.fork"),
    ("Allocates10GB", "agent_memory", "MemoryError"),
    ("IgnoresSigtermAndSleeps", "agent_timeout", "no answer within the wall-clock cap"),
    ("Spins", "agent_timeout", "s of CPU time"),
    ("HardExit", "agent_exit", "exited with code 7"),
    ("Raises", "agent_error", "KeyError"),
    ("GarbageAction", "invalid_action", "cannot be sent"),
    ("GarbageOnTheChannel", "agent_error", "garbage on the agent channel"),
])
def test_hostile_agents_end_their_episode_labelled_keeping_the_points(agent, termination,
                                                                       message, tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("intact")
    r = _sandboxed(agent, target=str(victim))
    assert r["termination"] == termination, r
    assert message in r.get("message", ""), r
    assert r["score"] == 5 and [e["item"] for e in r["items"]] == ["task_region"]
    assert 0.05 <= r["sim_time"] < 0.2
    assert victim.read_text() == "intact"


def test_the_episode_after_a_hostile_one_is_bit_identical_to_a_clean_one():
    standing = "pr2_drake.agents.standing:StandingAgent"
    first = run_sandboxed_episode(_scenario(standing), limits=LIMITS)
    _sandboxed("PatchReferee")
    again = run_sandboxed_episode(_scenario(standing), limits=LIMITS)
    assert again["state_digest"] == first["state_digest"]
    assert again["score"] == first["score"] == 5


@pytest.mark.parametrize("task, spec", [
    (1, "pr2_drake.controllers.standing:StandingController"),  # periodic unrestricted updates
    (1, "pr2_drake.agents.walk_to_goal:RockyRoadAgent"),  # walking controller: discrete ones
])
def test_a_system_agent_in_the_sandbox_matches_the_same_agent_in_process(task, spec):
    """A Drake System agent stepped across the process boundary every physics step gives the
    same plant state as wired into the testbed, bit for bit."""
    from pr2_drake.agents import instantiate_agent, load_agent_class
    from pr2_drake.compete.proxy import state_digest
    from pr2_drake.drive import drive_blocks
    from pr2_drake.episode import Episode, wire_system
    from pr2_drake.run import agent_params

    scenario = Scenario(task=task, seed=0, agent=spec, seconds=0.3)
    r = run_sandboxed_episode(scenario, limits=LIMITS)
    assert r["steps"] == round(0.3 / DEFAULT_TIME_STEP) and r["termination"] == "timeout"
    cls = load_agent_class(spec)
    episode = Episode(scenario, lambda b, tb: wire_system(instantiate_agent(
        cls, priors=dict(tb.scene.priors), task=task, seed=0, **agent_params(scenario)))(b, tb))
    drive_blocks(episode)
    assert r["state_digest"] == state_digest(episode)


@pytest.mark.parametrize("agent, termination", [
    ("WritesOutside", "agent_error"), ("Allocates10GB", "agent_memory"),
    ("HardExit", "agent_exit")])
def test_without_bubblewrap_namespaces_and_an_unprivileged_user_still_hold(
        agent, termination, tmp_path, monkeypatch):
    monkeypatch.setenv(NO_BWRAP_ENV, "1")  # as if bubblewrap were not installed
    victim = tmp_path / "victim.txt"
    victim.write_text("intact")
    r = run_sandboxed_episode(_scenario(f"{HOSTILE}:{agent}", target=str(victim)),
                              limits=LIMITS)
    assert r["sandbox"] == "unshare"
    assert r["termination"] == termination and r["score"] == 5, r
    assert victim.read_text() == "intact"


def test_no_isolation_only_when_the_organiser_trusts_the_submissions():
    with pytest.raises(IsolationUnavailable, match="--trust-submissions"):
        run_sandboxed_episode(_scenario("pr2_drake.agents.standing:StandingAgent", 0.05),
                              limits=SandboxLimits(isolation="none"))
    r = run_sandboxed_episode(_scenario("pr2_drake.agents.standing:StandingAgent", 0.05),
                              limits=SandboxLimits(isolation="none", trust=True))
    assert r["sandbox"] == "none" and r["termination"] == "timeout" and r["steps"] == 5


def test_the_sandbox_says_which_isolation_it_used():
    r = run_sandboxed_episode(_scenario("pr2_drake.agents.standing:StandingAgent", 0.05),
                              limits=LIMITS)
    assert r["sandbox"] == ("bwrap" if works("bwrap") else "unshare")
    assert r["steps"] == 5 and r["step_time_mean"] > 0 and r["agent_compute_max"] > 0


def test_camera_frames_cross_through_shared_memory():
    from pr2_drake.camera import CameraSettings

    scenario = Scenario(task=6, seed=0, agent=f"{HOSTILE}:NeedsCamera", seconds=0.15,
                        control_dt=0.01, camera=CameraSettings(enabled=True, width=320,
                                                               height=240, fps=20))
    r = run_sandboxed_episode(scenario, limits=LIMITS)
    assert r["termination"] == "timeout", r.get("message")
    assert r["steps"] == 15


def test_other_submissions_are_hidden(tmp_path):
    others = tmp_path / "others"
    others.mkdir()
    (others / "secret_solver.py").write_text("x = 1\n")
    r = run_sandboxed_episode(_scenario(f"{HOSTILE}:ReadsOthers", 0.05, target=str(others)),
                              limits=LIMITS, hide=(others,))
    assert r["termination"] == "timeout", r.get("message")


def test_the_episode_wall_clock_limit_ends_a_slow_agent():
    limits = SandboxLimits(step_seconds=1.0, startup_seconds=60.0, episode_seconds=3.0)
    r = run_sandboxed_episode(_scenario(f"{HOSTILE}:SlowSteps", 10.0), limits=limits)
    assert r["termination"] == "agent_timeout" and "wall-clock limit" in r["message"]
    assert r["score"] == 5 and r["sim_time"] < 10.0


def test_the_step_budget_is_charged_in_cpu_time_not_in_waiting():
    # 1.5 s of wall clock without computing is within a 1 s CPU budget (a machine busy with
    # other episodes starves agents the same way); the 2 s wall-clock cap still holds.
    r = run_sandboxed_episode(_scenario(f"{HOSTILE}:WaitsOnce", 0.1), limits=LIMITS)
    assert r["termination"] == "timeout", r.get("message")
    assert r["score"] == 5 and r["step_time_max"] >= 1.5 and r["steps"] == 10


def test_a_submission_that_cannot_be_imported_is_an_agent_error():
    r = run_sandboxed_episode(_scenario("no_such_module_here:Solver"), limits=LIMITS)
    assert r["termination"] == "agent_error" and "no_such_module_here" in r["message"]
    assert r["steps"] == 0


def test_a_system_agent_gets_only_the_offered_ports():
    r = _sandboxed("PeeksAtPlantState")
    assert r["termination"] == "agent_error" and "ports that are not offered" in r["message"], r
    assert r["steps"] == 0


def test_an_agent_asking_for_a_control_period_below_one_physics_step_is_refused():
    attackers = HOSTILE.with_name("attackers.py")
    r = run_sandboxed_episode(Scenario(task=1, seed=0, agent=f"{attackers}:TinyControlDt",
                                       start=ON_THE_ROAD, seconds=0.2), limits=LIMITS)
    assert r["termination"] == "agent_error" and "control_dt" in r["message"], r
    assert r["steps"] == 0

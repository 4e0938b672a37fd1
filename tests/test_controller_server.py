"""Drop-in for the original PR2 platform's solvers: its observation keys, and its walking
controller's TCP protocol answered by ``pr2-drake controller-server``."""

import json
import socket
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pr2_drake.env import Env
from pr2_drake.run import run_episode
from pr2_drake.observation import observation_from_ports
from pr2_drake.porting.clients import (
    ControllerClient,
    ControllerError,
    InProcessClient,
    request_from_obs,
)
from pr2_drake.porting.controller_server import ControllerServer
from pr2_drake.porting.session import ControllerServerConfig
from pr2_drake.scenario import Scenario
from pr2_drake.testbed import DEFAULT_TIME_STEP

ROOT = Path(__file__).resolve().parents[1]
SOLVER = ROOT / "examples" / "pr2_solver" / "solver.py"
ROUGH = ControllerServerConfig.for_task(1)


@pytest.fixture(scope="module")
def server():
    with ControllerServer("127.0.0.1", 0, log=None) as srv:
        yield srv.start()


def test_an_original_style_solver_walks_task1_through_the_tcp_server():
    """examples/pr2_solver/solver.py (TaskSolverBase style, its own TCP client, one request per
    physics step, no time field) on the rocky road for 5 s via the normal episode path."""
    with ControllerServer("127.0.0.1", 0, ROUGH, log=None) as srv:
        srv.start()
        report = run_episode(Scenario(task=1, seed=0, seconds=5.0, agent=f"{SOLVER}:TaskSolver",
                                      agent_params={"port": srv.address[1]}))
        # one per physics step
        assert srv.requests == round(5.0 / DEFAULT_TIME_STEP) and srv.errors == 0
    assert report["termination"] == "timeout", report  # not "fall"
    # The start region ends at x = 0.2 m and the task region begins at x = 0.6 m.
    assert [e["item"] for e in report["items"]] == ["task_region"], report
    assert report["score"] == 5


def test_error_replies_name_the_fault_and_keep_the_connection(server):
    obs = Env(seed=0).reset()
    good = request_from_obs(obs, 0.0, 0.0, 0.0, -1)
    with ControllerClient(*server.address) as client:
        assert "not valid JSON" in client.request(b'{"q_leg": [1, 2')["error"]
        assert "expected a JSON object" in client.request(b"[1, 2]")["error"]
        assert "not UTF-8" in client.request(b'{"a": "\xff"}')["error"]
        err = client.request({k: v for k, v in good.items() if k != "w_wb"})["error"]
        assert "missing key(s) ['w_wb']" in err
        for bad in (7, 1, 4, -2, "jump", True, 2.5, [3]):
            err = client.request({**good, "change_state": bad})["error"]
            assert f"request['change_state']: unknown value {bad!r}" in err, err
        assert "request['q_leg'] must have 10 entries" in client.request(
            {**good, "q_leg": [0.0] * 9})["error"]
        raw = json.dumps(good).replace('"v_wb": [', '"v_wb": [NaN, ', 1)
        assert "request['v_wb']" in client.request(raw.encode())["error"]
        assert "unknown key(s) ['speed']" in client.request({**good, "speed": 1})["error"]
        assert "unit quaternion" in client.request({**good, "quat_wb": [0, 0, 0, 0]})["error"]
        bad_obs = {"agent": {**obs["agent"], "body_state": {**obs["agent"]["body_state"],
                                                             "world_orient": np.zeros(4)}}}
        with pytest.raises(ControllerError, match="quat_wb"):
            client.get_cmd(bad_obs, 0.0, 0.0, 0.0)
        for state in (-1, 0, False, None, -1.0, 3, 3.0):  # the original's solvers send these
            reply = client.request({**good, "change_state": state})
            assert reply["mode"] == "effort" and len(reply["effort"]) == 10, reply
            assert np.all(np.isfinite(reply["effort"]))
    # A second connection is served too, as a new episode (time restarts).
    with ControllerClient(*server.address) as client:
        assert client.get_cmd(obs, 0.0, 0.0, 0.0)["time"] == 0.0
        assert client.get_cmd(obs, 0.0, 0.0, 0.0)["time"] == pytest.approx(DEFAULT_TIME_STEP)


def test_an_impossible_frame_gets_an_error_then_the_connection_closes(server):
    with socket.create_connection(server.address, timeout=10) as sock:
        sock.sendall(struct.pack(">I", 1 << 30))
        (n,) = struct.unpack(">I", sock.recv(4))
        assert "exceeds" in json.loads(sock.recv(n))["error"]
        assert sock.recv(4) == b""


def test_change_state_2_jumps_once():
    """A solver that sends change_state 2 for 0.1 s on flat ground: one jump (crouch, launch,
    flight, landing), the robot stays up; the repeated 2s do not start another one."""
    env = Env(seed=0)
    obs = env.reset()
    phases = set()
    with ControllerServer("127.0.0.1", 0, log=None) as srv, \
            ControllerClient(*srv.start().address) as client:
        for k in range(2400):
            reply = client.get_cmd(obs, 0.0, 0.0, 0.0, 2 if 200 <= k < 300 else -1)
            phases.add(reply["jump_phase"])
            done, _, obs = env.step({"legs": {"ctrl_mode": reply["mode"],
                                              "joint_values": reply["effort"]}})
            assert not done
    assert reply["jumps"] == 1 and {"CROUCH", "FLIGHT", "LANDING"} <= phases, (reply, phases)
    assert obs["agent"]["body_state"]["world_pos"][2] > 0.5  # standing again


def test_in_process_client_answers_like_the_server(server):
    obs = Env(seed=0).reset()
    local = InProcessClient()
    with ControllerClient(*server.address) as client:
        for _ in range(3):
            a, b = client.get_cmd(obs, 0.2, 0, 0, -1), local.get_cmd(obs, 0.2, 0, 0, -1)
            assert a == b
    assert "unknown value 4" in local.request({**request_from_obs(obs, 0, 0, 0),
                                                "change_state": 4})["error"]


def test_the_cli_serves_the_protocol():
    proc = subprocess.Popen([sys.executable, "-m", "pr2_drake.cli", "controller-server", "--port",
                             "0", "--task", "5"], stdout=subprocess.PIPE,
                            stderr=subprocess.DEVNULL, text=True, cwd=ROOT)
    try:
        line = proc.stdout.readline()
        assert "listening on 127.0.0.1:" in line and "for task 5" in line, line
        port = int(line.split("127.0.0.1:")[1].split()[0])
        obs = Env(seed=0).reset()
        with ControllerClient("127.0.0.1", port) as client:
            assert len(client.get_cmd(obs, 0, 0, 0, -1)["effort"]) == 10
            assert "change_state" in client.request(request_from_obs(obs, 0, 0, 0, 9))["error"]
    finally:
        proc.terminate()
        proc.wait(timeout=10)


# -- the original's observation keys --------------------------------------------------------
def test_the_observation_carries_the_original_keys():
    env = Env(task=3, seed=0)
    obs = env.reset()
    assert obs["current_sim_step"] == 0
    np.testing.assert_array_equal(obs["agent"]["start_pos"], obs["start_pos"])
    np.testing.assert_array_equal(obs["agent"]["start_orient"], obs["start_orient"])
    k, d = obs["agent"]["stiffness"], obs["agent"]["dampings"]
    tb = env.testbed.config
    # The default gains, each capped at what is stable at the physics step.
    limits = env.testbed.stable_gain_limits()
    k_max, d_max = (np.concatenate([limits["arms"][i], limits["legs"][i]]) for i in (0, 1))
    np.testing.assert_array_equal(k, np.minimum([tb.arm_gains[0]] * 8 + [tb.leg_gains[0]] * 10,
                                                k_max))
    np.testing.assert_array_equal(d, np.minimum([tb.arm_gains[1]] * 8 + [tb.leg_gains[1]] * 10,
                                                d_max))
    np.testing.assert_array_equal(obs["obstacle"]["position"], obs["bar_position"])
    np.testing.assert_allclose(obs["obstacle"]["orientation"], [1, 0, 0, 0])  # along x
    q = obs["agent"]["joint_state"]["legs_positions"]
    for _ in range(3):  # the original's effort commands carry empty gain lists: accepted
        _, _, obs = env.step({"legs": {"ctrl_mode": "position", "joint_values": q,
                                       "stiffness": [50.0] * 10, "dampings": []}})
    assert obs["current_sim_step"] == 3
    np.testing.assert_array_equal(obs["agent"]["stiffness"][8:], [50.0] * 10)  # in effect
    np.testing.assert_array_equal(obs["agent"]["dampings"][8:], d[8:])  # the default's


def test_task6_goal_is_the_instruction_sentence():
    """Task 6's priors carry the sentence: ``goal`` is it (the original's layout), without
    building the house: the same function builds every observation."""
    env = Env(seed=0)
    values = env.observation_values()
    values.update(task_feedback={}, instruction="put the cup on the coffee table",
                  score=np.zeros(1))
    obs = observation_from_ports(values, 0.0, {"instruction": "put the cup on the coffee table",
                                               "coffee_table_center": [1, 2, 0.4]},
                                 np.zeros(3), np.array([1.0, 0, 0, 0]))
    assert obs["goal"] == obs["language_instruction"] == "put the cup on the coffee table"
    obs1 = observation_from_ports(values, 0.0, {"goal_center": [4.0, 0, 0]}, np.zeros(3),
                                  np.array([1.0, 0, 0, 0]))
    assert obs1["goal"] == [4.0, 0, 0]  # tasks 1 and 4: unchanged


def test_the_sandboxed_observation_carries_the_original_keys():
    from pr2_drake.compete.proxy import run_sandboxed_episode
    from pr2_drake.compete.sandbox import SandboxLimits

    agent = Path(__file__).with_name("porting_agents.py")
    r = run_sandboxed_episode(Scenario(task=3, seed=0, seconds=0.05, agent=f"{agent}:"
                                       "OriginalKeysAgent"),
                              limits=SandboxLimits(step_seconds=1.0, startup_seconds=60.0))
    assert r["termination"] == "timeout" and r["steps"] == 5, r


def test_a_sandboxed_solver_uses_the_in_process_client():
    """In ``compete`` the agent's sockets are refused; the in-process client answers the same
    calls there (and its replies are the server's: see above)."""
    from pr2_drake.compete.proxy import run_sandboxed_episode
    from pr2_drake.compete.sandbox import SandboxLimits

    agent = Path(__file__).with_name("porting_agents.py")
    r = run_sandboxed_episode(Scenario(task=1, seed=0, seconds=0.3,
                                       agent=f"{agent}:InProcessWalker"),
                              limits=SandboxLimits(step_seconds=2.0, startup_seconds=60.0))
    assert r["termination"] == "timeout" and r["steps"] == round(0.3 / DEFAULT_TIME_STEP), r


@pytest.mark.parametrize("flags, named", [
    (["--max-clients", "0"], "--max-clients"), (["--idle-timeout", "nan"], "--idle-timeout"),
    (["--task", "7"], "unknown task 7"), (["--overrides", "no_such_file.yaml"], "no_such_file"),
    (["--terrain", "stairs"], "terrain 'stairs'"), (["--overrides", "{bad}"], "bad.yaml: while"),
    (["--jumping", "{bad}"], "bad.yaml: while")])
def test_the_cli_refuses_bad_flags(tmp_path, flags, named):
    bad = tmp_path / "bad.yaml"
    bad.write_text("gait: [1, 2\n")  # malformed YAML
    flags = [f.format(bad=bad) for f in flags]
    run = subprocess.run([sys.executable, "-m", "pr2_drake.cli", "controller-server", "--port",
                          "0", *flags], capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert run.returncode == 2 and run.stderr.startswith("pr2-drake: error:"), run.stderr
    assert named in run.stderr and not run.stdout

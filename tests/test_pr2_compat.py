"""The ``pr2`` compatibility package and ``pr2-drake pr2-launch``: a solver folder in the
original platform's layout (tests/pr2_style_solvers/) runs unchanged."""

import json
import socket
import struct
import subprocess
import sys
import time
from io import StringIO
from pathlib import Path

import numpy as np
import pytest

import pr2
from pr2.env import Env
from pr2.solver import TaskSolverBase
from pr2.tcp import PersistentTcpClient, TcpClient, bin2int, bin2json, int2bin, json2bin
from pr2_drake.porting.clients import request_from_obs
from pr2_drake.porting.controller_server import ControllerServer, ServerLimits
from pr2_drake.testbed import DEFAULT_TIME_STEP

ROOT = Path(__file__).resolve().parents[1]
FOLDER = Path(__file__).with_name("pr2_style_solvers")


def pr2_launch(task: int, seconds: float, report: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pr2_drake.cli", "pr2-launch", str(FOLDER),
                           str(task), "--seconds", str(seconds), "--port", "0", "--report",
                           str(report)], capture_output=True, text=True, cwd=ROOT, timeout=300)


@pytest.mark.parametrize("task, seconds", [(1, 3.0), (5, 2.0)])
def test_an_original_style_folder_runs_through_pr2_launch(tmp_path, task, seconds):
    """The folder's own task_launcher.py and task_N_solver (imports of pr2, pr2.env, pr2.solver
    and pr2.tcp only; port 8800 hard-coded) run against the task's server, started on a free
    port: one request per physics step, no error reply (the solvers raise on one), the
    client's exit frame closes the connection, and the report is written."""
    report = tmp_path / "report.json"
    run = pr2_launch(task, seconds, report)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "Task failed" in run.stdout  # a timeout is not a pass
    r = json.loads(report.read_text())
    assert (r["task"], r["termination"], r["sim_time"]) == (task, "timeout", seconds), r
    steps = round(seconds / 0.001)
    assert f"closed after {steps - 1} requests (the client's exit frame)" in run.stderr, \
        run.stderr  # every step but the first (the empty action) asked the server
    assert f"ended timeout at t = {seconds:.3f} s" in run.stdout


def test_a_folder_without_launcher_and_a_failing_solver_still_leave_a_report(tmp_path):
    """Without task_launcher.py, pr2.launcher runs the solver; a solver that raises ends the
    episode agent_error, named in the report, and pr2-launch exits with the launcher's status."""
    solver = tmp_path / "solvers" / "task_3_solver"
    solver.mkdir(parents=True)
    (solver / "__init__.py").write_text("")
    (solver / "task_solver.py").write_text(
        "from pr2.solver import TaskSolverBase\n\n\n"
        "class TaskSolver(TaskSolverBase):\n"
        "    def next_action(self, obs):\n"
        "        if obs['current_sim_step'] == 50:\n"
        "            raise KeyError('mode')\n"
        "        return {}\n")
    report = tmp_path / "report.json"
    run = subprocess.run([sys.executable, "-m", "pr2_drake.cli", "pr2-launch",
                          str(tmp_path / "solvers"), "3", "--port", "0", "--report", str(report),
                          "--seed", "5"], capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert run.returncode == 1 and "KeyError: 'mode'" in run.stderr, run.stderr
    r = json.loads(report.read_text())
    assert (r["termination"], r["message"], r["seed"]) == ("agent_error", "KeyError: 'mode'", 5)
    assert r["sim_time"] == 0.05 and "ended agent_error at t = 0.050 s" in run.stdout


def test_pr2_launch_refuses_bad_input():
    missing = subprocess.run([sys.executable, "-m", "pr2_drake.cli", "pr2-launch", str(FOLDER),
                              "2"], capture_output=True, text=True, cwd=ROOT)
    assert missing.returncode == 2
    assert missing.stderr.startswith("pr2-drake: error:") and "task_2_solver" in missing.stderr
    bad_task = subprocess.run([sys.executable, "-m", "pr2_drake.cli", "pr2-launch",
                               str(FOLDER), "9"], capture_output=True, text=True, cwd=ROOT)
    assert bad_task.returncode == 2 and "unknown task 9" in bad_task.stderr


# -- pr2.env and pr2.sim ------------------------------------------------------------------
def test_env_steps_one_millisecond_and_ends_on_an_invalid_action():
    env = Env(task_num=1, seed=0)
    assert env.testbed_env.testbed.config.time_step == 0.001
    done, success, obs = env.reset()
    assert (done, success, obs["current_sim_step"]) == (False, False, 0)
    done, success, obs = env.step({})  # the launcher's first step
    assert not done and obs["current_sim_step"] == 1
    pr2.sim.step()
    assert pr2.sim.current_time() == pytest.approx(0.002)
    assert pr2.sim.is_playing() and not pr2.sim.is_stopped()
    done, success, obs = env.step({"legs": {"ctrl_mode": "effort", "joint_values": [0.0] * 9}})
    assert (done, success) == (True, False)
    assert env.report()["termination"] == "invalid_action"
    assert "legs" in env.report()["message"]
    assert env.step({})[0]  # after the end: the final result again


def test_task_solver_base_is_abstract():
    with pytest.raises(TypeError):
        TaskSolverBase()

    class Still(TaskSolverBase):
        def next_action(self, obs):
            return {}

    assert Still().next_action({}) == {}


# -- pr2.tcp ------------------------------------------------------------------------------
def test_framing_helpers():
    assert int2bin(258) == b"\x00\x00\x01\x02" and bin2int(int2bin(70000)) == 70000
    data = json2bin({"a": [1.5, "é"]})
    assert data.isascii() and bin2json(data) == {"a": [1.5, "é"]}


@pytest.fixture
def quick_server():
    """A server whose connections idle out after 0.3 s."""
    log = StringIO()
    with ControllerServer("127.0.0.1", 0, log=log,
                          limits=ServerLimits(idle_timeout=0.3)) as srv:
        srv.start()
        srv.log_text = log
        yield srv


def test_clients_exchange_exit_and_reconnect(quick_server):
    obs = Env(task_num=1, seed=0).reset()[2]
    request = json2bin(request_from_obs(obs, 0.0, 0.0, 0.0, -1))
    port = quick_server.address[1]
    assert len(bin2json(TcpClient("0.0.0.0", port).send(request))["effort"]) == 10
    client = PersistentTcpClient("127.0.0.1", port)
    assert bin2json(client.send(request))["time"] == 0.0
    assert bin2json(client.send(request))["time"] == pytest.approx(DEFAULT_TIME_STEP)
    deadline = time.monotonic() + 30
    while "(idle for 0.3 s)" not in quick_server.log_text.getvalue():  # the server closed it
        assert time.monotonic() < deadline, quick_server.log_text.getvalue()
        time.sleep(0.05)
    reply = bin2json(client.send(request))  # reconnected: a new episode
    assert reply["time"] == 0.0 and reply["mode"] == "effort"
    client.close()
    deadline = time.monotonic() + 30
    while "(the client's exit frame)" not in quick_server.log_text.getvalue():
        assert time.monotonic() < deadline, quick_server.log_text.getvalue()
        time.sleep(0.05)


def test_a_zero_length_frame_closes_the_connection_without_a_reply(quick_server):
    obs = Env(task_num=1, seed=0).reset()[2]
    payload = json2bin(request_from_obs(obs, 0.0, 0.0, 0.0, -1))
    with socket.create_connection(quick_server.address, timeout=10) as sock:
        sock.sendall(struct.pack(">I", len(payload)) + payload)
        (n,) = struct.unpack(">I", sock.recv(4))
        assert "effort" in json.loads(_recv(sock, n))
        sock.sendall(struct.pack(">I", 0))
        assert sock.recv(4) == b""  # closed, nothing sent back


def _recv(sock, n):
    data = b""
    while len(data) < n:
        data += sock.recv(n - len(data))
    return data


def test_concurrent_clients_idle_timeout_and_a_full_server():
    """A silent client does not block another; past max_clients a client is told at once."""
    obs = Env(task_num=1, seed=0).reset()[2]
    request = request_from_obs(obs, 0.0, 0.0, 0.0, -1)
    with ControllerServer("127.0.0.1", 0, log=None,
                          limits=ServerLimits(max_clients=2, idle_timeout=30.0)) as srv:
        srv.start()
        silent = socket.create_connection(srv.address, timeout=10)
        talker = PersistentTcpClient(*srv.address)
        for _ in range(3):
            assert "effort" in bin2json(talker.send(json2bin(request)))
        with socket.create_connection(srv.address, timeout=10) as third:
            (n,) = struct.unpack(">I", third.recv(4))
            assert "busy" in json.loads(_recv(third, n))["error"]
            assert third.recv(4) == b""
        talker.close()
        silent.close()
        assert srv.refused == 1 and srv.errors == 0
    np.testing.assert_equal(srv.active, 0)

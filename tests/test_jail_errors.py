"""The sandbox's first program names what keeps an agent from starting (pr2_drake/compete/jail.py).

Run as root, as the harness does: the agent's uid (65534) cannot run a program under a folder
closed to other users (a project cloned into ``mktemp -d``, or a home folder of mode 700), and
the reason must name that folder, not only "Permission denied".
"""

import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from pr2_drake.compete import jail

pytestmark = pytest.mark.skipif(os.geteuid() != 0, reason="drops privileges: needs root")


@pytest.fixture
def open_folder():
    """A folder under /tmp that every user may enter (pytest's own tmp_path is mode 700)."""
    folder = Path(tempfile.mkdtemp(prefix="pr2-jail-", dir="/tmp"))
    folder.chmod(0o755)
    yield folder
    shutil.rmtree(folder)


def _run_jail(program: Path) -> subprocess.CompletedProcess:
    config = {"uid": 65534, "gid": 65534, "seccomp": False}
    return subprocess.run([sys.executable, "-I", "-S", jail.__file__, json.dumps(config), "--",
                           str(program)], capture_output=True, text=True, timeout=30)


def _program(folder: Path) -> Path:
    program = folder / "agent.sh"
    program.write_text("#!/bin/sh\necho started\n")
    program.chmod(0o755)
    return program


def test_a_folder_closed_to_other_users_is_named(open_folder):
    closed = open_folder / "closed"
    closed.mkdir(mode=0o700)
    result = _run_jail(_program(closed))
    assert result.returncode == jail.JAIL_FAILED, result
    assert "started" not in result.stdout
    assert "sandbox: PermissionError" in result.stderr
    assert f"{closed} is closed to other users" in result.stderr
    assert f"chmod o+rx {closed}" in result.stderr


def test_an_open_folder_runs_the_program_as_the_agents_uid(open_folder):
    result = _run_jail(_program(open_folder))
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "started"

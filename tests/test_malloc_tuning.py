"""The allocator setting the ``pr2-drake`` program starts with (pr2_drake/malloc_tuning.py):
when it applies, the restart, and that episodes under it are the same bit for bit."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from pr2_drake import malloc_tuning as mt

NEW = (2, 36)


def test_tuned_env_adds_the_tunable_on_glibc():
    env = mt.tuned_env({"HOME": "/h"}, version=NEW)
    assert env == {"HOME": "/h", "GLIBC_TUNABLES": mt.TUNABLES}


def test_tuned_env_keeps_other_tunables_and_the_users_count():
    env = mt.tuned_env({"GLIBC_TUNABLES": "glibc.malloc.arena_max=2"}, version=NEW)
    assert env["GLIBC_TUNABLES"] == f"glibc.malloc.arena_max=2:{mt.TUNABLES}"
    mine = {"GLIBC_TUNABLES": "glibc.malloc.tcache_count=10"}
    assert mt.tuned_env(mine, version=NEW) == mine


@pytest.mark.parametrize("env, version", [
    ({}, None),                                  # not glibc (no version)
    ({}, (2, 29)),                               # glibc too old for a count of 200
    ({mt.OPT_OUT: "0"}, NEW),                    # the opt-out
])
def test_tuned_env_leaves_the_environment_alone(env, version, monkeypatch):
    monkeypatch.setattr(mt, "glibc_version", lambda: None)
    assert mt.tuned_env(env, version=version) == env


def test_plain_env_undoes_the_restart_only():
    tuned = mt.tuned_env({"GLIBC_TUNABLES": "glibc.malloc.arena_max=2"}, version=NEW)
    tuned[mt.MARKER] = "1"
    assert mt.plain_env(tuned) == {"GLIBC_TUNABLES": "glibc.malloc.arena_max=2"}
    assert mt.plain_env({mt.MARKER: "1", "GLIBC_TUNABLES": mt.TUNABLES}) == {}
    users = {"GLIBC_TUNABLES": mt.TUNABLES}  # set by the user, not by a restart: kept
    assert mt.plain_env(users) == users


_SHOW = ("import os; from pr2_drake.malloc_tuning import restart_tuned; "
         "print('start', flush=True); restart_tuned(); "
         "print(os.environ.get('GLIBC_TUNABLES'), os.environ.get('{marker}'))")


def _child(code, **env):
    base = {k: v for k, v in os.environ.items()
            if k not in ("GLIBC_TUNABLES", mt.MARKER, mt.OPT_OUT)}
    out = subprocess.run([sys.executable, "-c", code], env={**base, **env}, capture_output=True,
                         text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    return out.stdout.split("\n")


@pytest.mark.skipif(mt.glibc_version() is None or mt.glibc_version() < mt.MIN_GLIBC,
                    reason="needs glibc 2.30 or newer")
def test_restart_runs_the_command_again_once_with_the_tunable():
    lines = _child(_SHOW.replace("{marker}", mt.MARKER))
    # "start" twice: the process ran its command line again, then went on once
    assert lines[:3] == ["start", "start", f"{mt.TUNABLES} 1"]
    lines = _child(_SHOW.replace("{marker}", mt.MARKER), **{mt.OPT_OUT: "0"})
    assert lines[:2] == ["start", "None None"]


FINGERPRINT = Path(__file__).resolve().parents[1] / "tools" / "fingerprint.py"


def _state_hash(tmp_path, name, **env):
    """The plant state's SHA-256 at the end of 0.6 s of task 4 seed 0 (tools/fingerprint.py)."""
    out = tmp_path / f"{name}.json"
    _child(f"import runpy, sys; sys.argv = ['fp', '--tasks', '4', '--seconds', '0.6', "
           f"'--out', {str(out)!r}]; runpy.run_path({str(FINGERPRINT)!r}, run_name='__main__')",
           **env)
    return json.loads(out.read_text())[0]["state_sha256"]


def test_an_episode_is_the_same_bit_for_bit_under_the_tunable(tmp_path):
    plain = _state_hash(tmp_path, "plain")
    tuned = _state_hash(tmp_path, "tuned", GLIBC_TUNABLES=mt.TUNABLES)
    assert len(plain) == 64 and tuned == plain

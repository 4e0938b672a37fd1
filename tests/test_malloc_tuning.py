"""The allocator setting the ``pr2-drake`` program starts with (pr2_drake/malloc_tuning.py):
when it applies, the restart, and that episodes under it are the same bit for bit."""

import os
import subprocess
import sys

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


_EPISODE = """
import hashlib, numpy as np
from pr2_drake import episode as em
from pr2_drake.run import run_episode
from pr2_drake.scenario import Scenario
orig = em.Episode.report
def report(self, *a, **k):
    r = orig(self, *a, **k)
    x = np.asarray(self.testbed.GetOutputPort("plant_state").Eval(self.tb_context), float)
    r["sha"] = hashlib.sha256(x.tobytes()).hexdigest()
    return r
em.Episode.report = report
print(run_episode(Scenario(task=4, seed=0, seconds=0.6))["sha"])
"""


def test_an_episode_is_the_same_bit_for_bit_under_the_tunable():
    plain = _child(_EPISODE)[0]
    tuned = _child(_EPISODE, GLIBC_TUNABLES=mt.TUNABLES)[0]
    assert len(plain) == 64 and tuned == plain

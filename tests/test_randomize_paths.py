"""Domain randomisation through every way in: the gymnasium ids (``randomize=True``, the
in-place reset to a new seed), and the CLI's ``run``, ``eval`` and ``compete`` with ``--set
randomize.enabled=true``: each reports the physics of the episode's seed, the same draw."""

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")

import pr2_drake  # noqa: E402,F401  (registers the ids)
from pr2_drake.env import Env  # noqa: E402
from pr2_drake.randomize import RandomizeSettings  # noqa: E402
from pr2_drake.scenario import Scenario  # noqa: E402

SUBMISSIONS = Path(__file__).resolve().parents[1] / "examples" / "submissions"
DRAWN = ("friction", "mass_scale", "base_com_offset", "motor_strength", "joint_damping",
         "armature")


def _rollout(env, seed: int, steps: int = 4):
    """(info["physics"] at reset, the observations and rewards of a fixed action)."""
    obs, info = env.reset(seed=seed)
    out = [np.concatenate([obs[k].ravel() for k in sorted(obs)])]
    action = np.linspace(-0.5, 0.5, env.action_space.shape[0]).astype(np.float32)
    for _ in range(steps):
        obs, reward, *_ = env.step(action)
        out.append(np.concatenate([[reward]] + [obs[k].ravel() for k in sorted(obs)]))
    return info["physics"], out


def test_command_env_draws_the_seeds_physics_and_redraws_it_on_a_reused_diagram():
    """Seed 11 on the diagram built for seed 0 (reset in place), then 12, then 11 again, and
    11 on a diagram built for it: one physics and one trajectory per seed."""
    env = gym.make("pr2_drake/RockyRoadCommand-v0", randomize=True).unwrapped
    built_for_seed_0 = env.episode.diagram
    p11, first = _rollout(env, 11)
    p12, other = _rollout(env, 12)
    p11_again, again = _rollout(env, 11)
    fresh = gym.make("pr2_drake/RockyRoadCommand-v0", randomize=True, reuse=False).unwrapped
    p11_fresh, rebuilt = _rollout(fresh, 11)
    assert env.episode.diagram is built_for_seed_0 and fresh.episode.diagram is not None
    assert p11 == p11_again == p11_fresh
    for key in DRAWN:
        assert p11[key] != p12[key], key
    for x, y, z in zip(first, again, rebuilt):
        assert np.array_equal(x, y) and np.array_equal(x, z)
    assert not np.array_equal(first[-1], other[-1])


def test_joint_env_randomize_reaches_the_valve_and_the_observation():
    """Joint level, task 2: the valve's drawn dynamics in info, the encoders noisy (the same
    seed's first observation differs from the unrandomised one, not the true state)."""
    on = gym.make("pr2_drake/Valve-v0", randomize=True, seconds=0.2).unwrapped
    off = gym.make("pr2_drake/Valve-v0", seconds=0.2).unwrapped
    obs_on, info_1 = on.reset(seed=1)
    obs_off, info_off = off.reset(seed=1)
    assert "physics" not in info_off
    assert set(info_1["physics"]["valve"]) == {"friction_torque", "damping"}
    _, info_2 = on.reset(seed=2)
    assert info_1["physics"]["valve"] != info_2["physics"]["valve"]
    on.reset(seed=1)
    assert np.array_equal(on.episode.testbed.plant.GetPositions(on.episode.plant_context),
                          off.episode.testbed.plant.GetPositions(off.episode.plant_context))
    assert not np.array_equal(obs_on["joints"], obs_off["joints"])


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "pr2_drake.cli", *args], capture_output=True,
                          text=True, timeout=600)


def test_run_eval_and_compete_report_the_same_draw_as_env(tmp_path):
    on = ("--set", "randomize.enabled=true")
    common = ("--task", "1", "--seconds", "0.05")
    run = _cli("run", *common, "--seed", "1", "--quiet", "--report", str(tmp_path / "r.json"),
               *on)
    assert run.returncode == 0, run.stderr
    ev = _cli("eval", *common, "--seeds", "0:2", "--out", str(tmp_path / "e.json"), *on)
    assert ev.returncode == 0, ev.stderr
    subs = tmp_path / "subs"
    shutil.copytree(SUBMISSIONS / "stand_still", subs / "stand_still")
    comp = _cli("compete", str(subs), "--tasks", "1", "--seeds", "1:2", "--seconds", "0.05",
                "--out", str(tmp_path / "c"), *on)
    assert comp.returncode == 0, comp.stderr
    env = Env(task=1, seed=1, scenario=Scenario(randomize=RandomizeSettings(enabled=True)),
              time_limit=0.05)
    expected = json.loads(json.dumps(env.physics))  # as JSON writes it
    ran = json.loads((tmp_path / "r.json").read_text())["physics"]
    evaluated = [e["physics"] for e in json.loads((tmp_path / "e.json").read_text())["episodes"]]
    competed = json.loads((tmp_path / "c" / "results.json").read_text())
    assert ran == evaluated[1] == competed["episodes"][0]["physics"] == expected
    assert evaluated[0]["friction"] != evaluated[1]["friction"]
    assert competed["competition"]["randomize"]["enabled"] is True
    refused = _cli("compete", str(subs), "--tasks", "1", "--out", str(tmp_path / "x"),
                   "--set", "seed=3")
    assert refused.returncode == 2 and "randomize.* keys only" in refused.stderr
    assert not (tmp_path / "x").exists()

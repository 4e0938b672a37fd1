"""Reference agents of tasks 1 (rocky road) and 4 (slope): terrain models, swing shaping, and
short closed-loop runs on the task scenes (the full-episode success rates come from
``pr2-drake eval``)."""

import math

import numpy as np
import pytest

from pr2_drake.agents.walk_to_goal import RockyRoadAgent, SlopeAgent
from pr2_drake.controllers.planning.terrain import FlatTerrain, RoughTerrain, SlopeTerrain
from pr2_drake.controllers.planning.swing import SwingTrajectory
from pr2_drake.controllers.walking_params import WalkingParams
from pr2_drake.episode import Episode, wire_system
from pr2_drake.ports import P_WB
from pr2_drake.scenario import Scenario
from pr2_drake.tasks import task_entry

SLOPE = math.radians(7.0)


def test_slope_terrain_follows_the_incline_up_to_the_top():
    terrain = SlopeTerrain(SLOPE, goal=[4.5, 0.0], z_top=0.307)
    stance = np.array([1.5, 0.1, 0.06, 0.0])
    on_slope = math.tan(SLOPE)
    z, pitch = terrain.foothold(stance, on_slope, np.array([1.75, -0.1, 0.0, 0.0]))
    assert z == pytest.approx(0.06 + 0.25 * on_slope, abs=3e-3)  # rises along +x (goal side)
    assert pitch == pytest.approx(-SLOPE, abs=0.02)  # toe up
    # Stance on level ground: a level foothold at the stance height.
    assert terrain.foothold(stance, 0.01, np.array([1.75, 0.0, 0.0, 0.0])) == (0.06, 0.0)
    # Near the plateau: capped at its height, level.
    z, pitch = terrain.foothold(np.array([3.4, 0.0, 0.29, 0.0]), on_slope,
                                np.array([3.65, 0.0, 0.0, 0.0]))
    assert z == pytest.approx(0.307) and pitch == 0.0


def test_rough_and_flat_terrain_footholds():
    stance = np.array([1.0, 0.0, 0.02, 0.3])
    target = np.array([1.2, 0.1, 0.5, 0.3])
    assert FlatTerrain().foothold(stance, 0.1, target) == (0.02, 0.0)
    assert RoughTerrain(0.025).foothold(stance, 0.1, target) == (pytest.approx(-0.005), 0.0)


def test_swing_lift_fraction_and_pitch():
    start = np.array([0.0, 0.1, 0.0, 0.0])
    target = np.array([0.2, 0.1, 0.03, 0.0])
    sw = SwingTrajectory(0.0, 0.35, start, target, 0.07, 0.9, lift_fraction=0.15)
    sw.pitch_target = -SLOPE
    p, *_ = sw.evaluate(0.1 * 0.315)  # tau = 0.1: lifting, not yet moving forward
    assert p[0] == pytest.approx(0.0) and p[2] > 0.003
    p, *_ = sw.evaluate(0.5 * 0.315)
    assert 0.05 < p[0] < 0.1 and p[2] > 0.07  # forward motion starts late, catches up later
    p, v, *_ = sw.evaluate(0.315)
    assert np.allclose(p, target[:3]) and np.allclose(v, 0.0)
    assert sw.pitch()[0] == pytest.approx(-SLOPE)


def test_walking_parameter_overrides_keep_the_rest():
    base = WalkingParams.load()
    rough = base.with_overrides("params/controllers/walking_rough.yaml")
    assert rough.gait.blocked_touchdown_error > 0 and base.gait.blocked_touchdown_error == 0
    assert rough.gait.single_support == base.gait.single_support
    assert rough.qp == base.qp


def test_default_agents_of_tasks_1_and_4():
    assert task_entry(1).agent == "pr2_drake.agents.walk_to_goal:RockyRoadAgent"
    assert task_entry(4).agent == "pr2_drake.agents.walk_to_goal:SlopeAgent"


def _run(task: int, agent_cls, seconds: float, seed: int = 0):
    episode = Episode(Scenario(task=task, seed=seed), lambda b, tb: wire_system(
        agent_cls(priors=tb.scene.priors, **task_entry(task).agent_params))(b, tb))
    simulator, testbed, ctx = episode.simulator, episode.testbed, episode.tb_context
    simulator.Initialize()
    z_max = -np.inf
    t = 0.0
    while t < seconds - 1e-9:
        t = min(t + 0.25, seconds)
        simulator.AdvanceTo(t)
        status = testbed.GetOutputPort("episode").Eval(ctx)
        p = testbed.GetOutputPort("body_state").Eval(ctx)[P_WB]
        z_max = max(z_max, p[2])
        if status.done:
            break
    return status, p, z_max


def test_slope_agent_walks_onto_the_ramp():
    status, p, z_max = _run(4, SlopeAgent, 7.5)
    assert not status.done, status.termination  # no fall
    assert "task_region" in [e.item for e in status.items]
    assert p[0] > 1.5 and p[2] > 0.58 + 0.04  # on the ramp, base higher than standing on flat


def test_rocky_road_agent_walks_onto_the_stones():
    status, p, _ = _run(1, RockyRoadAgent, 7.5)
    assert not status.done, status.termination
    assert "task_region" in [e.item for e in status.items]
    assert p[0] > 1.0  # 0.4 m onto the road (it starts at x = 0.6)

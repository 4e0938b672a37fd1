"""Footholds with height: the planar-patch terrain, footholds on treads, the swing over an edge,
and one 0.10 m step climbed in closed loop (pr2_drake.controllers.planning.{terrain,tread_steps},
pr2_drake.bench.stairs)."""

from __future__ import annotations

import numpy as np
import pytest

from pr2_drake.bench.rigs import StairsSim
from pr2_drake.bench.stairs import LANE_GAIN
from pr2_drake.controllers.planning.swing import SwingTrajectory
from pr2_drake.controllers.planning.terrain import (
    PatchTerrain,
    PlanarPatch,
    stairs_from_priors,
    stairs_terrain,
)
from pr2_drake.controllers.planning.tread_steps import (
    BESIDE,
    TreadFootstepPlanner,
    TreadPlannerParams,
)
from pr2_drake.controllers.walking_params import WalkingParams
from tests._locomotion_sim import scene_geometry

PARAMS = WalkingParams.load().with_overrides("params/controllers/walking_stairs.yaml")
HALF_FOOT = 0.075  # [m] sole centre to heel / toe


def test_stairs_from_the_task_priors_match_the_scene_on_every_tread_and_the_floor():
    _, scene, *_ = scene_geometry(5, seed=0)
    p = scene.priors
    terrain = stairs_from_priors(p)
    x0, d, h, n = p["step_start_x"], p["step_depth"], p["step_height"], p["step_count"]
    assert terrain.height(x0 - 0.3, 0.0) == 0.0
    for k in range(n):
        for x in (x0 + k * d + 0.02, x0 + (k + 0.5) * d, x0 + (k + 1) * d - 0.02):
            for y in (-0.8, 0.0, 0.8):
                assert terrain.height(x, y) == pytest.approx((k + 1) * h)
                assert terrain.height(x, y) == pytest.approx(scene.ground_height(x, y))
    floor = x0 + n * d + 0.5
    assert terrain.height(floor, 0.3) == pytest.approx(n * h) == scene.ground_height(floor, 0.3)
    np.testing.assert_allclose(terrain.normal(floor, 0.0), [0.0, 0.0, 1.0])
    assert [dz for _, dz in terrain.risers()] == pytest.approx([h] * n)


def test_a_sloped_patch_answers_height_normal_and_landing_pitch():
    ramp = PatchTerrain([PlanarPatch(0.0, 2.0, -1.0, 1.0, z=0.1, gx=0.1)])
    assert ramp.height(1.5, 0.0) == pytest.approx(0.15)
    n = ramp.normal(1.0, 0.0)
    assert n[0] < 0 and n[2] > 0.99
    z, pitch = ramp.foothold(None, 0.0, np.array([1.5, 0.0, 0.0, 0.0]))
    assert z == pytest.approx(0.15) and pitch == pytest.approx(-np.arctan(0.1))  # toe up


def test_heights_along_a_line_are_the_pointwise_heights_bit_for_bit():
    """The swing planner samples the ground along its path at every tick, all samples at once;
    each must be what :meth:`PatchTerrain.height` gives for that point (the highest patch,
    sloped or level, or the base), to the last bit."""
    rng = np.random.default_rng(3)
    patches = [PlanarPatch(0.0, 2.0, -1.0, 1.0, z=0.1, gx=0.07, gy=-0.03),
               PlanarPatch(0.5, 1.0, -0.2, 0.3, z=0.25),  # a box on the ramp
               PlanarPatch(0.8, 1.6, -0.5, 0.5, z=0.12),  # lower than the ramp in parts
               PlanarPatch(-np.inf, np.inf, 0.9, 1.5, z=-0.05)]
    terrain = PatchTerrain(patches, base=0.02)
    for _ in range(300):
        x, y = rng.uniform(-0.5, 2.5, 2)
        yaw, s0 = rng.uniform(-np.pi, np.pi), rng.uniform(-0.3, 0.0)
        s1 = s0 + rng.uniform(0.0, 0.8)
        z = terrain.heights_along(x, y, yaw, s0, s1)
        d = np.linspace(s0, s1, len(z))
        assert len(z) == max(int(np.ceil((s1 - s0) / 0.005)), 1) + 1
        expected = [terrain.height(x + np.cos(yaw) * t, y + np.sin(yaw) * t) for t in d]
        assert z.tolist() == expected
    assert terrain.heights_along(3.0, 0.0, 0.0, 0.0, 0.1).tolist() == [0.02] * 21  # base


def test_a_riser_taller_than_the_planner_limit_is_refused_naming_the_terrain():
    tall = stairs_terrain(1.0, 2, 0.20, 0.40, 2.0)
    with pytest.raises(ValueError, match=r"stairs\(2 x 0.200 m risers.*0.200 m riser at "
                                         r"x = 1.000 m.*max_step_height"):
        TreadFootstepPlanner(PARAMS.gait, 0.01, tall)


def _plan(terrain, x0=0.55, steps=24, speed=0.25, params=None):
    planner = TreadFootstepPlanner(PARAMS.gait, 0.01, terrain, params)
    feet = [np.array([x0, 0.11, 0.0, 0.0]), np.array([x0, -0.11, 0.0, 0.0])]
    side = 1  # right foot first
    out = []
    for _ in range(steps):
        planner.observe(feet)
        stance = 1 - side
        step = planner.next_steps(feet[stance], stance, 0.0, np.array([speed, 0.0, 0.0]), 1)[0]
        out.append((side, feet[side].copy(), step))
        feet[side] = step
        side = 1 - side
    return out


@pytest.mark.parametrize("height", [0.05, 0.10, 0.12])
def test_footholds_land_on_treads_and_step_to_over_each_riser(height):
    terrain = stairs_terrain(1.0, 2, height, 0.40, 2.0, floor_length=1.2, down=True)
    params = TreadFootstepPlanner(PARAMS.gait, 0.01, terrain).params
    # One riser stride: from the toe approach_margin short of the edge (a sole beside the
    # stance one: up to BESIDE behind it) to the heel edge_margin
    # past it.
    riser_stride = 2 * HALF_FOOT + params.approach_margin + params.edge_margin + BESIDE
    levels = set()
    for side, start, step in _plan(terrain):
        assert terrain.on_one_level(step)  # heel and toe (plus margin) on one tread
        assert step[2] == pytest.approx(terrain.height(step[0], step[1]))
        if abs(step[2] - start[2]) > 1e-6:  # a step up or down
            assert abs(step[2] - start[2]) == pytest.approx(height)
            assert abs(step[0] - start[0]) < riser_stride  # step-to: one riser stride
        levels.add(round(step[2], 3))
    assert levels == {round(k * height, 3) for k in range(3)}  # up both steps and down again


def test_a_sole_that_changes_level_next_starts_its_swing_clear_of_the_riser():
    """The soles stopping short of a riser keep approach_margin from it (the rear toe rises
    before it moves on instead of catching the nosing)."""
    terrain = stairs_terrain(1.0, 2, 0.12, 0.40, 2.0, floor_length=1.2, down=True)
    params = TreadPlannerParams.load()
    params.approach_margin = margin = params.edge_margin + 0.04
    plan = _plan(terrain, steps=30, params=params)
    checked = 0
    for k, (side, start, step) in enumerate(plan):
        later = [s for sd, _, s in plan[k + 1:] if sd == side]
        if not later or abs(later[0][2] - step[2]) < 1e-6:
            continue  # this sole's next step stays on its level
        ahead = terrain.edges_along(step[0], step[1], 0.0, 0.0, 0.5)
        assert ahead[0] - HALF_FOOT >= margin - 0.006  # toe to edge (to the edge sampling)
        checked += 1
    assert checked >= 8  # both soles, at each of the four risers


def test_the_swing_over_a_riser_clears_it_with_toe_and_heel_and_lands_flat():
    terrain = stairs_terrain(1.0, 1, 0.10, 0.40, 2.0)
    start = np.array([1.0 - HALF_FOOT - 0.03, 0.11, 0.0, 0.0])
    target = np.array([1.0 + HALF_FOOT + 0.03, 0.11, 0.10, 0.0])
    g = PARAMS.gait
    swing = SwingTrajectory(0.0, g.single_support, start, target, g.swing_height,
                            g.swing_land_fraction)
    swing.clear_z = terrain.swing_clearance(start, target)
    swing.clear_fractions = (g.swing_clear_lift, g.swing_clear_lower)
    assert swing.clear_z == pytest.approx(0.10 + terrain.clearance)
    for t in np.linspace(0.0, swing.t_land, 200):
        p, *_ = swing.evaluate(t)
        for end in (-HALF_FOOT, HALF_FOOT):  # heel, toe: above the ground under them
            assert p[2] >= terrain.height(p[0] + end, p[1]) - 1e-9
    p, v, *_ = swing.evaluate(swing.t_land)
    np.testing.assert_allclose(p, target[:3], atol=1e-9)
    np.testing.assert_allclose(v, 0.0, atol=1e-9)
    assert swing.pitch() == (0.0, 0.0)  # lands flat


def test_a_step_down_moves_early_and_lowers_only_once_its_heel_is_past_the_edge():
    """Down a 0.12 m riser (edge at x = 1.0): the sole moves forward from
    ``swing_down_move_start`` and stays at the clearance height until its heel is
    ``swing_down_heel_margin`` past the edge; then it lowers and lands flat on the target.
    A step up keeps the lift-then-move curve."""
    terrain = stairs_terrain(-1.0, 1, 0.12, 2.0, 2.0, floor_length=0.0)  # 0.12 m up to x = 1
    g = PARAMS.gait
    start = np.array([1.0 - HALF_FOOT - 0.03, 0.11, 0.12, 0.0])
    target = np.array([1.0 + HALF_FOOT + 0.05, 0.11, 0.0, 0.0])
    swing = SwingTrajectory(0.0, g.single_support, start, target, g.swing_height,
                            g.swing_land_fraction)
    swing.plan_over_terrain(terrain, g)
    clear_z = 0.12 + terrain.clearance
    assert swing.clear_z == pytest.approx(clear_z) and swing.step_down is not None
    lowered = moved = None
    for t in np.linspace(0.0, swing.t_land, 400):
        p, *_ = swing.evaluate(t)
        tau = swing.progress
        if moved is None and p[0] > start[0] + 1e-6:
            moved = tau
        heel = p[0] - HALF_FOOT
        if heel < 1.0 + g.swing_down_heel_margin - 1e-9:
            assert p[2] >= min(clear_z, terrain.height(p[0] + HALF_FOOT, p[1])) - 1e-9
        if lowered is None and tau > 0.5 and p[2] < clear_z - 1e-6:
            lowered = tau
    assert moved == pytest.approx(g.swing_down_move_start, abs=0.01)
    assert lowered is not None and lowered > 1.0 - g.swing_clear_lower
    p, v, *_ = swing.evaluate(swing.t_land)
    np.testing.assert_allclose(p, target[:3], atol=1e-9)
    np.testing.assert_allclose(v, 0.0, atol=1e-9)
    up = SwingTrajectory(0.0, g.single_support, np.array([target[0], 0.11, 0.0, 0.0]), start,
                         g.swing_height, g.swing_land_fraction)
    up.plan_over_terrain(terrain, g)
    assert up.clear_z is not None and up.step_down is None


def test_one_step_up_ends_with_both_soles_on_the_tread_without_a_fall():
    terrain = stairs_terrain(0.6, 1, 0.10, 0.40, 2.0, floor_length=2.0)
    sim = StairsSim(terrain)
    assert sim.walk(0.25, x_end=1.4, timeout=20.0)  # no fall; stands after the step
    for side in (0, 1):
        heel, toe = sim.sole_points(side)
        for point in (heel, toe):
            assert point[0] > 0.6 + 0.01  # past the riser
            assert point[2] == pytest.approx(0.10, abs=0.01)  # on the tread
    assert int(sim.status()[3]) == 0  # standing


def test_one_step_down_of_0_12_m_lands_both_soles_on_the_floor_without_a_fall():
    """0.12 m down (the CoM descends before the swing sole reaches the lower floor:
    com_height_step_down)."""
    terrain = stairs_terrain(-1.0, 1, 0.12, 0.40, 2.0, floor_length=1.2)  # edge at x = 0.6
    sim = StairsSim(terrain)
    assert sim.walk(0.25, x_end=1.3, timeout=20.0, lane_gain=LANE_GAIN), sim.fall
    for side in (0, 1):
        for point in sim.sole_points(side):
            assert point[0] > 0.6 + 0.01 and point[2] == pytest.approx(0.0, abs=0.01)
    assert int(sim.status()[3]) == 0  # standing


def _stop_before_riser():
    """A tread planner, a stance sole and the planned step-to stop beside it, short of the
    0.10 m riser at x = 1.0 (both on the ground)."""
    terrain = stairs_terrain(1.0, 2, 0.10, 0.40, 2.0)
    planner = TreadFootstepPlanner(PARAMS.gait, 0.01, terrain)
    stop_x = 1.0 - HALF_FOOT - planner.params.approach_margin - 0.002
    stance = np.array([stop_x - 0.01, -0.11, 0.0, 0.0])
    planned = np.array([stop_x, 0.11, 0.0, 0.0])
    planner.observe([planned - [0.15, 0, 0, 0], stance])
    return terrain, planner, stance, planned


def _catch(planner, planned, stance, wishes, progress=0.05):
    out = None
    for w in wishes:
        out = planner.catch_step(np.array([planned[0] + w, planned[1]]), planned, stance,
                                 progress)
    return out


def test_a_stop_before_a_riser_steps_up_at_once_when_the_dcm_runs_ahead():
    from pr2_drake.controllers.planning.tread_steps import CATCH_MIN_TICKS
    terrain, planner, stance, planned = _stop_before_riser()
    p = planner.params
    far = p.catch_excess + 0.06  # the wish [m] past the stop's front limit
    # Not before CATCH_MIN_TICKS calls ...
    assert _catch(planner, planned, stance, [far] * (CATCH_MIN_TICKS - 1)) is None
    # ... then onto the tread: heel (plus the margin) past the edge, within the stride limit.
    step = _catch(planner, planned, stance, [far])
    assert step is not None
    assert step[2] == pytest.approx(0.10) and terrain.on_one_level(step)
    assert 1.0 + p.edge_margin <= step[0] - HALF_FOOT <= 1.0 + p.edge_margin + 0.01
    assert step[1] == planned[1] and step[3] == planned[3]
    assert step[0] - stance[0] <= PARAMS.gait.max_step_forward + 0.05


def test_a_stop_keeps_its_plan_for_noise_a_small_excess_or_a_late_swing():
    _, planner, stance, planned = _stop_before_riser()
    p = planner.params
    # Single ticks past the threshold whose mean is below it (sensor noise): kept.
    noisy = [p.catch_excess + 0.05, p.catch_excess - 0.08] * 6
    assert _catch(planner, planned, stance, noisy) is None
    _, planner, stance, planned = _stop_before_riser()
    assert _catch(planner, planned, stance, [p.catch_excess - 0.01] * 20) is None
    _, planner, stance, planned = _stop_before_riser()
    late = p.catch_phase + 0.01
    assert _catch(planner, planned, stance, [p.catch_excess + 0.2] * 20, late) is None


def test_a_step_up_is_not_caught_again_and_a_stride_too_long_is_refused():
    _, planner, stance, planned = _stop_before_riser()
    far = [planner.params.catch_excess + 0.1] * 10
    up = np.array([1.0 + HALF_FOOT + 0.04, 0.11, 0.10, 0.0])
    assert _catch(planner, up, stance, far) is None  # already changes level
    behind = stance - [0.2, 0, 0, 0]  # the stance sole 0.2 m further back: out of reach
    assert _catch(planner, planned, behind, far) is None


@pytest.mark.parametrize("bad", [dict(catch_excess=0.0), dict(catch_excess=float("nan")),
                                 dict(catch_phase=1.5), dict(catch_phase=float("nan"))])
def test_bad_catch_settings_are_refused_naming_them(bad):
    import dataclasses
    params = dataclasses.replace(TreadPlannerParams.load(), **bad)
    with pytest.raises(ValueError, match="catch_excess must be > 0.*catch_phase"):
        TreadFootstepPlanner(PARAMS.gait, 0.01, stairs_terrain(1.0, 2, 0.10, 0.40, 2.0), params)


@pytest.mark.parametrize("bad", [dict(swing_down_move_start=-0.1),
                                 dict(swing_down_move_start=0.9),
                                 dict(swing_down_heel_margin=float("nan")),
                                 dict(swing_down_heel_margin=0.5)])
def test_bad_step_down_settings_are_refused_naming_them(bad):
    import dataclasses
    params = dataclasses.replace(PARAMS, gait=dataclasses.replace(PARAMS.gait, **bad))
    with pytest.raises(ValueError, match="swing_down_move_start.*swing_down_heel_margin"):
        params.check()

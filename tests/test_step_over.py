"""Stepping over a low obstacle: footholds off it, a high swing over it, and the closed loop
over a 0.06 m box (pr2_drake.controllers.planning.step_over)."""

from __future__ import annotations

import numpy as np
import pytest

from pr2_drake.bench.rigs import StairsSim
from pr2_drake.controllers.planning.footsteps import VelocityFootstepPlanner
from pr2_drake.controllers.planning.step_over import Obstacle, StepOverFootstepPlanner
from pr2_drake.controllers.planning.terrain import PatchTerrain
from pr2_drake.controllers.walking_params import WalkingParams

PARAMS = WalkingParams.load()
BOX = Obstacle(0.60, 0.65, -1.0, 1.0, 0.06, "box")
HALF_FOOT = 0.075  # [m] sole centre to heel / toe


def _velocity():
    return VelocityFootstepPlanner(PARAMS.gait, PARAMS.limits.start_threshold)


def _walk_plan(planner, steps=12, speed=0.2):
    feet = [np.array([0.0, 0.11, 0.0, 0.0]), np.array([0.0, -0.11, 0.0, 0.0])]
    side, out = 1, []
    for _ in range(steps):
        planner.observe(feet)
        stance = 1 - side
        step = planner.next_steps(feet[stance], stance, 0.0, np.array([speed, 0.0, 0.0]), 1)[0]
        out.append((side, feet[side].copy(), step, feet[stance].copy()))
        feet[side] = step
        side = 1 - side
    return out


def test_footholds_stay_off_the_box_and_only_swings_over_it_are_high():
    planner = StepOverFootstepPlanner(_velocity(), [BOX], clearance=0.05, margin=0.03)
    crossed = 0
    for side, start, step, stance in _walk_plan(planner):
        # Heel and toe (plus the margin) never over the box.
        assert step[0] + HALF_FOOT + 0.03 <= BOX.x_min + 1e-6 or (
            step[0] - HALF_FOOT - 0.03 >= BOX.x_max - 1e-6)
        assert planner.is_free(step)
        assert step[0] - stance[0] <= planner.reach + 1e-9  # within the stride limit
        clear = planner.swing_clearance(start, step)
        if start[0] < BOX.x_min < step[0]:
            crossed += 1
            assert clear == pytest.approx(BOX.top + 0.05)
        else:
            assert clear is None
    assert crossed == 2  # both soles stepped over it


def test_with_the_option_off_the_planner_is_the_wrapped_one():
    plain = _walk_plan(_velocity())
    wrapped = _walk_plan(StepOverFootstepPlanner(_velocity()))
    for (_, _, a, _), (_, _, b, _) in zip(plain, wrapped):
        np.testing.assert_array_equal(a, b)
    planner = StepOverFootstepPlanner(_velocity())
    start, target = np.array([0.0, 0.1, 0.0, 0.0]), np.array([0.2, 0.1, 0.0, 0.0])
    assert planner.swing_clearance(start, target) is None
    planner.swing_apex = 0.12  # per command: every swing high
    assert planner.swing_clearance(start, target) == pytest.approx(0.12)
    planner.swing_apex = None
    assert planner.swing_clearance(start, target) is None


def test_bad_obstacles_and_options_raise_naming_them():
    with pytest.raises(ValueError, match="empty rectangle"):
        Obstacle(0.6, 0.5, -1.0, 1.0, 0.06)
    with pytest.raises(ValueError, match="finite"):
        Obstacle(0.5, 0.6, -1.0, 1.0, float("nan"))
    with pytest.raises(ValueError, match="obstacles\\[0\\]"):
        StepOverFootstepPlanner(_velocity(), [(0.5, 0.6, -1.0, 1.0, 0.06)])
    with pytest.raises(ValueError, match="swing_apex"):
        StepOverFootstepPlanner(_velocity(), swing_apex=-0.1)


def test_the_robot_steps_over_a_6cm_box_without_touching_it_or_falling():
    # The rig's own walking parameters (walking.yaml + walking_stairs.yaml: swings over an edge
    # lift longer before they move). With walking.yaml's alone the second sole's toe crossed
    # the box's near edge 2.5 mm above it (1 ms, "lagged"): any change of the walk's physics
    # (the 2 ms step, the "similar" contact approximation) made it graze; with these, 4 cm.
    planner = StepOverFootstepPlanner(_velocity(), [BOX])
    sim = StairsSim(PatchTerrain([]), footsteps=planner, obstacles=[BOX])
    touched = []
    lowest_over_box = [np.inf]

    def log(s):
        if s.touching(s.obstacle_ids):
            touched.append(s.time)
        for side in (0, 1):
            for point in s.sole_points(side):
                if BOX.x_min <= point[0] <= BOX.x_max:
                    lowest_over_box[0] = min(lowest_over_box[0], point[2])

    assert sim.walk(0.2, x_end=1.1, timeout=12.0, check_every=0.01, log=log)  # no fall
    assert touched == []
    assert lowest_over_box[0] > BOX.top  # heel and toe passed above its top
    for side in (0, 1):  # both soles past the box, on the ground
        heel, toe = sim.sole_points(side)
        assert heel[0] > BOX.x_max and abs(heel[2]) < 0.01 and abs(toe[2]) < 0.01

"""Task 5's sequencer: the WALK command (pr2_drake.agents.steps_button.walk_velocity) and the
stairs span the agent takes from its priors."""

import numpy as np
import pytest

from pr2_drake.agents.steps_button import (
    StepsButtonParams,
    StepsButtonSequencer,
    walk_velocity,
)

P = StepsButtonParams.load()
STAIRS = (1.0 - P.stairs_lead, 1.8)  # the default scene: risers from x = 1.0, two 0.4 m treads


def test_far_from_the_stand_point_it_walks_at_walk_speed_and_steers_sideways():
    vx, vy = walk_velocity(2.0, 0.3, 0.0, P, STAIRS)
    assert vx == pytest.approx(P.walk_speed)
    assert vy == pytest.approx(P.max_lateral_speed)  # capped
    assert walk_velocity(2.0, -0.02, 0.0, P, STAIRS)[1] == pytest.approx(-P.lateral_gain * 0.02)


def test_over_the_steps_the_forward_command_is_capped():
    assert P.stairs_speed < P.walk_speed
    for x in (STAIRS[0] + 0.01, 1.2, 1.79):
        assert walk_velocity(2.0, 0.0, x, P, STAIRS)[0] == pytest.approx(P.stairs_speed)
    assert walk_velocity(2.0, 0.0, 1.85, P, STAIRS)[0] == pytest.approx(P.walk_speed)
    assert walk_velocity(2.0, 0.0, 1.2, P, None)[0] == pytest.approx(P.walk_speed)


def test_past_the_stand_point_with_a_lateral_error_it_backs_up_instead_of_walking_on():
    """A robot that drifted sideways reached the stand point's x with 0.2 m left to go
    sideways: the old command kept 0.05 m/s forward and walked it into the button's post."""
    vx, vy = walk_velocity(-0.05, 0.2, 3.3, P, STAIRS)
    assert vx == pytest.approx(-P.approach_gain * 0.05)
    assert vy == pytest.approx(P.max_lateral_speed)
    assert walk_velocity(-1.0, 0.2, 3.3, P, STAIRS)[0] == pytest.approx(-P.approach_speed)
    assert walk_velocity(0.0, 0.2, 3.3, P, STAIRS)[0] == 0.0


def test_the_agent_takes_the_stairs_span_from_the_priors():
    from pr2_drake.agents.steps_button import StepsButtonAgent

    priors = {"button_center": [3.47, 0.0, 1.0], "step_height": 0.1, "step_depth": 0.4,
              "step_width": 2.0, "step_count": 2, "step_start_x": 1.0}
    agent = StepsButtonAgent(priors)
    seq = next(s for s in agent.GetSystems() if isinstance(s, StepsButtonSequencer))
    x0 = float(priors["step_start_x"])
    end = x0 + float(priors["step_depth"]) * int(priors["step_count"])
    assert seq.stairs_x == pytest.approx((x0 - P.stairs_lead, end))
    assert np.allclose(seq.stand, [priors["button_center"][0] - P.stand_distance,
                                   priors["button_center"][1]])

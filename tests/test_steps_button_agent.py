"""Task 5's sequencer: the WALK command (pr2_drake.agents.steps_button.walk_velocity), the
stairs span the agent takes from its priors, and the check after a press."""

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


def _press_check(short: float, reaches: int = 1):
    """The sequencer after a press whose hand sphere stopped ``short`` [m] before the button's
    face (robot in its zero pose at the origin): (stage, stand_shift, hand target)."""
    from pr2_drake.agents.steps_button import Stage, StepsButtonMemory
    from pr2_drake.controllers.model import WholeBodyModel
    from pr2_drake.ports import BODY_STATE_SIZE, JOINT_STATE_SIZE, P_WB, QUAT_WB

    bs, js = np.zeros(BODY_STATE_SIZE), np.zeros(JOINT_STATE_SIZE)
    bs[QUAT_WB], bs[P_WB] = [1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.8]
    model = WholeBodyModel()
    model.update(*model.state_from_ports(js, bs))
    p_WH = model.hand_point(P.hand)[0]
    seq = StepsButtonSequencer(p_WH + [_hand_radius() + short, 0.0, 0.0], P)
    context = seq.CreateDefaultContext()
    seq.GetInputPort("joint_state").FixValue(context, js)
    m = StepsButtonMemory(stage=Stage.PRESS, reaches=reaches)
    m.targets[P.hand] = p_WH
    seq._after_press(context, bs, m, 10.0)
    return Stage(m.stage), m.stand_shift, m.targets[P.hand]


def _hand_radius() -> float:
    from pr2_drake.robot.params import load_robot_params

    return float(load_robot_params().raw["arms"]["hand_sphere"]["radius"])


def test_a_press_out_of_reach_is_tried_again_from_nearer():
    """Randomised seed 17: the hand stopped 1 cm short of the button (the body stood back), the
    agent stood still to the end and ran out of time; now it walks nearer and reaches again."""
    from pr2_drake.agents.steps_button import Stage

    stage, shift, target = _press_check(0.05)
    assert stage == Stage.APPROACH and target is None
    assert shift == pytest.approx(0.05 + P.press_step)
    stage, shift, _ = _press_check(0.5)  # never farther than press_max_shift
    assert stage == Stage.APPROACH and shift == pytest.approx(P.press_max_shift)


def test_a_press_that_reached_the_button_or_the_last_try_ends_the_task():
    from pr2_drake.agents.steps_button import Stage

    assert _press_check(0.0)[0] == Stage.DONE  # the sphere on the face: pressed
    assert _press_check(-0.01)[0] == Stage.DONE  # pushed into it
    assert _press_check(0.05, reaches=P.press_tries)[0] == Stage.DONE

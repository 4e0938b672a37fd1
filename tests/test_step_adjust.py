"""Step adjustment (pr2_drake.controllers.planning.step_adjust): where and when a swing sole lands, from
the capture point, and a push while walking recovered in closed loop."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from pr2_drake.bench.walking import push_once
from pr2_drake.controllers.planning.step_adjust import choose_step, reach_box
from pr2_drake.controllers.walking_params import WalkingParams

GAIT = WalkingParams.load().gait
OMEGA = np.sqrt(9.81 / GAIT.com_height)
# Left sole stance at the origin, heading +x; the right sole swings, planned 0.22 m to the right.
STANCE = np.array([0.0, 0.11, 0.0, 0.0])
PLAN = np.array([0.10, -0.11])
T0, T_PLAN = 0.0, GAIT.swing_time  # lift-off now, planned landing


def _choose(xi, b=np.array([0.0, 0.03]), t=0.05):
    """choose_step for the right swing sole with the left stance above, at time t [s]."""
    earliest = max(t + GAIT.min_remaining_swing, T0 + GAIT.min_swing_time)
    return choose_step(t, np.asarray(xi, float), STANCE[:2], STANCE, 0, PLAN, b, 0.0,
                       earliest, T_PLAN, T_PLAN + GAIT.max_swing_extension, T_PLAN, GAIT, OMEGA)


def _dcm_for_landing_at(u, b, t, t_land):
    """The DCM now that reaches u + b at the switch when landing at t_land (inverse of the
    LIPM prediction with the ZMP on the stance sole)."""
    growth = np.exp(OMEGA * (t_land - t + 0.5 * GAIT.double_support))
    return STANCE[:2] + (u + b - STANCE[:2]) / growth


def test_on_the_planned_orbit_the_plan_is_kept():
    b = np.array([0.0, 0.03])
    xi = _dcm_for_landing_at(PLAN, b, 0.05, T_PLAN)
    c = _choose(xi, b)
    assert c.landing_time == T_PLAN
    np.testing.assert_allclose(c.target_xy, PLAN, atol=1e-9)
    np.testing.assert_allclose(c.residual, 0.0, atol=1e-12)
    assert c.cost < 1e-9


def test_dcm_pushed_outward_lands_sooner_and_wider():
    # The DCM heads out to the right so fast that at the planned time it is beyond reach.
    _, _, _, w_max = reach_box(GAIT)
    b = np.array([0.0, 0.03])
    far = np.array([0.10, STANCE[1] - w_max - 0.10])
    xi = _dcm_for_landing_at(far, b, 0.05, T_PLAN)
    c = _choose(xi, b)
    assert c.landing_time < T_PLAN - 0.02, "a step that cannot reach far enough lands sooner"
    lateral = STANCE[1] - c.target_xy[1]
    assert lateral > 0.3, f"the swing sole steps out wide, got {lateral:.3f} m"
    assert lateral <= w_max + 1e-9
    # Keeping the planned time would leave the DCM further outside the new sole.
    keep = choose_step(0.05, xi, STANCE[:2], STANCE, 0, PLAN, b, 0.0, T_PLAN, T_PLAN, T_PLAN,
                       T_PLAN, GAIT, OMEGA)
    assert keep.residual[1] > c.residual[1] > -1e-9
    assert keep.cost > c.cost


def test_dcm_pushed_over_the_stance_sole_never_crosses_the_feet():
    # Pushed left, over and past the left stance sole: the ideal step would cross the feet.
    xi = np.array([0.02, STANCE[1] + 0.03])
    c = _choose(xi)
    lateral = STANCE[1] - c.target_xy[1]
    assert abs(lateral - GAIT.recovery_min_step_width) < 1e-9, lateral
    assert c.residual[1] < 0.0  # the unreachable part is inwards: caught by the next step


def test_dcm_pushed_backwards_steps_back_as_far_as_the_recovery_reach():
    # The DCM runs 0.4 m behind the stance sole: the swing sole lands at the backward limit,
    # max_step_backward + 0.05 by default, recovery_step_backward when that is set.
    b = np.array([0.0, 0.03])
    xi = _dcm_for_landing_at(np.array([-0.40, PLAN[1]]), b, 0.05, T_PLAN)
    for gait, back in ((GAIT, GAIT.max_step_backward + 0.05),
                       (dataclasses.replace(GAIT, recovery_step_backward=0.25), 0.25)):
        c = choose_step(0.05, xi, STANCE[:2], STANCE, 0, PLAN, b, 0.0, T_PLAN, T_PLAN, T_PLAN,
                        T_PLAN, gait, OMEGA)
        assert c.target_xy[0] == pytest.approx(-back, abs=1e-9)
        assert c.residual[0] < -0.1  # the rest of the step is out of reach
    assert reach_box(GAIT)[0] == pytest.approx(-(GAIT.max_step_backward + 0.05))


def test_forward_push_while_walking_is_recovered():
    fell, _ = push_once("back", walking=True, force=40.0, push_time=0.2, walk_before=4.0)
    assert not fell


def test_side_push_towards_the_stance_leg_is_recovered():
    # 4.0 s into the walk the left sole is the stance: a push from the right drives the DCM
    # over it, the case that needs a narrow step and then a quick wide one.
    fell, _ = push_once("right", walking=True, force=40.0, push_time=0.2, walk_before=4.0)
    assert not fell


def test_partial_sideways_gain_takes_that_share_of_the_lateral_error():
    # dcm_gain [1, 0.8] (the rocky road's): a DCM off the orbit sideways and forwards moves
    # the landing 0.8 of the full capture-point correction sideways, all of it forwards.
    b = np.array([0.0, 0.03])
    xi = _dcm_for_landing_at(PLAN + np.array([0.03, -0.04]), b, 0.05, T_PLAN)
    full, part = (choose_step(0.05, xi, STANCE[:2], STANCE, 0, PLAN, b, 0.0, T_PLAN, T_PLAN,
                              T_PLAN, T_PLAN, dataclasses.replace(GAIT, dcm_gain=gain), OMEGA)
                  for gain in ([1.0, 1.0], [1.0, 0.8]))
    np.testing.assert_allclose(full.target_xy - PLAN, [0.03, -0.04], atol=1e-9)
    np.testing.assert_allclose(part.target_xy - PLAN, [0.03, -0.032], atol=1e-9)
    rough = WalkingParams.load(overrides=["params/controllers/walking_rough.yaml"]).gait
    assert list(rough.dcm_gain) == [1.0, 0.8]


def test_partial_gain_acts_in_the_heading_frame():
    # Heading 0.7 rad: the landing moves by R G R^T (u* - plan) from the plan, G = diag(gains).
    b = np.array([0.0, 0.03])
    err = np.array([0.02, -0.03])
    xi = _dcm_for_landing_at(PLAN + err, b, 0.05, T_PLAN)
    gait = dataclasses.replace(GAIT, dcm_gain=[0.9, 0.6])
    c = choose_step(0.05, xi, STANCE[:2], STANCE, 0, PLAN, b, 0.7, T_PLAN, T_PLAN, T_PLAN,
                    T_PLAN, gait, OMEGA)
    ch, sh = np.cos(0.7), np.sin(0.7)
    R = np.array([[ch, -sh], [sh, ch]])
    np.testing.assert_allclose(c.target_xy - PLAN, R @ np.diag([0.9, 0.6]) @ R.T @ err,
                               atol=1e-9)


def test_bad_recovery_step_backward_is_refused():
    params = WalkingParams.load()
    for bad in (-0.1, 0.6, float("nan")):
        bad_params = dataclasses.replace(
            params, gait=dataclasses.replace(params.gait, recovery_step_backward=bad))
        with pytest.raises(ValueError, match="recovery_step_backward"):
            bad_params.check()


def test_bad_dcm_gain_is_refused():
    for bad in ([1.0], [1.0, -0.5], [float("nan"), 1.0]):
        params = WalkingParams.load()
        params = dataclasses.replace(params, gait=dataclasses.replace(params.gait, dcm_gain=bad))
        with pytest.raises(ValueError, match="dcm_gain"):
            params.check()

"""The gait planner's double support when the new stance sole slides after touchdown.

On the rocky road a sole can land on a stone's edge and slide off it (task 1, randomised,
seed 9: 18 cm forward after touchdown). The shift planned from where it landed then aimed the
DCM behind the sole, and the robot fell backwards. With ``stance_slip_replan`` > 0
(walking_rough.yaml) the planner re-reads the sole, plans the shift's target again and
lifts off no sooner than ``double_support`` after the slide.
Kinematic only: the model's state is set by hand, no simulation.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from pr2_drake.controllers.model import WholeBodyModel
from pr2_drake.controllers.planning.gait import GaitPlanner, Phase
from pr2_drake.controllers.walking_params import WalkingParams

DT = 0.004  # [s] the controller's tick


def _standing(model: WholeBodyModel, dx: float = 0.0):
    q = model.q_nominal.copy()
    q[model.maps.q_base[:4]] = [1.0, 0.0, 0.0, 0.0]
    q[model.maps.q_base[4:]] = [dx, 0.0, 0.58]
    model.update(q, np.zeros(model.nv))


def _tick(planner: GaitPlanner, model: WholeBodyModel, t: float) -> None:
    p, v, _, _ = model.com()
    planner.update(t, np.array([0.2, 0.0, 0.0]), p, v)


def _in_double_support(slip: float):
    """A planner walking on the spot until its first double support (the swing sole never
    descends here: touchdown comes from ``late_touchdown``)."""
    params = WalkingParams.load(overrides=["params/controllers/walking_rough.yaml"])
    params.gait.stance_slip_replan = slip
    model = WholeBodyModel()
    _standing(model)
    planner = GaitPlanner(params, model)
    t = 0.0
    while planner.phase != Phase.DOUBLE:
        assert t < 3.0, planner.phase
        _tick(planner, model, t)
        t += DT
    return planner, model, t


def test_a_sole_that_slides_in_double_support_is_re_read_and_the_shift_re_aimed():
    planner, model, t = _in_double_support(0.03)
    g = planner.params.gait
    stance = planner.stance
    landed = planner.footholds[stance].copy()
    t0, xi0, target = planner.start_dcm
    t_phase, duration = planner.t_phase, planner.phase_duration
    while t - t_phase < 0.08:  # late in the shift
        _tick(planner, model, t)
        t += DT
    assert planner.phase == Phase.DOUBLE
    _standing(model, dx=0.06)  # the whole robot, so the stance sole, 6 cm forward
    t_slide = t
    _tick(planner, model, t)
    assert planner.phase == Phase.DOUBLE and planner.stance == stance
    np.testing.assert_allclose(planner.footholds[stance][:2], landed[:2] + [0.06, 0.0],
                               atol=1e-9)
    # The shift's target moves with the sole (forward); its start stays ...
    assert planner.start_dcm[2][0] > target[0] + 0.03
    assert planner.start_dcm[0] == t0 and np.array_equal(planner.start_dcm[1], xi0)
    assert planner.t_phase == t_phase
    # ... and it lasts at least double_support more from the slide: no lift-off from a
    # sole still sliding.
    assert planner.phase_duration >= max(duration, t_slide - t_phase + g.double_support) - 1e-9
    while t < t_slide + g.double_support - 2 * DT:
        t += DT
        _tick(planner, model, t)
        assert planner.phase == Phase.DOUBLE


def test_a_small_settling_or_the_rule_off_keeps_the_shift():
    for slip, dx in ((0.03, 0.02), (0.0, 0.06)):
        planner, model, t = _in_double_support(slip)
        stance = planner.stance
        landed = planner.footholds[stance].copy()
        t_phase, target = planner.t_phase, planner.start_dcm[2].copy()
        _standing(model, dx=dx)
        _tick(planner, model, t)
        np.testing.assert_array_equal(planner.footholds[stance], landed)
        assert planner.t_phase == t_phase
        np.testing.assert_array_equal(planner.start_dcm[2], target)


def test_negative_settings_are_refused():
    for bad in (dict(stance_slip_replan=-0.01), dict(shift_time_factor=-1.0),
                dict(shift_time_factor=float("nan"))):
        params = WalkingParams.load()
        params = replace(params, gait=replace(params.gait, **bad))
        with pytest.raises(ValueError, match="stance_slip_replan"):
            params.check()

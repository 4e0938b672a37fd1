"""The walking controller's estimate of the CoM's offset from its model's
(:mod:`pr2_drake.controllers.planning.com_bias`): alone, and on a robot whose base centre of
mass is 2 cm to the side of the model's (the ``mass.base_com`` range of ``randomize``)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from pr2_drake.controllers.planning.com_bias import ComBiasEstimator
from pr2_drake.controllers.walking_params import WalkingParams

DT = 0.004  # [s] the controller's tick
ROUGH = "params/controllers/walking_rough.yaml"  # task 1's overrides: the estimate on


def _gait(**changes):
    return replace(WalkingParams.load().gait, **changes)


def test_a_steady_error_is_integrated_up_to_the_limit():
    g = _gait(com_bias_rate=1.0, com_bias_max=0.03, com_bias_error_max=0.02, com_bias_axes="y")
    est = ComBiasEstimator(g)
    for _ in range(250):  # 1 s of a 1 cm error to the left
        est.observe(np.array([0.0, 0.01]), 0.0, DT)
    assert est.y == pytest.approx(0.01, rel=1e-9)
    assert est.x == 0.0  # "y": forward errors are left to the speed correction
    for _ in range(5000):
        est.observe(np.array([0.0, 0.01]), 0.0, DT)
    assert est.y == pytest.approx(0.03)


def test_a_large_transient_counts_no_more_than_the_error_clip():
    """A push's 10 cm DCM error for 0.2 s moves the estimate by rate x clip x 0.2 s only."""
    g = _gait(com_bias_rate=0.5, com_bias_error_max=0.02, com_bias_axes="y")
    est = ComBiasEstimator(g)
    for _ in range(50):
        est.observe(np.array([0.0, -0.10]), 0.0, DT)
    assert est.y == pytest.approx(-0.5 * 0.02 * 0.2)


def test_errors_that_alternate_with_the_stance_side_cancel():
    """The swing leg's own sway: +-1 cm on alternate steps leaves no offset."""
    est = ComBiasEstimator(_gait(com_bias_rate=1.0, com_bias_axes="xy"))
    step = 80  # ticks per single support
    for k in range(10 * step):
        sign = 1.0 if (k // step) % 2 == 0 else -1.0
        est.observe(np.array([0.0, sign * 0.01]), 0.0, DT)
    assert abs(est.y) < 1e-12 and est.x == 0.0


def test_the_offset_is_in_the_pelvis_yaw_frame():
    """Facing +y (yaw 90 deg), a world error along -x is the body's left; the CoM the planner
    uses moves with the body when it turns."""
    est = ComBiasEstimator(_gait(com_bias_rate=1.0, com_bias_axes="y"))
    est.observe(np.array([-0.01, 0.0]), math.pi / 2, 1.0)
    assert est.y == pytest.approx(0.01)
    com = np.array([1.0, 2.0, 0.8])
    assert np.allclose(est.shifted(com, math.pi / 2), [0.99, 2.0, 0.8])
    assert np.allclose(est.shifted(com, 0.0), [1.0, 2.01, 0.8])
    assert est.shifted(com, 0.0) is not com  # the caller's array is not changed


def test_bad_settings_are_refused():
    for bad in (dict(com_bias_axes="z"), dict(com_bias_rate=-1.0), dict(com_bias_max=-0.01)):
        params = WalkingParams.load()
        params = replace(params, gait=replace(params.gait, **bad))
        with pytest.raises(ValueError, match="com_bias"):
            params.check()


def test_off_means_off():
    est = ComBiasEstimator(_gait(com_bias_rate=0.0))
    est.observe(np.array([0.1, 0.1]), 0.0, DT)
    com = np.array([1.0, 2.0, 0.8])
    assert est.shifted(com, 0.3) is com


def _walk_with_offset(offset_y: float, seconds: float = 15.0):
    """Walk straight ahead at 0.2 m/s on flat ground, with task 1's estimate rate, for
    ``seconds`` on a robot whose base CoM is ``offset_y`` [m] to the left of the model's. Returns (the estimate's y [m], the whole
    robot's CoM offset that makes [m], whether it stayed upright)."""
    from pr2_drake.bench.rigs import WalkingSim
    from pr2_drake.randomize import _scaled_inertia

    rate = WalkingParams.load(overrides=[ROUGH]).gait.com_bias_rate  # task 1's estimate
    params = WalkingParams.load()
    sim = WalkingSim(replace(params, gait=replace(params.gait, com_bias_rate=rate)))
    sim.base.SetSpatialInertiaInBodyFrame(
        sim.plant_context, _scaled_inertia(sim.base, 1.0, [0.0, offset_y, 0.0]))
    shift = offset_y * sim.base.default_mass() / sim.plant.CalcTotalMass(sim.plant_context)
    sim.set_command(0.2, 0.0, 0.0)
    upright = sim.run(seconds)
    return sim.walker.core.planner.com_bias.y, shift, upright


@pytest.mark.parametrize("offset_y", [0.02, -0.02, 0.0])
def test_walking_finds_a_base_com_off_to_the_side(offset_y):
    """A base CoM 2 cm to one side (the end of ``randomize.mass.base_com``) moves the robot's
    CoM 9.2 mm (a 15.9 kg base of 34.5 kg): after 15 s of walking the estimate is on that side,
    more than 0.3 and less than 1.5 times that (measured: 4.1 mm either side); the nominal
    robot's stays within 1 mm of zero (measured: 0.2 mm)."""
    estimate, shift, upright = _walk_with_offset(offset_y)
    assert upright
    if offset_y == 0.0:
        assert abs(estimate) < 0.001, estimate
    else:
        assert 0.3 * abs(shift) < abs(estimate) < 1.5 * abs(shift), (estimate, shift)
        assert np.sign(estimate) == np.sign(offset_y)

"""The gait planner's decisions under sensor noise and an agent's per-tick commands.

Parts tested alone (no simulation): the lift-off rule of double support and the shift's
duration (:mod:`pr2_drake.controllers.planning.liftoff`) and the integral speed correction
(:mod:`pr2_drake.controllers.planning.speed_correction`).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from pr2_drake.controllers.planning.liftoff import LiftoffRule, shift_duration
from pr2_drake.controllers.planning.speed_correction import SpeedCorrection
from pr2_drake.controllers.walking_params import WalkingParams

DT = 0.004  # [s] the controller's tick


def _gait():
    return WalkingParams.load().gait


def _noisy_shift(rng, sigma: float, seconds: float, start: float, rate: float):
    """DCM errors [m] of a shift that reduces the error at ``rate`` [m/s], with white noise."""
    n = int(round(seconds / DT))
    return [max(start - rate * k * DT, 0.0) + sigma * rng.standard_normal() for k in range(n)]


def test_noise_does_not_look_like_a_runaway():
    """A shrinking DCM error with the noise of the randomised body_state (about 5 mm per axis
    after dividing the velocity noise by omega) never triggers the runaway rule, though
    tick to tick it 'grows' at about half the ticks."""
    g = _gait()
    rng = np.random.default_rng(7)
    errs = _noisy_shift(rng, 0.005, 0.3, start=0.09, rate=0.15)
    raw_grows = sum(b > a + 1e-4 and b > g.runaway_dcm_error for a, b in zip(errs, errs[1:]))
    assert raw_grows > 5  # the tick-to-tick comparison would have stepped at once
    rule = LiftoffRule(g)
    for e in errs:
        rule.update(e, DT)
        assert not rule.running_away()


def test_a_real_runaway_is_caught_within_a_few_ticks():
    """An error that grows at 0.2 m/s from 6 cm (a push) is a runaway within 60 ms, with or
    without the noise."""
    g = _gait()
    for sigma in (0.0, 0.005):
        rng = np.random.default_rng(3)
        rule = LiftoffRule(g)
        for k in range(10):  # the shift first holds the error at 6 cm
            rule.update(0.06 + sigma * rng.standard_normal(), DT)
        caught = None
        for k in range(40):
            rule.update(0.06 + 0.2 * k * DT + sigma * rng.standard_normal(), DT)
            if rule.running_away():
                caught = k * DT
                break
        assert caught is not None and caught <= 0.06, (sigma, caught)


def test_extension_ends_when_the_error_is_small_or_stops_falling():
    g = _gait()
    rule = LiftoffRule(g)
    for e in (0.08, 0.07, 0.06):
        rule.update(e, DT)
    assert not rule.done(0.1, 0.1)  # still falling, still large: extend
    for _ in range(100):
        rule.update(0.06, DT)
    assert rule.done(0.2, 0.1)  # no longer falling
    rule.reset()
    rule.update(0.01, DT)
    assert rule.done(0.1, 0.1)  # within the tolerance
    rule.reset()
    rule.update(0.08, DT)
    assert rule.done(0.1 + g.max_shift_extension, 0.1)  # the extension's cap


def _rough_gait():
    return WalkingParams.load(overrides=["params/controllers/walking_rough.yaml"]).gait


def _dcm_after(xi0, p_old, omega: float, seconds: float) -> np.ndarray:
    """The DCM [m] after ``seconds`` with the ZMP held at ``p_old`` (LIPM, integrated by ticks)."""
    xi = np.array(xi0, dtype=float)
    for _ in range(int(round(seconds / DT))):
        xi += DT * omega * (xi - p_old)
    return xi


def test_a_shift_from_near_the_old_sole_is_given_the_time_it_needs():
    """A DCM 4 cm from the old sole cannot move 12 cm in 0.10 s with the ZMP on that sole;
    the shift's duration is the least time that can (the LIPM, integrated, arrives in it)."""
    g = _rough_gait()
    assert g.shift_time_factor > 0.0
    omega = math.sqrt(9.81 / g.com_height)
    p_old, xi0, xi_end = np.zeros(2), np.array([0.0, -0.04]), np.array([0.0, -0.16])
    T = shift_duration(xi0, xi_end, p_old, omega, g)
    assert g.double_support < T <= g.double_support + g.max_shift_extension
    assert np.linalg.norm(_dcm_after(xi0, p_old, omega, g.double_support) - xi_end) > 0.05
    assert np.linalg.norm(_dcm_after(xi0, p_old, omega, T) - xi_end) < 0.005


def test_a_shift_with_time_enough_or_after_a_push_keeps_the_planned_duration():
    g = _rough_gait()
    omega = math.sqrt(9.81 / g.com_height)
    p_old = np.array([0.3, 0.1])
    # Far ahead of the old sole: the DCM covers 5 cm in well under 0.10 s.
    assert shift_duration(p_old + [0.0, -0.3], p_old + [0.0, -0.35], p_old, omega, g) \
        == g.double_support
    # Behind the old sole (pushed the other way): no finite least time; step as planned.
    assert shift_duration(p_old + [0.0, 0.02], p_old + [0.0, -0.1], p_old, omega, g) \
        == g.double_support
    # Just ahead of it: the longest shift, not more.
    assert shift_duration(p_old + [0.0, -0.011], p_old + [0.0, -0.3], p_old, omega, g) \
        == g.double_support + g.max_shift_extension
    # Off (walking.yaml's default): the planned duration whatever the DCM.
    assert shift_duration([0.0, -0.04], [0.0, -0.16], np.zeros(2), omega, _gait()) \
        == _gait().double_support


def _walk_steps(corr: SpeedCorrection, command_at, v_W, steps: int, t0: float = 0.0):
    """Ticks and touchdowns of ``steps`` steps at the CoM velocity ``v_W`` (W, heading 0)."""
    g = corr.gait
    period = g.step_period
    t, com = t0, np.zeros(2)
    corr.reset(t, com)
    for _ in range(steps):
        for _ in range(int(round(period / DT))):
            t += DT
            com = com + DT * np.asarray(v_W)
            target = command_at(t)
            corr.observe_command(t, target, target)
        corr.touchdown(t, com, np.asarray(command_at(t)), 0.0)
    return corr.value


def test_a_heading_loop_does_not_hold_the_lateral_correction():
    """An agent trims vx and the yaw rate at every tick (small changes): a sideways drift of
    5 cm/s is still corrected (the correction steers left, against it)."""
    def trimmed(t):
        return [0.2 + 0.005 * math.sin(40 * t), 0.0, 0.05 * math.sin(25 * t)]
    value = _walk_steps(SpeedCorrection(_gait()), trimmed, [0.2, -0.05], 8)
    assert value[1] > 0.05


def test_a_real_command_change_holds_the_correction():
    """While the linear command moves by more than speed_hold_change per step the correction
    does not integrate the (expected) speed error."""
    g = _gait()
    def ramp(t):
        return [0.1 + 0.2 * t, 0.0, 0.0]  # 0.2 m/s^2: a new command every step
    value = _walk_steps(SpeedCorrection(g), ramp, [0.0, -0.05], 6)
    assert np.all(value == 0.0)


def test_a_learnt_correction_fades_when_the_command_changes():
    """A correction learnt on a steady walk (drift to the right) shrinks, step by step, once
    the agent's command really changes (an approach's small, varying steps)."""
    g = _gait()
    corr = SpeedCorrection(g)
    learnt = _walk_steps(corr, lambda t: [0.2, 0.0, 0.0], [0.2, -0.05], 8).copy()
    assert learnt[1] > 0.05

    def approach(t):  # a P-law on a swaying base: vy between -0.02 and -0.10 m/s
        return [0.0, -0.06 + 0.04 * math.sin(14 * t), 0.0]
    t, com = 8 * g.step_period, np.zeros(2)
    for _ in range(4):
        for _ in range(int(round(g.step_period / DT))):
            t += DT
            corr.observe_command(t, approach(t), approach(t))
        corr.touchdown(t, com, np.asarray(approach(t)), 0.0)
    assert abs(corr.value[1]) <= learnt[1] * g.speed_hold_decay ** 3 + 1e-12


def _stride_gait(window: int = 2, error_max: float = 0.2):
    g = _gait()
    g.speed_window_steps, g.speed_error_max = window, error_max
    return g


def _sway_steps(corr: SpeedCorrection, steps: int, drift: float, sway: float,
                push_step: int = -1, push: float = 0.0):
    """Touchdowns of a straight walk at 0.2 m/s whose single steps alternate their sideways
    speed by ``sway`` [m/s] around ``drift`` [m/s]; step ``push_step`` is ``push`` [m/s] off."""
    g = corr.gait
    period, t, com = g.step_period, 0.0, np.zeros(2)
    command = [0.2, 0.0, 0.0]
    corr.reset(t, com)
    values = []
    for k in range(steps):
        for _ in range(int(round(period / DT))):
            t += DT
            corr.observe_command(t, command, command)
        vy = drift + (sway if k % 2 else -sway) + (push if k == push_step else 0.0)
        com = com + period * np.array([0.2, vy])
        corr.touchdown(t, com, np.asarray(command), 0.0)
        values.append(corr.value.copy())
    return values


def test_a_stride_window_does_not_integrate_the_sway():
    """Single steps sway +-0.2 m/s sideways with no drift: one-step windows swing the
    correction step to step; a stride window leaves it at zero."""
    one = _sway_steps(SpeedCorrection(_stride_gait(1, 0.0)), 8, 0.0, 0.2)
    two = _sway_steps(SpeedCorrection(_stride_gait(2, 0.0)), 8, 0.0, 0.2)
    assert max(abs(v[1]) for v in one) > 0.05
    assert max(abs(v[1]) for v in two) < 1e-9


def test_a_stride_window_still_corrects_a_drift():
    """A 5 cm/s drift to the right under the sway is corrected (the correction steers left)."""
    values = _sway_steps(SpeedCorrection(_stride_gait()), 10, -0.05, 0.15)
    assert values[-1][1] > 0.05


def test_a_push_is_not_integrated():
    """One step 0.6 m/s off sideways (a push): without the limit the correction jumps to its
    bound; with speed_error_max it does not move."""
    free = _sway_steps(SpeedCorrection(_stride_gait(2, 0.0)), 6, 0.0, 0.0, 3, -0.6)
    held = _sway_steps(SpeedCorrection(_stride_gait(2, 0.2)), 6, 0.0, 0.0, 3, -0.6)
    assert free[3][1] > 0.05
    assert max(abs(v[1]) for v in held) < 1e-9


def test_bad_speed_window_is_refused():
    for window, error_max in ((0, 0.0), (5, 0.0), (2, -0.1), (2, math.inf)):
        params = WalkingParams.load()
        params.gait.speed_window_steps, params.gait.speed_error_max = window, error_max
        with pytest.raises(ValueError, match="speed_window_steps"):
            params.check()

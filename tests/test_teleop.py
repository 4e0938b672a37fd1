"""Velocity sources for the walking controller."""

import numpy as np
import pytest
from pydrake.geometry import Meshcat

from pr2_drake.teleop import MeshcatVelocitySliders, VelocitySchedule


def _command(system, t):
    ctx = system.CreateDefaultContext()
    ctx.SetTime(t)
    return system.GetOutputPort("velocity_command").Eval(ctx)


def test_schedule_is_piecewise_constant():
    s = VelocitySchedule([(0.5, 0.3, 0, 0), (2.0, 0, 0.1, 0.2)])
    np.testing.assert_array_equal(_command(s, 0.0), [0, 0, 0])
    np.testing.assert_array_equal(_command(s, 0.5), [0.3, 0, 0])
    np.testing.assert_array_equal(_command(s, 1.99), [0.3, 0, 0])
    np.testing.assert_array_equal(_command(s, 5.0), [0, 0.1, 0.2])


@pytest.mark.parametrize("bad", [[(0, 1, 2)], [(1.0, 0, 0, 0), (0.5, 0, 0, 0)], [(0, np.nan, 0, 0)]])
def test_bad_schedules_are_rejected(bad):
    with pytest.raises(ValueError, match="VelocitySchedule"):
        VelocitySchedule(bad)


def test_sliders_read_meshcat():
    meshcat = Meshcat()
    sliders = MeshcatVelocitySliders(meshcat)
    meshcat.SetSliderValue("vx [m/s]", 0.2)
    meshcat.SetSliderValue("yaw rate [rad/s]", -0.3)
    np.testing.assert_allclose(_command(sliders, 0.0), [0.2, 0.0, -0.3])

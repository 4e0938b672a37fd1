"""Shared fixtures: small builders used across the test suite."""

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from pr2_drake.controllers.standing import StandingController
from pr2_drake.episode import connect_by_name
from pr2_drake.testbed import Testbed, TestbedConfig


def standing_simulator(config: TestbedConfig | None = None):
    """Testbed + StandingController; returns (simulator, testbed, testbed context)."""
    builder = DiagramBuilder()
    testbed = builder.AddSystem(Testbed(config or TestbedConfig()))
    controller = builder.AddSystem(StandingController())
    connect_by_name(builder, testbed, controller)
    simulator = Simulator(builder.Build())
    simulator.Initialize()
    return simulator, testbed, testbed.GetMyContextFromRoot(simulator.get_context())


@pytest.fixture
def rng():
    return np.random.default_rng(0)

"""Shared fixtures: small builders used across the test suite."""

import math

import numpy as np
import pytest

from pr2_drake.controllers.standing import StandingController
from pr2_drake.episode import Episode, wire_system
from pr2_drake.scenario import Scenario


def standing_simulator(scenario: Scenario | None = None):
    """Testbed + StandingController; returns (simulator, testbed, testbed context)."""
    episode = Episode(scenario or Scenario(seconds=math.inf), wire_system(StandingController()))
    episode.simulator.Initialize()
    return episode.simulator, episode.testbed, episode.tb_context


def wire_standing_legs(builder, testbed, controller: StandingController) -> None:
    """Add ``controller`` and let it drive the legs only (the test drives the arms)."""
    builder.AddSystem(controller)
    for n in ("joint_state", "body_state"):
        builder.Connect(testbed.GetOutputPort(n), controller.GetInputPort(n))
    builder.Connect(controller.GetOutputPort("legs_command"), testbed.GetInputPort("legs_command"))


@pytest.fixture
def rng():
    return np.random.default_rng(0)

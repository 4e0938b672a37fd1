"""Agents that misbehave on purpose, for the fault tests (tests/test_faults.py).

Each stands until ``T_FAULT`` [s] of simulated time, so that an episode can earn points
first, then commits its fault.
"""

import sys

import numpy as np

from pr2_drake.agents.standing import StandingAgent
from pr2_drake.controllers.standing import StandingController
from pr2_drake.ports import JointGroupCommand

T_FAULT = 0.1  # [s]


class NaNAfterPoints(StandingAgent):
    """A next_action agent that sends NaN leg efforts from T_FAULT on."""

    def next_action(self, obs):
        action = super().next_action(obs)
        if obs["time"] >= T_FAULT:
            action["legs"]["joint_values"] = np.full(10, np.nan)
        return action


class RaisingPolicy(StandingAgent):
    def next_action(self, obs):
        if obs["time"] >= T_FAULT:
            return 1 / 0
        return super().next_action(obs)


class ExitingPolicy(StandingAgent):
    def next_action(self, obs):
        if obs["time"] >= T_FAULT:
            sys.exit(3)
        return super().next_action(obs)


class RaisingSystem(StandingController):
    """A System agent whose update raises RuntimeError from T_FAULT on (a RuntimeError was
    once read by the testbed as an unconnected port, i.e. zero torque)."""

    __slots__ = ()  # (see pr2_drake.lifetime)

    def _update(self, context, state) -> None:
        if context.get_time() >= T_FAULT:
            raise RuntimeError("controller exploded")
        super()._update(context, state)


class NaNSystem(StandingController):
    """A System agent whose legs command holds NaN efforts from T_FAULT on."""

    __slots__ = ()

    def _update(self, context, state) -> None:
        super()._update(context, state)
        if context.get_time() >= T_FAULT:
            state.get_mutable_abstract_state(int(self._legs)).set_value(
                JointGroupCommand.effort(np.full(10, np.nan)))


class NotAnAgent:
    """Has neither ports nor next_action."""


class NeedsArgument(StandingAgent):
    def __init__(self, mandatory):
        super().__init__()


not_a_class = 42

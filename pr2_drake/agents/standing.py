"""StandingAgent: the standing controller as a ``next_action(obs)`` agent (PR2 dictionaries).

It shows the dictionary interface end to end; in a diagram use
:class:`pr2_drake.controllers.standing.StandingController` directly.
"""

from __future__ import annotations

from typing import Any

from pr2_drake.controllers.standing import StandingPolicy
from pr2_drake.observation import command_to_dict, state_vectors


class StandingAgent:
    """Stands still: legs in effort mode (PD + weight compensation), arms in position mode."""

    def __init__(self):
        self.policy = StandingPolicy()

    def next_action(self, obs: dict[str, Any]) -> dict[str, Any]:
        joint_state, body_state = state_vectors(obs)
        legs, arms = self.policy.compute(joint_state, body_state)
        return {"legs": command_to_dict(legs), "arms": command_to_dict(arms), "pick": None,
                "release": False}

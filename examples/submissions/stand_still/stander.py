"""A submission in the original platform's style: ``next_action(obs) -> action``.

It stands: legs in effort mode (PD about a crouch plus gravity compensation from the built-in
standing policy), arms held in position mode, at 200 Hz. It never looks, so it asks the head
camera for no frames (``camera_capture`` False): on Task 6 that saves a render at every sample.
"""

from pr2_drake.agents.standing import StandingAgent


class Stander(StandingAgent):
    control_dt = 0.005  # [s]

    def next_action(self, obs):
        action = super().next_action(obs)
        action["pick"] = None
        action["camera_capture"] = False
        return action

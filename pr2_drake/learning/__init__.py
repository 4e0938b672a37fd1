"""The testbed as a learning suite: gymnasium ids, command-level and joint-level envs, dense
rewards, fast resets, vector envs and Ray rollouts (README, "Learning").

After ``import pr2_drake`` gymnasium knows the ids ``pr2_drake/<Name>-v0`` (joint level) and
``pr2_drake/<Name>Command-v0`` (command level) for every task of the registry
(:mod:`pr2_drake.learning.ids`)::

    import gymnasium as gym
    import pr2_drake  # noqa: F401  (registers the ids)
    env = gym.make("pr2_drake/SlopeCommand-v0")

Importing this package imports neither pydrake nor gymnasium: the envs live in
:mod:`pr2_drake.learning.envs` (needs the ``[rl]`` extra's gymnasium).
"""

"""Competitions: every submission's agent in a sandboxed subprocess, a leaderboard and plots.

- :mod:`.sandbox`: the agent's process (bubblewrap where available, resource limits) and its
  message channel.
- :mod:`.child`: what runs inside the sandbox (builds the agent, answers observations).
- :mod:`.proxy`: one episode with the simulator and referee here and the agent there.
- :mod:`.runner`: ``pr2-drake compete`` (submissions x tasks x seeds, resumable).
- :mod:`.leaderboard`, :mod:`.plots`: the ranking and the figures.
"""

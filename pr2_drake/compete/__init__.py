"""Competitions: every submission's agent in a sandboxed subprocess, a leaderboard and plots.

- :mod:`.sandbox`: the agent's process (bubblewrap where available, resource limits, timeouts)
  and its message channel.
- :mod:`.child`: what runs inside the sandbox (builds the agent, answers observations or steps
  a System agent with the testbed's port values).
- :mod:`.proxy`: one episode with the simulator and referee here and the agent there
  (:func:`.proxy.run_sandboxed_episode`).
- :mod:`.runner`: ``pr2-drake compete`` (submissions x tasks x seeds, resumable).
- :mod:`.leaderboard`: ``pr2-drake leaderboard`` (ranking, markdown/HTML, the paper's plots).
"""

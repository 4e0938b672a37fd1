"""Competitions: every submission's agent in an isolated subprocess, a leaderboard and plots.

- :mod:`.isolation`: which isolation works here (bubblewrap, util-linux ``unshare``) and the
  command that starts an agent in it; :mod:`.jail` runs first inside the namespaces (file
  system, privileges, seccomp); :mod:`.cgroups`: the agent's memory and process limits.
- :mod:`.sandbox`: the agent's process for one episode and the requests to it;
  :mod:`.channel`: the frames, the answers' decoding, the camera's shared memory;
  :mod:`.limits`: what an agent may use; :mod:`.submission`: what the harness reads of a
  submission.
- :mod:`.child`: what runs inside the sandbox (builds the agent, answers observations or steps
  a System agent with the testbed's port values).
- :mod:`.proxy`: one episode with the simulator and referee here and the agent there
  (:func:`.proxy.run_sandboxed_episode`).
- :mod:`.runner`: ``pr2-drake compete`` (submissions x tasks x seeds, resumable; rows signed by
  :mod:`.ledger`); :mod:`.command`: the command lines of ``compete`` and ``run --isolate``.
- :mod:`.leaderboard`: ``pr2-drake leaderboard`` (ranking, markdown/HTML, the paper's plots).
"""

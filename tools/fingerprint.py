"""Bit-identity fingerprints of the default agents' episodes (a refactoring check).

    python tools/fingerprint.py --tasks 1,2,3,4,5,6 --seeds 0:2 --out fp.json [--variation]

Runs each (task, seed) with the task's default agent, as ``pr2-drake run`` does, and writes its
report plus a SHA-256 of the plant's whole state (positions and velocities, float64 bytes) at
the episode's end. Any change of a tick anywhere in an episode changes that hash. Works on the
code of any commit that has ``Episode.report`` (run it with that commit on PYTHONPATH).
"""

import argparse
import hashlib
import json
import sys
import time

import numpy as np


EXTRA = [
    dict(task=1, seed=0, seconds=2.0, agent="pr2_drake.agents.standing:StandingAgent"),
    dict(task=2, seed=3, seconds=2.0, agent="examples/submissions/stand_still/stander.py:Stander"),
    dict(task=None, seed=0, seconds=2.0),
    dict(task=1, seed=1, seconds=2.0, diagram="diagrams/standing.yaml"),
    dict(task=4, seed=0, seconds=3.0, agent="pr2_drake.agents.walk_to_goal:WalkToGoalAgent"),
]


def main() -> int:
    p = argparse.ArgumentParser()
    p.add_argument("--tasks", default="1,2,3,4,5,6")
    p.add_argument("--seeds", default="0:1")
    p.add_argument("--seconds", type=float, default=None)
    p.add_argument("--out", required=True)
    p.add_argument("--variation", action="store_true",
                   help="scene variation on (--set scene.variation=true)")
    p.add_argument("--extra", action="store_true",
                   help="also: next_action agents, flat ground, a diagram YAML (2 s each)")
    a = p.parse_args()
    from pr2_drake import episode as episode_module
    try:
        from pr2_drake.run import run_episode
    except ImportError:
        run_episode = episode_module.run_episode
    from pr2_drake.scenario import Scenario

    original = episode_module.Episode.report

    def report(self, *args, **kwargs):
        r = original(self, *args, **kwargs)
        x = np.asarray(self.testbed.GetOutputPort("plant_state").Eval(self.tb_context), float)
        r["state_sha256"] = hashlib.sha256(x.tobytes()).hexdigest()
        return r

    episode_module.Episode.report = report
    lo, hi = (int(v) for v in a.seeds.split(":"))
    out = []
    for task in (int(t) for t in a.tasks.split(",")):
        for seed in range(lo, hi):
            start = time.perf_counter()
            kw = {}
            if a.variation:
                from pr2_drake.scenario import SceneSettings
                kw["scene"] = SceneSettings(variation=True)
            r = run_episode(Scenario(task=task, seed=seed, seconds=a.seconds, **kw))
            r.pop("wall_time", None)
            r.pop("real_time_factor", None)
            out.append(r)
            print(f"task {task} seed {seed}: {r['termination']} {r['score']} t={r['sim_time']} "
                  f"{r['state_sha256'][:12]} ({time.perf_counter() - start:.1f} s)", flush=True)
    if a.extra:
        for kw in EXTRA:
            r = run_episode(Scenario(**kw))
            r.pop("wall_time", None)
            r.pop("real_time_factor", None)
            out.append(r)
            print(f"{kw}: {r['termination']} {r['score']} {r['state_sha256'][:12]}", flush=True)
    with open(a.out, "w") as f:
        json.dump(out, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())

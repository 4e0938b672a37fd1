"""Sandbox benchmark: what the process boundary costs per control tick.

    pr2-drake bench sandbox [--task 1] [--seconds 1.0] [--camera 320x240]

Runs the same agents sandboxed (:func:`pr2_drake.compete.proxy.run_sandboxed_episode`) and in
process, on the same scenario, and prints per tick: the agent's round trip, its own compute
time, the overhead of the boundary (round trip minus compute: pickling the observation or the
port values, the pipe both ways, JSON of the action, the parent's validation), and the wall
time of each episode. Agents: ``StandingAgent`` (``next_action``, a tick per physics step) and
``StandingController`` (a Drake System, a tick per physics step); with ``--camera`` the
observation carries colour and depth frames through shared memory.
"""

from __future__ import annotations

import argparse
import os
import time

from pr2_drake.camera import CameraSettings
from pr2_drake.compete.proxy import run_sandboxed_episode
from pr2_drake.compete.sandbox import SandboxLimits, isolation_note
from pr2_drake.run import run_episode
from pr2_drake.scenario import Scenario
from pr2_drake.testbed import task_time_step

AGENTS = ("pr2_drake.agents.standing:StandingAgent",
          "pr2_drake.controllers.standing:StandingController")


def boundary_cpu_us(task: int, repeats: int = 2000) -> dict[str, float]:
    """CPU time [us] of the work the boundary adds per tick, measured in one process (so no
    scheduling delay): pickling the request, unpickling it, building the observation (next_action
    agents), encoding the answer and decoding it. Per agent kind."""
    import json
    import pickle

    from pr2_drake.agents.standing import StandingAgent
    from pr2_drake.compete.child import _binary, jsonable
    from pr2_drake.compete.channel import decode_reply
    from pr2_drake.env import Env
    from pr2_drake.observation import observation_from_ports

    env = Env(task=task, seed=0)
    tb, ctx = env.testbed, env.episode.tb_context
    values = {n: tb.GetOutputPort(n).Eval(ctx) for n in env.observation_ports()}
    X = tb.X_WB_start
    start = (X.translation(), X.rotation().ToQuaternion().wxyz())
    priors = env.priors
    obs = observation_from_ports(values, 0.0, priors, *start)
    action = StandingAgent().next_action(obs)
    system_values = {n: values[n] for n in ("joint_state", "body_state")}

    def answer():
        blob: list[bytes] = []
        head = json.dumps(_binary({"action": jsonable(action), "compute": 1e-4}, blob,
                                  [0])).encode()
        decode_reply(len(head).to_bytes(4, "big") + head + b"".join(blob))

    def policy():
        msg = pickle.loads(pickle.dumps({"op": "act", "time": 0.0, "ports": values}, 5))
        observation_from_ports(msg["ports"], msg["time"], priors, *start)
        answer()

    def system():
        pickle.loads(pickle.dumps({"op": "tick", "time": 0.0, "ports": system_values,
                                   "prev": system_values, "t_prev": 0.0}, 5))
        answer()

    out = {}
    for name, fn in (("next_action", policy), ("System", system)):
        t0 = time.process_time()
        for _ in range(repeats):
            fn()
        out[name] = (time.process_time() - t0) / repeats * 1e6
    return out


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="pr2-drake bench sandbox")
    p.add_argument("--task", type=int, default=1)
    p.add_argument("--seconds", type=float, default=1.0, help="simulated seconds per episode")
    p.add_argument("--camera", help="WIDTHxHEIGHT: send camera frames (10 fps) too")
    a = p.parse_args(argv)
    camera = None
    if a.camera:
        w, h = (int(v) for v in a.camera.lower().split("x"))
        camera = CameraSettings(enabled=True, width=w, height=h, fps=10)
    limits = SandboxLimits()
    print(isolation_note(limits))
    step = task_time_step(a.task)
    print(f"task {a.task}, {a.seconds:g} s simulated, a tick per physics step "
          f"({step * 1e3:g} ms)" + (f", camera {a.camera}" if camera else ""))
    print(f"  {'agent':<48}{'ticks':>7}{'round trip':>12}{'compute':>10}{'overhead':>10}"
          f"{'median':>9}"
          f"{'wall':>8}{'in proc.':>10}")
    for spec in AGENTS:
        scenario = Scenario(task=a.task, seed=0, agent=spec, seconds=a.seconds, camera=camera,
                            control_dt=step if spec.endswith("Agent") else None)
        r = run_sandboxed_episode(scenario, limits=limits)
        start = time.perf_counter()
        run_episode(scenario)
        inproc = time.perf_counter() - start
        us = 1e6
        print(f"  {spec:<48}{r['steps']:>7}{r['step_time_mean'] * us:>10.0f}us"
              f"{r['agent_compute_mean'] * us:>8.0f}us{r['ipc_overhead_mean'] * us:>8.0f}us"
              f"{r['ipc_overhead_median'] * us:>7.0f}us"
              f"{r['wall_time']:>7.1f}s{inproc:>9.1f}s")
    print("overhead = round trip - the agent's own compute per tick (mean, median); wall = "
          "whole episode (start of the sandbox included); in proc. = the same episode in "
          "process")
    cpu = boundary_cpu_us(a.task)
    print("CPU work of the boundary per tick, in one process (no scheduling delays): "
          + ", ".join(f"{k} {v:.0f} us" for k, v in cpu.items()))
    print(f"load average while measuring: {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    return 0


if __name__ == "__main__":
    import sys

    sys.exit(main(sys.argv[1:]))

"""Controller ticks recorded in closed loop, replayed open loop: time and bit-identity.

    python tools/tick_replay.py record --task 4 --seed 0 --out /tmp/t4.pkl [--seconds S]
    python tools/tick_replay.py replay /tmp/t4.pkl [--repeats 3] [--profile]

``record`` runs the task's default agent (as ``pr2-drake run`` does) and saves the inputs of
every controller tick (``WholeBodyController.update`` / ``JumpCore.update``, outermost calls
only: time, q, v, command, arm torques, hand targets, attached; jump command) with a SHA-256
of each tick's outputs (torques, arm torques, status vector).

``replay`` builds the same episode again (the agent and its controllers, not run), feeds the
recorded inputs to its controllers in the same order and reports the controller's wall time
per tick (no plant, no agent, no ports) and whether every tick's outputs are bit-identical
to the recording. Run it with another commit's code on PYTHONPATH to time that commit on the
same inputs (the recording holds plain numpy data only).
"""

import argparse
import hashlib
import pickle
import sys
import time

import numpy as np


def _classes():
    from pr2_drake.controllers.whole_body import WholeBodyController
    try:
        from pr2_drake.controllers.jumping import JumpCore
    except ImportError:  # pragma: no cover - older layouts
        JumpCore = None
    return [c for c in (WholeBodyController, JumpCore) if c is not None]


class _Tap:
    """Patches the controller classes: numbers their instances, logs outermost update calls."""

    def __init__(self, log: bool):
        self.instances: list = []
        self.calls: list = []
        self.depth = 0
        self.log = log
        self.saved = []
        for cls in _classes():
            self._patch(cls)

    def _patch(self, cls) -> None:
        tap = self
        init, update = cls.__init__, cls.update
        self.saved.append((cls, init, update))

        def __init__(self, *a, **k):
            init(self, *a, **k)
            tap.instances.append(self)

        def wrapped(self, *a, **k):
            tap.depth += 1
            try:
                out = update(self, *a, **k)
            finally:
                tap.depth -= 1
            if tap.depth == 0 and tap.log:
                tap.calls.append((tap.instances.index(self), _copy(a), _copy(k), _digest(self, out)))
            return out

        cls.__init__ = __init__
        cls.update = wrapped

    def restore(self) -> None:
        for cls, init, update in self.saved:
            cls.__init__, cls.update = init, update


def _copy(x):
    if isinstance(x, np.ndarray):
        return x.copy()
    if isinstance(x, (list, tuple)):
        return type(x)(_copy(v) for v in x)
    if isinstance(x, dict):
        return {k: _copy(v) for k, v in x.items()}
    return x


def _core(ctrl):
    return getattr(ctrl, "core", ctrl)


def _digest(ctrl, out) -> str:
    core = _core(ctrl)
    h = hashlib.sha256(np.asarray(out, float).tobytes())
    if core.arms_driven:
        h.update(np.asarray(core.tau_arms, float).tobytes())
    h.update(core.info.vector().tobytes())
    return h.hexdigest()


def _episode(task: int, seed: int, seconds):
    from pr2_drake.run import _agent_wiring, _build, agent_spec
    from pr2_drake.scenario import Scenario

    scenario = Scenario(task=task, seed=seed, seconds=seconds)
    return _build(scenario, _agent_wiring(scenario, agent_spec(scenario)), None)


def record(a) -> int:
    from pr2_drake.drive import drive_blocks
    from pr2_drake.run import Progress

    tap = _Tap(log=True)
    episode = _episode(a.task, a.seed, a.seconds)
    t0 = time.perf_counter()
    drive_blocks(episode, Progress(None, episode.limit))
    wall = time.perf_counter() - t0
    tap.restore()
    with open(a.out, "wb") as f:
        pickle.dump(dict(task=a.task, seed=a.seed, seconds=a.seconds, calls=tap.calls), f)
    print(f"task {a.task} seed {a.seed}: {len(tap.calls)} ticks, {episode.time:.2f} s simulated, "
          f"{episode.status.termination} {episode.status.score}, wall {wall:.2f} s")
    return 0


def _callgrind(state: str) -> None:
    """Switch valgrind's instrumentation of this process on or off (``--callgrind``)."""
    import os
    import subprocess

    subprocess.run(["callgrind_control", "-i", state, str(os.getpid())], check=True,
                   capture_output=True)


def replay(a) -> int:
    with open(a.file, "rb") as f:
        rec = pickle.load(f)
    calls = rec["calls"]
    n = len(calls)
    chunks = range(0, n, a.chunk)
    best = np.full(len(chunks), np.inf)  # per chunk: least thread CPU time over the passes
    split = np.full((len(chunks), 3), np.inf)  # per chunk: least planner/objectives/QP wall
    mismatch = None
    # Pass 0 checks every tick's outputs; passes 1..repeats are timed (a fresh build each).
    for rep in range(a.repeats + 1):
        tap = _Tap(log=False)
        _episode(rec["task"], rec["seed"], rec["seconds"])
        tap.restore()
        ctrls = tap.instances
        updates = [type(c).update for c in ctrls]
        args = [(updates[i], ctrls[i], _copy(p), _copy(k)) for i, p, k, _ in calls]
        if rep == 0:
            for k, (fn, ctrl, p, kw) in enumerate(args):
                if _digest(ctrl, fn(ctrl, *p, **kw)) != calls[k][3]:
                    mismatch = k
                    break
            continue
        if a.profile and rep == 1:
            import cProfile
            import pstats
            prof = cProfile.Profile()
            prof.enable()
        if a.callgrind and rep == 1:
            _callgrind("on")
        cores = {id(_core(c)): _core(c) for c in ctrls}.values()
        for c in cores:
            c.timing[:] = 0.0
            c.timed = True
        for j, lo in enumerate(chunks):
            before = sum(c.timing for c in cores)
            t0 = time.thread_time()
            for fn, ctrl, p, kw in args[lo:lo + a.chunk]:
                fn(ctrl, *p, **kw)
            cpu = time.thread_time() - t0
            best[j] = min(best[j], cpu)
            split[j] = np.minimum(split[j], sum(c.timing for c in cores) - before)
        if a.callgrind and rep == 1:
            _callgrind("off")
        if a.profile and rep == 1:
            prof.disable()
            pstats.Stats(prof).sort_stats("tottime").print_stats(a.profile_lines)
    same = "bit-identical" if mismatch is None else f"DIFFERS from tick {mismatch}"
    print(f"task {rec['task']} seed {rec['seed']}: {n} ticks, outputs {same}")
    if a.repeats:
        tick = 1e3 * best.sum() / n
        parts = 1e3 * split.sum(axis=0) / n
        print(f"  {tick:.4f} ms CPU per tick (sum over {len(chunks)} chunks of {a.chunk} ticks "
              f"of the least of {a.repeats} passes); split [ms, wall, same rule]: planner "
              f"{parts[0]:.4f}, objectives {parts[1]:.4f}, QP {parts[2]:.4f}")
    return 0 if mismatch is None else 1


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("record")
    r.add_argument("--task", type=int, required=True)
    r.add_argument("--seed", type=int, default=0)
    r.add_argument("--seconds", type=float, default=None)
    r.add_argument("--out", required=True)
    r.set_defaults(fn=record)
    q = sub.add_parser("replay")
    q.add_argument("file")
    q.add_argument("--repeats", type=int, default=3)
    q.add_argument("--chunk", type=int, default=50, help="ticks per timed chunk")
    q.add_argument("--profile", action="store_true", help="cProfile the first timed pass")
    q.add_argument("--callgrind", action="store_true",
                   help="instructions of the first timed pass: run this under valgrind "
                        "--tool=callgrind --instr-atstart=no (it switches the instrumentation)")
    q.add_argument("--profile-lines", type=int, default=40)
    q.set_defaults(fn=replay)
    a = p.parse_args()
    return a.fn(a)


if __name__ == "__main__":
    sys.exit(main())

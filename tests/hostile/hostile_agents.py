"""Submissions that cheat or misbehave on purpose (tests/test_compete.py).

Each stands (earning what standing earns) until ``T_FAULT`` [s] of simulated time, then
commits its offence. In process, the four cheats of issue 9 (gc walk to the plant, a stack
frame's referee state, a monkeypatched referee, report.json rewritten at exit) all scored full
marks without moving; in the sandbox none of them can reach anything of the referee.
"""

import atexit
import gc
import json
import os
import signal
import socket
import sys
import time

import numpy as np

from pr2_drake.agents.standing import StandingAgent

T_FAULT = 0.05  # [s]


class _Later(StandingAgent):
    def __init__(self, target: str = ""):
        super().__init__()
        self.target = target

    def next_action(self, obs):
        if obs["time"] >= T_FAULT:
            self.offend(obs)
        return super().next_action(obs)

    def offend(self, obs):
        raise NotImplementedError


# -- the four cheats ------------------------------------------------------------------------
class GcTeleport(_Later):
    """Walks gc to every MultibodyPlant and puts the robot's base on the goal."""

    def offend(self, obs):
        goal = np.asarray(obs.get("goal", [4.96, 0.0, 0.0]), float)
        for o in gc.get_objects():
            try:
                testbed = getattr(o, "testbed", None)
                ctx = getattr(o, "plant_context", None)
                plant = getattr(testbed, "plant", None)
                if plant is None or ctx is None:
                    continue
                q = plant.GetPositions(ctx)
                q[4:7] = [goal[0], goal[1], goal[2] + 0.6]
                plant.SetPositions(ctx, q)
            except Exception:
                pass


class FrameReferee(_Later):
    """Walks up the stack to the episode and the referee and writes full marks."""

    def offend(self, obs):
        frame = sys._getframe()
        while frame is not None:
            for value in list(frame.f_locals.values()):
                status = getattr(value, "status", None)
                if status is not None and hasattr(status, "score"):
                    try:
                        status.score = status.max_score
                        status.success = True
                    except Exception:
                        pass
            frame = frame.f_back


class PatchReferee(_Later):
    """Monkeypatches the referee classes to award every item at once."""

    def offend(self, obs):
        import pr2_drake.tasks.base as base

        def judge(self, context, status):
            for r in self.spec.rubric:
                if r.points > 0:
                    self.award(status, r.item, 0.0)

        for name in list(sys.modules):
            if name.startswith("pr2_drake.tasks."):
                for value in vars(sys.modules[name]).values():
                    if isinstance(value, type) and issubclass(value, base.Referee):
                        value.judge = judge
        base.Referee.judge = judge


class AtexitReport(_Later):
    """Registers an exit hook that rewrites ``target`` (the run's report) with full marks,
    then leaves."""

    def offend(self, obs):
        def rewrite():
            with open(self.target, "w") as f:
                json.dump({"score": 15.0, "max_score": 15.0, "success": True}, f)

        atexit.register(rewrite)
        sys.exit(0)


# -- misbehaviour -----------------------------------------------------------------------------
class WritesOutside(_Later):
    def offend(self, obs):
        with open(self.target, "w") as f:
            f.write("pwned")


class OpensSocket(_Later):
    def offend(self, obs):
        s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        s.connect(("127.0.0.1", 80))


class ForkBomb(_Later):
    def offend(self, obs):
        for _ in range(1000):
            if os.fork() == 0:
                time.sleep(60)
                os._exit(0)


class Allocates10GB(_Later):
    def offend(self, obs):
        self.hoard = np.ones(10 * 2**30 // 8)


class IgnoresSigtermAndSleeps(_Later):
    def offend(self, obs):
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        while True:
            time.sleep(1.0)


class Spins(_Later):
    def offend(self, obs):
        while True:
            pass


class WaitsOnce(_Later):
    """Waits 1.5 s of wall clock once (no CPU), as a starved agent on a busy machine would."""

    def offend(self, obs):
        if not getattr(self, "waited", False):
            self.waited = True
            time.sleep(1.5)


class HardExit(_Later):
    def offend(self, obs):
        os._exit(7)


class Raises(_Later):
    def offend(self, obs):
        raise KeyError("no such joint")


class GarbageAction(StandingAgent):
    def next_action(self, obs):
        if obs["time"] >= T_FAULT:
            return {"legs": object()}
        return super().next_action(obs)


class GarbageOnTheChannel(_Later):
    """Writes bytes that are not a framed JSON answer on the channel to the parent."""

    def offend(self, obs):
        fd_out = int(sys.argv[2])
        os.write(fd_out, b"\x00\x00\x00\x10not json at all!")
        time.sleep(5)


class NeedsCamera(StandingAgent):
    """Not hostile: raises unless the camera frames arrived (through shared memory) intact."""

    def next_action(self, obs):
        rgb, depth = obs["cam"]["rgb"], obs["cam"]["distance_to_image_plane"]
        if rgb.dtype != np.uint8 or rgb.ndim != 3 or rgb.shape[2] != 3 or depth.dtype.kind != "f":
            raise ValueError(f"bad frames {rgb.dtype} {rgb.shape} {depth.dtype}")
        if obs["time"] > 0.05 and not rgb.any():
            raise ValueError("an all-black frame")
        rgb[:] = 0  # its own copy: the next frame must be intact again
        return super().next_action(obs)


class ReadsOthers(StandingAgent):
    """Raises if it can see any file in ``target`` (another submission's folder)."""

    def __init__(self, target: str = ""):
        super().__init__()
        if os.path.isdir(target) and os.listdir(target):
            raise RuntimeError(f"saw {os.listdir(target)}")


class SlowSteps(StandingAgent):
    """Within the step budget every step, but too slow for the episode's wall-clock limit."""

    def next_action(self, obs):
        time.sleep(0.3)
        return super().next_action(obs)


def _peeking_system():
    """A System agent that reads the whole plant state, after widening the child's list of
    offered ports (the parent decides what crosses, not the child)."""
    from pydrake.systems.framework import LeafSystem

    import pr2_drake.compete.child as child
    from pr2_drake.controllers.standing import StandingController

    for module in (child, sys.modules["__main__"]):  # the child runs as __main__
        if hasattr(module, "ALLOWED_INPUTS"):
            module.ALLOWED_INPUTS = module.ALLOWED_INPUTS + ("plant_state",)

    class PeeksAtPlantState(StandingController):
        __slots__ = ()

        def __init__(self):
            super().__init__()
            LeafSystem.DeclareVectorInputPort(self, "plant_state", 1)

    return PeeksAtPlantState


def PeeksAtPlantState():  # noqa: N802 (an agent factory)
    return _peeking_system()()

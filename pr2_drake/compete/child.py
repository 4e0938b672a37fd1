"""Inside the sandbox: build the agent, then answer each observation with an action.

``python -m pr2_drake.compete.child FD_IN FD_OUT FD_CAMERA SCRATCH`` (started by
:class:`pr2_drake.compete.sandbox.AgentProcess`). Requests are pickled dicts with ``op``
(the child trusts its parent); answers are JSON (the parent never unpickles agent data):

- ``init`` {spec, kwargs}: import and build the agent; answer {kind, control_dt, inputs}.
- ``reset`` {obs}: a ``next_action`` agent's ``reset(obs)`` if it has one; answer {}.
- ``act`` {obs}: a ``next_action`` agent; answer {action, compute} (compute: its time [s]).
- ``tick`` {time, ports}: a System agent; answer {action, compute}.

A System agent (a Drake System, like the built-in agents) runs in a diagram of its own with a
Simulator of its own, a tick per physics step. In one diagram Drake steps the plant and the
agent's unrestricted updates from the same state, then runs the agent's discrete updates with
the plant already stepped. So at the tick at t the child first runs the updates due at the
previous tick t_prev, with the port values from before the plant's step (``prev``: with the
previous answer applied, since ``joint_state``'s applied efforts follow it) for an agent with
unrestricted updates, or with the port values now (after the step) for an agent with discrete
state; then it fixes the inputs to the port values at t and answers its outputs (what the
plant uses for its step at t). Tests: the standing controller (unrestricted), the walking
agents and the moving-bar agent (discrete) give the same plant state as in process, bit for
bit; an agent that mixes both kinds (StepsButtonAgent) feeds its unrestricted updates the
after-step values too (the state differs by ~1e-10 after 40 ms).

Calls an agent must not make (sockets, processes, signals, writing outside its scratch
folder) raise PermissionError inside the agent and are reported with the next answer as
{forbidden}; the parent ends the episode ``agent_error``.
"""

from __future__ import annotations

import errno
import json
import mmap
import os
import sys
import time
from typing import Any

import numpy as np

from pr2_drake.framing import LENGTH, frame

# Testbed outputs a sandboxed System agent may read (copies of them cross the boundary).
ALLOWED_INPUTS = ("joint_state", "body_state", "pick_state", "task_feedback", "instruction",
                  "rgbd", "score")
TIME_TOLERANCE = 1e-7  # times closer than this are the same tick (sums of steps drift) [s]
_OUTPUTS = {"legs_command": "legs", "arms_command": "arms", "pick": "pick", "release": "release",
            "camera_capture": "camera_capture"}
_FORBIDDEN_EVENTS = ("socket.__new__", "socket.connect", "socket.bind", "os.fork", "os.forkpty",
                     "os.system", "os.posix_spawn", "os.exec", "os.spawn", "subprocess.Popen",
                     "os.kill", "os.killpg", "signal.pthread_kill", "pty.spawn")


class SystemRunner:
    """A Drake System agent stepped tick by tick (see the module docstring)."""

    def __init__(self, system):
        from pydrake.systems.analysis import Simulator
        from pydrake.systems.framework import DiagramBuilder

        self.inputs = [system.get_input_port(i).get_name() for i in range(system.num_input_ports())]
        bad = [n for n in self.inputs if n not in ALLOWED_INPUTS]
        if bad:
            raise ValueError(f"agent input ports {bad} are not offered in a competition; a "
                             f"System agent may read {list(ALLOWED_INPUTS)}")
        builder = DiagramBuilder()
        builder.AddSystem(system)
        self.system = system
        self.diagram = builder.Build()
        self.sim = Simulator(self.diagram)
        self.context = system.GetMyMutableContextFromRoot(self.sim.get_mutable_context())
        self.ports_in = {n: system.GetInputPort(n) for n in self.inputs}
        self.ports_out = {key: system.GetOutputPort(n) for n, key in _OUTPUTS.items()
                          if system.HasOutputPort(n)}
        self.started = False
        self.discrete = self.context.num_discrete_state_groups() > 0

    def peek(self, values: dict[str, Any]) -> dict[str, Any]:
        """The outputs of the default state (before initialization) for ``values``."""
        self._fix(values)
        return self._outputs()

    def tick(self, t: float, values: dict[str, Any], prev: dict[str, Any] | None = None,
             t_prev: float | None = None) -> dict[str, Any]:
        """The outputs at ``t`` for the testbed's port values ``values`` at ``t``, after the
        updates due at ``t_prev`` ran with ``prev`` (the port values once the previous answer
        was applied: the applied efforts in ``joint_state`` depend on it)."""
        sim = self.sim
        if self.started and t_prev is not None:
            # In one diagram the plant steps first (an unrestricted update) and a discrete
            # update at t_prev sees its result: the port values now. Unrestricted updates at
            # t_prev see the state before the step, with the previous answer applied: prev.
            self._fix(values if self.discrete or prev is None else prev)
            sim.AdvanceTo(t_prev + TIME_TOLERANCE)  # the updates due at t_prev
            sim.AdvanceTo(max(t_prev + TIME_TOLERANCE, t - TIME_TOLERANCE))  # and before t
        self._fix(values)
        if not self.started:
            sim.Initialize()
            self.started = True
        else:
            sim.AdvanceTo(t)  # to t itself (outputs may read the time); the updates at t wait
        return self._outputs()

    def _fix(self, values: dict[str, Any]) -> None:
        for name, port in self.ports_in.items():
            port.FixValue(self.context, values[name])

    def _outputs(self) -> dict[str, Any]:
        return {key: port.Eval(self.context) for key, port in self.ports_out.items()}


def jsonable(x: Any, where: str = "action") -> Any:
    """``x`` as JSON data (arrays as lists; floats round-trip exactly). Raises TypeError
    naming the key."""
    from pr2_drake.ports import JointGroupCommand

    if isinstance(x, JointGroupCommand):
        from pr2_drake.observation import command_to_dict

        x = command_to_dict(x)
    if isinstance(x, dict):
        return {str(k): jsonable(v, f"{where}[{k!r}]") for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v, where) for v in x]
    if isinstance(x, np.ndarray):
        if x.dtype.kind not in "biuf" or x.size > 10000:
            raise TypeError(f"{where}: an array of {x.dtype} x {x.size} cannot be sent")
        return x.astype(np.float64) if x.ndim == 1 and x.dtype.kind != "b" else x.tolist()
    if isinstance(x, np.generic):
        return x.item()
    if x is None or isinstance(x, (bool, int, float, str)):
        return x
    raise TypeError(f"{where}: a {type(x).__name__} cannot be sent")


def _binary(x: Any, blob: list[bytes], used: list[int]) -> Any:
    """``x`` with its numeric arrays moved into ``blob`` as float64 (see Child.send)."""
    if isinstance(x, dict):
        return {k: _binary(v, blob, used) for k, v in x.items()}
    if isinstance(x, list) and x and isinstance(x[0], float) and len(x) > 4:
        x = np.asarray(x, dtype=np.float64)
    if isinstance(x, np.ndarray) and x.ndim == 1:
        data = x.astype("<f8").tobytes()
        ref = {"__f8__": [used[0], x.size]}
        blob.append(data)
        used[0] += len(data)
        return ref
    return x


class Child:
    """The request loop."""

    def __init__(self, fd_in: int, fd_out: int, fd_cam: int, scratch: str):
        self.fd_in, self.fd_out = fd_in, fd_out
        self.cam = mmap.mmap(fd_cam, 0, prot=mmap.PROT_READ)
        self.scratch = os.path.realpath(scratch)
        self.agent = None
        self.runner: SystemRunner | None = None
        self.forbidden: list[str] = []
        self.priors: dict[str, Any] = {}
        self.start: tuple = ()

    # -- channel ------------------------------------------------------------------------------
    def recv(self) -> dict[str, Any] | None:
        import pickle

        header = self._read(4)
        if header is None:
            return None
        data = self._read(LENGTH.unpack(header)[0])
        return None if data is None else self.unpack(pickle.loads(data))

    def _read(self, n: int) -> bytes | None:
        out = bytearray()
        while len(out) < n:
            chunk = os.read(self.fd_in, n - len(out))
            if not chunk:
                return None
            out += chunk
        return bytes(out)

    def send(self, reply: dict[str, Any]) -> None:
        """One frame: length, then the JSON header's length, the header, and the float64
        arrays it refers to (``{"__f8__": [offset, count]}``) as raw bytes."""
        blob: list[bytes] = []
        head = json.dumps(_binary(reply, blob, [0])).encode()
        view = memoryview(frame(frame(head) + b"".join(blob)))
        while view:
            view = view[os.write(self.fd_out, view):]

    def unpack(self, x: Any) -> Any:
        """Replace shared-memory references (see ``sandbox.to_shared``) by array copies."""
        if isinstance(x, dict):
            if "__shm__" in x:
                _, offset, shape, dtype = x["__shm__"]
                count = int(np.prod(shape))
                return np.frombuffer(self.cam, np.dtype(dtype), count, offset).reshape(
                    shape).copy()
            return {k: self.unpack(v) for k, v in x.items()}
        if hasattr(x, "__dataclass_fields__") and any(
                isinstance(getattr(x, f), dict) for f in x.__dataclass_fields__):
            for f in x.__dataclass_fields__:
                setattr(x, f, self.unpack(getattr(x, f)))
        return x

    # -- requests -----------------------------------------------------------------------------
    def handle(self, msg: dict[str, Any]) -> dict[str, Any]:
        op = msg.get("op")
        if op == "init":
            self.priors = dict(msg["kwargs"].get("priors") or {})
            self.start = msg.get("start") or (np.zeros(3), np.array([1.0, 0, 0, 0]))
            return self.init(msg["spec"], msg["kwargs"])
        if op == "reset":
            if self.runner is None and callable(getattr(self.agent, "reset", None)):
                self.agent.reset(self.observation(msg))
            return {}
        t0 = time.perf_counter()
        if op == "act":
            action = self.agent.next_action(self.observation(msg))
        elif op == "tick":
            action = self.runner.tick(msg["time"], msg["ports"], msg.get("prev"),
                                      msg.get("t_prev"))
        elif op == "peek":
            action = self.runner.peek(msg["ports"])
        else:
            raise RuntimeError(f"unknown request {op!r}")
        compute = time.perf_counter() - t0
        try:
            data = jsonable(action)
        except TypeError as e:
            return {"invalid": str(e)}
        return {"action": data, "compute": compute}

    def observation(self, msg: dict[str, Any]) -> dict[str, Any]:
        """The observation dictionary of a request (built here from the port values)."""
        if "obs" in msg:
            return msg["obs"]
        from pr2_drake.observation import observation_from_ports

        return observation_from_ports(msg["ports"], msg["time"], self.priors, *self.start)

    def init(self, spec: str, kwargs: dict[str, Any],
             start: tuple | None = None) -> dict[str, Any]:
        from pr2_drake.agents import (
            instantiate_agent,
            is_policy_agent,
            is_system_agent,
            load_agent_class,
        )

        agent = instantiate_agent(load_agent_class(spec), **kwargs)
        if is_system_agent(agent):
            self.runner = SystemRunner(agent)
            return {"kind": "system", "control_dt": None, "inputs": self.runner.inputs,
                    "discrete": self.runner.discrete}
        if not is_policy_agent(agent):
            raise ValueError(f"agent {spec!r} is neither a Drake System nor has next_action(obs)")
        self.agent = agent
        dt = getattr(agent, "control_dt", None)
        return {"kind": "policy", "inputs": [],
                "control_dt": float(dt) if isinstance(dt, (int, float)) else None}

    # -- forbidden calls ----------------------------------------------------------------------
    def audit(self, event: str, args: tuple) -> None:
        if event.startswith(_FORBIDDEN_EVENTS):
            self._forbid(event)
        elif event == "open" and len(args) >= 3 and self._writes(args[1], args[2]):
            path = args[0]
            if isinstance(path, int):
                return
            real = os.path.realpath(os.fsdecode(path))
            if real not in ("/dev/null", self.scratch) and \
                    not real.startswith(self.scratch + os.sep):
                self._forbid(f"open({real!r}) for writing")

    @staticmethod
    def _writes(mode, flags) -> bool:
        if isinstance(mode, str):
            return any(c in mode for c in "wax+")
        return isinstance(flags, int) and bool(flags & (os.O_WRONLY | os.O_RDWR | os.O_CREAT))

    def _forbid(self, what: str) -> None:
        self.forbidden.append(what)
        raise PermissionError(f"forbidden in the competition sandbox: {what}")

    def loop(self) -> None:
        while True:
            msg = self.recv()
            if msg is None:
                return
            try:
                reply = self.handle(msg)
            except SystemExit as e:
                code = e.code if isinstance(e.code, (int, str, type(None))) else str(e.code)
                reply = {"exit": code}
            except MemoryError as e:
                reply = {"error": f"MemoryError: {e}", "type": "MemoryError"}
            except OSError as e:
                # an mmap or a thread beyond the address-space limit: out of memory
                kind = "MemoryError" if e.errno == errno.ENOMEM else type(e).__name__
                reply = {"error": f"{type(e).__name__}: {' '.join(str(e).split())}"[:1000],
                         "type": kind}
            except BaseException as e:  # the agent's fault, whatever it is: report it
                reply = {"error": f"{type(e).__name__}: {' '.join(str(e).split())}"[:1000],
                         "type": type(e).__name__}
            if self.forbidden:
                reply = {"forbidden": "; ".join(dict.fromkeys(self.forbidden))[:1000]}
            self.send(reply)


def main(argv: list[str]) -> int:
    fd_in, fd_out, fd_cam = (int(a) for a in argv[:3])
    child = Child(fd_in, fd_out, fd_cam, argv[3])
    # What the agents and the runner need is imported before the audit hook is installed.
    import importlib

    for module in ("pydrake.all", "pr2_drake.agents", "pr2_drake.observation"):
        importlib.import_module(module)
    sys.addaudithook(child.audit)
    child.loop()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

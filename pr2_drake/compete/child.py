"""Inside the sandbox: build the agent, then answer each observation with an action.

``python -m pr2_drake.compete.child FD_IN FD_OUT FD_CAMERA`` (started by
:class:`pr2_drake.compete.sandbox.AgentProcess`). Requests (pickled dicts with ``op``):

- ``init`` {spec, kwargs}: import and build the agent; answer {kind, control_dt}.
- ``reset`` {obs}: call the agent's ``reset(obs)`` if it has one; answer {}.
- ``act`` {obs}: answer {action, compute} (compute: the agent's own time [s]).

A System agent (a Drake System, like the built-in ones) runs in a small diagram of its own
whose inputs ``joint_state`` and ``body_state`` are fixed from each observation; it advances
to the observation's time, so its periodic updates see the same inputs as in the testbed.
Answers are JSON; a raise is {error, type}, ``sys.exit`` is {exit}, an action that cannot be
sent is {invalid}.
"""

from __future__ import annotations

import json
import mmap
import os
import struct
import sys
import time
from typing import Any

import numpy as np

_HEADER = struct.Struct(">I")
_OUTPUTS = {"legs_command": "legs", "arms_command": "arms", "pick": "pick", "release": "release"}
_INPUTS = ("joint_state", "body_state")


class SystemPolicy:
    """A Drake System agent evaluated on observations (see the module docstring)."""

    def __init__(self, system):
        from pydrake.systems.analysis import Simulator
        from pydrake.systems.framework import DiagramBuilder

        for i in range(system.num_input_ports()):
            name = system.get_input_port(i).get_name()
            if name not in _INPUTS:
                raise ValueError(f"a sandboxed System agent may read only {_INPUTS}; it has "
                                 f"input port {name!r}")
        builder = DiagramBuilder()
        builder.AddSystem(system)
        self.system = system
        self.diagram = builder.Build()
        self.sim = Simulator(self.diagram)
        self.context = system.GetMyMutableContextFromRoot(self.sim.get_mutable_context())
        periods = _periods(system)
        self.control_dt = min(periods) if periods else None
        self.started = False

    def next_action(self, obs: dict[str, Any]) -> dict[str, Any]:
        from pr2_drake.observation import state_vectors_from_obs

        joint_state, body_state = state_vectors_from_obs(obs)
        values = {"joint_state": joint_state, "body_state": body_state}
        for name in _INPUTS:
            if self.system.HasInputPort(name):
                self.system.GetInputPort(name).FixValue(self.context, values[name])
        if not self.started:
            self.sim.Initialize()
            self.started = True
        eps = 1e-6 * (self.control_dt or 1e-3)
        self.sim.AdvanceTo(float(obs["time"]) + eps)  # runs the updates due at obs time
        action: dict[str, Any] = {}
        for port_name, key in _OUTPUTS.items():
            if self.system.HasOutputPort(port_name):
                action[key] = self.system.GetOutputPort(port_name).Eval(self.context)
        return action


def _periods(system) -> list[float]:
    """The shortest update period [s] of ``system`` (its first event after t = 0), or []."""
    context = system.CreateDefaultContext()
    context.SetTime(1e-9)
    t = system.CalcNextUpdateTime(context, system.AllocateCompositeEventCollection())
    return [t] if np.isfinite(t) and t > 1e-6 else []


def jsonable(x: Any, where: str = "action") -> Any:
    """``x`` as JSON data (arrays as lists; floats exact). Raises TypeError naming the key."""
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
        return x.tolist()
    if isinstance(x, np.generic):
        return x.item()
    if x is None or isinstance(x, (bool, int, float, str)):
        return x
    if hasattr(x, "get_value") and hasattr(x, "size"):  # a BasicVector output
        return np.asarray(x.get_value()).tolist()
    raise TypeError(f"{where}: a {type(x).__name__} cannot be sent")


class Child:
    """The request loop."""

    def __init__(self, fd_in: int, fd_out: int, fd_cam: int):
        self.fd_in, self.fd_out = fd_in, fd_out
        self.cam = mmap.mmap(fd_cam, 0, prot=mmap.PROT_READ)
        self.agent = None

    def recv(self) -> dict[str, Any] | None:
        import pickle

        header = self._read(4)
        if header is None:
            return None
        data = self._read(_HEADER.unpack(header)[0])
        return None if data is None else pickle.loads(data)

    def _read(self, n: int) -> bytes | None:
        out = bytearray()
        while len(out) < n:
            chunk = os.read(self.fd_in, n - len(out))
            if not chunk:
                return None
            out += chunk
        return bytes(out)

    def send(self, reply: dict[str, Any]) -> None:
        data = json.dumps(reply).encode()
        view = memoryview(_HEADER.pack(len(data)) + data)
        while view:
            view = view[os.write(self.fd_out, view):]

    def obs(self, obs: dict[str, Any]) -> dict[str, Any]:
        cam = obs.get("cam")
        if isinstance(cam, dict):
            images = {}
            for key, m in cam.items():
                dtype = np.dtype(m["dtype"])
                count = int(np.prod(m["shape"]))
                images[key] = np.frombuffer(self.cam, dtype, count, m["offset"]).reshape(
                    m["shape"]).copy()
            obs["cam"] = images
        return obs

    def handle(self, msg: dict[str, Any]) -> dict[str, Any]:
        op = msg.get("op")
        if op == "init":
            return self.init(msg["spec"], msg["kwargs"])
        if op == "reset":
            if callable(getattr(self.agent, "reset", None)):
                self.agent.reset(self.obs(msg["obs"]))
            return {}
        if op == "act":
            obs = self.obs(msg["obs"])
            t0 = time.perf_counter()
            action = self.agent.next_action(obs)
            compute = time.perf_counter() - t0
            try:
                data = jsonable(action)
            except TypeError as e:
                return {"invalid": str(e)}
            return {"action": data, "compute": compute}
        raise RuntimeError(f"unknown request {op!r}")

    def init(self, spec: str, kwargs: dict[str, Any]) -> dict[str, Any]:
        from pr2_drake.agents import (
            instantiate_agent,
            is_policy_agent,
            is_system_agent,
            load_agent_class,
        )

        agent = instantiate_agent(load_agent_class(spec), **kwargs)
        if is_system_agent(agent):
            self.agent = SystemPolicy(agent)
            return {"kind": "system", "control_dt": self.agent.control_dt}
        if not is_policy_agent(agent):
            raise ValueError(f"agent {spec!r} is neither a Drake System nor has next_action(obs)")
        self.agent = agent
        dt = getattr(agent, "control_dt", None)
        return {"kind": "policy", "control_dt": float(dt) if isinstance(dt, (int, float)) else None}

    def loop(self) -> None:
        while True:
            msg = self.recv()
            if msg is None:
                return
            try:
                reply = self.handle(msg)
            except SystemExit as e:
                reply = {"exit": e.code if isinstance(e.code, (int, str, type(None))) else
                         str(e.code)}
            except MemoryError as e:
                reply = {"error": f"MemoryError: {e}", "type": "MemoryError"}
            except BaseException as e:  # the agent's fault, whatever it is: report it
                reply = {"error": f"{type(e).__name__}: {' '.join(str(e).split())}"[:1000],
                         "type": type(e).__name__}
            self.send(reply)


def main(argv: list[str]) -> int:
    fd_in, fd_out, fd_cam = (int(a) for a in argv[:3])
    Child(fd_in, fd_out, fd_cam).loop()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

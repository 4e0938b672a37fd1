"""Run one scored episode: testbed + agent, simulated until the referee ends it.

Used by ``pr2-drake run`` and ``pr2-drake eval``; usable from Python::

    from pr2_drake.episode import EpisodeOptions, run_episode
    report = run_episode(EpisodeOptions(task=1, seed=7))
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, TextIO

import numpy as np
from pydrake.geometry import Meshcat
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from pr2_drake.agents import (
    DEFAULT_AGENTS,
    instantiate_agent,
    is_policy_agent,
    is_system_agent,
    load_agent_class,
)
from pr2_drake.camera import CameraSettings
from pr2_drake.ports import P_WB
from pr2_drake.tasks.base import EpisodeStatus
from pr2_drake.testbed import Testbed, TestbedConfig

FREE_RUN_SECONDS = 10.0  # default length of a run without a task [s]
FREE_FALL_HEIGHT = 0.35  # without a task: fallen below this base height [m]


@dataclass
class EpisodeOptions:
    """One episode.

    Attributes:
        task: task id or name; None = flat ground, no referee (runs ``seconds``).
        seed: episode seed.
        agent: "module:Class"; None = the task's default agent.
        diagram: a diagram YAML (see :mod:`pr2_drake.diagrams`) whose blocks replace the agent.
        seconds: stop after this much simulated time [s] (default: the task's time limit).
        time_step: physics step [s].
        camera: camera settings override (None: the task's own choice).
        meshcat: draw to this Meshcat (and pace the run at real time unless ``realtime`` is 0).
        record: write a self-contained Meshcat replay (HTML) to this path.
        realtime: target real-time rate with Meshcat (0 = as fast as possible).
        progress: where to print progress lines (None: silent).
    """

    task: int | str | None = None
    seed: int = 0
    agent: str | None = None
    diagram: str | None = None
    seconds: float | None = None
    time_step: float = 0.001
    camera: CameraSettings | None = None
    meshcat: Meshcat | None = None
    record: str | None = None
    realtime: float = 1.0
    progress: TextIO | None = field(default=None)


def _config(opts: EpisodeOptions) -> TestbedConfig:
    cfg = TestbedConfig(task=opts.task, seed=int(opts.seed), time_step=opts.time_step)
    if opts.camera is not None:
        cfg.camera = opts.camera
    return cfg


class _Progress:
    """Prints 'sim time / limit, score, real-time factor' every ``every`` wall seconds."""

    def __init__(self, stream: TextIO | None, limit: float, every: float = 2.0):
        self.stream, self.limit, self.every = stream, limit, every
        self.start = time.perf_counter()
        self.last = self.start

    def __call__(self, t: float, status: EpisodeStatus, force: bool = False) -> None:
        now = time.perf_counter()
        if self.stream is None or (not force and now - self.last < self.every):
            return
        self.last = now
        wall = now - self.start
        rtf = t / wall if wall > 0 else float("nan")
        limit = "" if math.isinf(self.limit) else f"/{self.limit:.0f}"
        score = f"  score {status.score:g}/{status.max_score:g}" if status.max_score else ""
        print(f"  t = {t:6.2f}{limit} s{score}  real-time factor {rtf:4.2f}", file=self.stream,
              flush=True)


def run_episode(opts: EpisodeOptions) -> dict[str, Any]:
    """Simulate one episode and return its report (see ``report.json`` in the README)."""
    wall_start = time.perf_counter()
    diagram = None
    if opts.diagram:
        from pr2_drake.diagrams import load_diagram_spec

        diagram = load_diagram_spec(opts.diagram)
        if opts.agent:
            raise ValueError("give either a diagram YAML or --agent, not both")
        opts = replace(opts, task=opts.task if opts.task is not None else diagram.task)
        agent_spec = opts.diagram
    else:
        agent_spec = opts.agent or DEFAULT_AGENTS.get(_task_key(opts.task))
        cls = load_agent_class(agent_spec)
    meshcat = opts.meshcat
    if opts.record and meshcat is None:
        meshcat = Meshcat()
    testbed = Testbed(_config(opts), meshcat)
    limit = testbed.task.spec.time_limit if testbed.task is not None else FREE_RUN_SECONDS
    if opts.seconds is not None:
        if not opts.seconds > 0:
            raise ValueError(f"seconds must be positive, got {opts.seconds}")
        limit = min(limit, opts.seconds) if testbed.task is not None else opts.seconds
    context = dict(priors=dict(testbed.scene.priors), task=opts.task, seed=opts.seed)
    if meshcat is not None and opts.record:
        meshcat.StartRecording()
    if diagram is not None:
        from pr2_drake.diagrams import wire_diagram

        runner = _SystemRunner(testbed, lambda b: wire_diagram(b, testbed, diagram, **context),
                               limit)
    elif is_system_agent(agent := instantiate_agent(cls, **context)):
        runner = _SystemRunner(testbed, lambda b: connect_by_name(b, testbed, b.AddSystem(agent)),
                               limit)
    elif is_policy_agent(agent):
        runner = _PolicyRunner(testbed, agent, limit)
    else:
        raise ValueError(
            f"agent {agent_spec!r} is neither a Drake System nor has next_action(obs)"
        )
    if meshcat is not None and opts.realtime and not opts.record:
        runner.simulator.set_target_realtime_rate(opts.realtime)
    progress = _Progress(opts.progress, limit)
    sim_start = time.perf_counter()
    status, message = runner.run(progress)
    sim_wall = time.perf_counter() - sim_start
    t = runner.time()
    progress(t, status, force=True)
    if meshcat is not None and opts.record:
        meshcat.StopRecording()
        meshcat.PublishRecording()
        Path(opts.record).write_text(meshcat.StaticHtml())
    report = {
        "task": None if testbed.task is None else testbed.task.id,
        "task_name": "flat" if testbed.task is None else testbed.task.name,
        "seed": int(opts.seed),
        "agent": agent_spec,
        "score": float(status.score),
        "max_score": float(status.max_score),
        "success": bool(status.success),
        "termination": status.termination or "timeout",
        "items": [{"item": e.item, "points": e.points, "time": round(e.time, 4)}
                  for e in status.items],
        "sim_time": round(t, 6),
        "wall_time": round(time.perf_counter() - wall_start, 3),
        "real_time_factor": round(t / sim_wall, 3) if sim_wall > 0 else None,
    }
    if message:
        report["message"] = message
    return report


def _task_key(task):
    if task is None:
        return None
    from pr2_drake.tasks import task_id

    return task_id(task)


def _free_status(t: float, z: float, limit: float) -> EpisodeStatus:
    """Verdict without a referee: fell, diverged or time up."""
    s = EpisodeStatus(time=t)
    if not np.isfinite(z):
        s.done, s.termination = True, "diverged"
    elif z < FREE_FALL_HEIGHT:
        s.done, s.termination = True, "fell"
    elif t >= limit - 1e-9:
        s.done, s.termination = True, "timeout"
    return s


class _SystemRunner:
    """Testbed plus blocks added by ``wire(builder)``, simulated in chunks."""

    CHUNK = 0.05  # simulated seconds between verdict checks

    def __init__(self, testbed: Testbed, wire, limit: float):
        builder = DiagramBuilder()
        builder.AddSystem(testbed)
        wire(builder)
        self.diagram = builder.Build()
        self.testbed, self.limit = testbed, limit
        self.simulator = Simulator(self.diagram)
        self.ctx = self.simulator.get_mutable_context()
        self.tb_ctx = testbed.GetMyContextFromRoot(self.ctx)

    def time(self) -> float:
        return self.ctx.get_time()

    def status(self) -> EpisodeStatus:
        tb, ctx = self.testbed, self.tb_ctx
        if tb.task is not None:
            s = tb.GetOutputPort("episode").Eval(ctx)
            if not s.done and ctx.get_time() >= self.limit - 1e-9:
                s = replace(s, done=True, termination="timeout", items=list(s.items))
            return s
        z = tb.GetOutputPort("body_state").Eval(ctx)[P_WB][2]
        return _free_status(ctx.get_time(), z, self.limit)

    def run(self, progress) -> tuple[EpisodeStatus, str]:
        self.simulator.Initialize()
        status = self.status()
        while not status.done:
            t_next = min(self.ctx.get_time() + self.CHUNK, self.limit)
            try:
                self.simulator.AdvanceTo(t_next)
            except RuntimeError as e:
                return _diverged(status), f"simulation diverged: {e}"
            status = self.status()
            progress(self.ctx.get_time(), status)
        return status, ""


class _PolicyRunner:
    """A next_action(obs) agent driven through Env."""

    def __init__(self, testbed: Testbed, agent, limit: float):
        from pr2_drake.env import Env

        self.env = Env.from_testbed(
            testbed, control_dt=getattr(agent, "control_dt", None), time_limit=limit
        )
        self.agent, self.limit = agent, limit
        self.simulator = self.env.simulator

    def time(self) -> float:
        return self.env.time

    def run(self, progress) -> tuple[EpisodeStatus, str]:
        obs = self.env.reset()
        if hasattr(self.agent, "reset"):
            self.agent.reset(obs)
        done = self.env.status.done
        while not done:
            done, _, obs = self.env.step(self.agent.next_action(obs))
            status = self.env.status
            if not done and self.env.time >= self.limit - 1e-9:
                return replace(status, done=True, termination="timeout", items=list(status.items)), ""
            progress(self.env.time, status)
        message = getattr(self.env, "divergence_message", "")
        return self.env.status, (f"simulation diverged: {message}" if message else "")


def _diverged(s: EpisodeStatus) -> EpisodeStatus:
    return EpisodeStatus(s.score, s.max_score, True, False, "diverged", list(s.items), s.time)


def connect_by_name(builder: DiagramBuilder, testbed, agent) -> list[str]:
    """Connect every agent input to the testbed output of the same name and every agent
    output to the testbed input of the same name. Returns the connections made.

    Raises:
        ValueError: an agent input port has no testbed output of that name.
    """
    made = []
    for i in range(agent.num_input_ports()):
        port = agent.get_input_port(i)
        name = port.get_name()
        if not testbed.HasOutputPort(name):
            outputs = [testbed.get_output_port(k).get_name() for k in range(testbed.num_output_ports())]
            raise ValueError(
                f"agent input port {name!r} has no testbed output of that name; testbed outputs: "
                f"{outputs}"
            )
        builder.Connect(testbed.GetOutputPort(name), port)
        made.append(f"testbed.{name} -> agent.{name}")
    for i in range(agent.num_output_ports()):
        port = agent.get_output_port(i)
        name = port.get_name()
        if testbed.HasInputPort(name):
            builder.Connect(port, testbed.GetInputPort(name))
            made.append(f"agent.{name} -> testbed.{name}")
    return made

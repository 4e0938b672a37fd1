"""Run one episode from its scenario: build it with its agent, drive it, report.

``pr2-drake run`` and ``eval`` come here::

    from pr2_drake.run import run_episode
    from pr2_drake.scenario import Scenario
    report = run_episode(Scenario(task=1, seed=7))

:func:`run_episode` resolves the agent (the scenario's ``agent``, its ``diagram``, or the task's
default), builds the :class:`pr2_drake.episode.Episode` (which validates the scenario), drives
it (:mod:`pr2_drake.drive`), optionally draws, records and prints progress, and returns the
report (see :meth:`pr2_drake.episode.Episode.report`).
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import replace
from pathlib import Path
from typing import Any, TextIO

from pydrake.geometry import Meshcat
from pydrake.systems.framework import DiagramBuilder

from pr2_drake.agents import instantiate_agent, is_policy_agent, is_system_agent, load_agent_class
from pr2_drake.drive import drive_blocks, drive_policy
from pr2_drake.env import Env
from pr2_drake.episode import Episode, Wiring, wire_system
from pr2_drake.recording import frame_robot, quiet_meshcat, with_camera_recorder, write_replay
from pr2_drake.scenario import Scenario, ScenarioError
from pr2_drake.tasks import AgentEntry, agent_entry
from pr2_drake.tasks.base import EpisodeStatus
from pr2_drake.testbed import Testbed


class Progress:
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
        limit = "" if math.isinf(self.limit) else f"/{self.limit:g}"
        score = f"  score {status.score:g}/{status.max_score:g}" if status.max_score else ""
        print(f"  t = {t:6.2f}{limit} s{score}  real-time factor {rtf:4.2f}", file=self.stream,
              flush=True)


def agent_spec(scenario: Scenario) -> str:
    """The agent a scenario runs: its ``agent``, its ``diagram``, or the task's default."""
    if scenario.diagram:
        return scenario.diagram
    return _agent_entry(scenario).agent


def agent_params(scenario: Scenario) -> dict[str, str]:
    """The parameter files the scenario's agent is built with: its task's registry row's (when
    it is that task's default agent), then the scenario's ``agent_params`` over them."""
    if scenario.diagram:
        return dict(scenario.agent_params)
    return {**_agent_entry(scenario).agent_params, **scenario.agent_params}


def _agent_entry(scenario: Scenario) -> AgentEntry:
    try:
        return agent_entry(scenario.task, scenario.agent or None)
    except ValueError as e:
        raise ScenarioError(str(e)) from None


def check_output_path(path: str | None, what: str) -> None:
    """Fail before an episode starts if ``path`` cannot be written (a folder, no parent)."""
    if path is None:
        return
    p = Path(path)
    if p.is_dir():
        raise ScenarioError(f"{what} {path}: is a folder; give a file name")
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise ScenarioError(f"{what} {path}: folder {parent} does not exist")
    if not os.access(p if p.exists() else parent, os.W_OK):
        raise ScenarioError(f"{what} {path}: cannot write there")


def run_episode(scenario: Scenario, *, meshcat: Meshcat | None = None,
                record: str | None = None, progress: TextIO | None = None,
                record_camera: str | None = None, camera_depth: bool = False,
                watchers: Wiring | None = None) -> dict[str, Any]:
    """Build the scenario, run its agent until the episode ends, and return the report.

    Args:
        scenario: the episode (see :class:`Scenario`).
        meshcat: draw to this Meshcat (paced at ``scenario.realtime_rate`` unless recording).
        record: write a self-contained Meshcat replay (HTML) to this path.
        progress: where to print progress lines (None: silent).
        record_camera: write the head camera's colour stream to this mp4 file at the camera's
            rate (turns the camera on if the scenario has it off); ``camera_depth``: put the
            depth, as a colour map, beside the colour.
        watchers: ``watchers(builder, testbed)`` adds blocks that watch the episode (they read
            testbed outputs and drive none of its inputs), e.g. ``pr2-drake render``'s state
            recorder; wired after the agent.

    Raises:
        ScenarioError (a ValueError): the episode could not start (bad scenario, agent spec,
            agent constructor, diagram file or output path). Once it runs, every fault ends
            the episode with a named termination in the report instead.
    """
    wall_start = time.perf_counter()
    check_output_path(record, "--record")
    check_output_path(record_camera, "--record-camera")
    spec = agent_spec(scenario)
    if record_camera and (scenario.camera is None or not scenario.camera.enabled):
        scenario = replace(scenario, camera=replace(scenario.camera or task_camera(scenario),
                                                    enabled=True))
    if record and meshcat is None:
        meshcat = quiet_meshcat()
    recorders: list = []
    if scenario.diagram:
        scenario, wire = _diagram_wiring(scenario)
    else:
        wire = _agent_wiring(scenario, spec)
    wire = with_camera_recorder(wire, record_camera, camera_depth, recorders)
    episode = _build(scenario, _with_watchers(wire, watchers), meshcat)
    policy = None if scenario.diagram or is_system_agent(episode.blocks) else episode.blocks
    if meshcat is not None:
        frame_robot(meshcat, episode.testbed)
    if meshcat is not None and record:
        meshcat.StartRecording()
    if meshcat is not None and scenario.realtime_rate and not record:
        episode.simulator.set_target_realtime_rate(scenario.realtime_rate)
    show = Progress(progress, episode.limit)
    sim_start = time.perf_counter()
    try:
        if policy is None:
            drive_blocks(episode, show)
        else:
            env = Env.from_episode(episode, control_dt=getattr(policy, "control_dt", None))
            drive_policy(env, policy, show)
    finally:
        for recorder in recorders:
            recorder.close()
    sim_wall = time.perf_counter() - sim_start
    show(episode.time, episode.status, force=True)
    if meshcat is not None and record:
        write_replay(meshcat, record)
    return episode.report(spec, time.perf_counter() - wall_start, sim_wall)


def _agent_kwargs(scenario: Scenario, testbed: Testbed) -> dict[str, Any]:
    """What an agent's (or a diagram block's) constructor may take: the task's priors, the
    task id, the seed and the parameter files (:func:`agent_params`)."""
    return dict(priors=dict(testbed.scene.priors), task=scenario.task, seed=scenario.seed,
                **agent_params(scenario))


def _agent_wiring(scenario: Scenario, spec: str) -> Wiring:
    """The wiring of an agent class: a System is wired by port name; a ``next_action``
    agent is kept as the episode's blocks (the driver calls it)."""
    try:
        cls = load_agent_class(spec)
    except ValueError as e:
        raise ScenarioError(str(e)) from None

    def wire(builder: DiagramBuilder, testbed: Testbed):
        agent = instantiate_agent(cls, **_agent_kwargs(scenario, testbed))
        if is_system_agent(agent):
            return wire_system(agent)(builder, testbed)
        if not is_policy_agent(agent):
            raise ScenarioError(
                f"agent {spec!r} is neither a Drake System nor has next_action(obs)")
        return agent

    return wire


def _diagram_wiring(scenario: Scenario) -> tuple[Scenario, Wiring]:
    """The wiring of a diagram YAML, and the scenario with the diagram's task (when the
    scenario names none)."""
    from pr2_drake.diagrams import load_diagram_spec, wire_diagram

    diagram = load_diagram_spec(scenario.diagram)
    if scenario.task is None and diagram.task is not None:
        scenario = replace(scenario, task=diagram.task)

    def wire(builder: DiagramBuilder, testbed: Testbed):
        kwargs = _agent_kwargs(scenario, testbed)
        return wire_diagram(builder, testbed, diagram, **kwargs)

    return scenario, wire


def _with_watchers(wire: Wiring | None, watchers: Wiring | None) -> Wiring | None:
    """``wire``, then ``watchers`` (see :func:`run_episode`); the blocks are ``wire``'s."""
    if watchers is None:
        return wire

    def wire_and_watch(builder: DiagramBuilder, testbed: Testbed):
        blocks = wire(builder, testbed) if wire is not None else None
        watchers(builder, testbed)
        return blocks

    return wire_and_watch


def task_camera(scenario: Scenario):
    """The camera settings the scenario's task asks for (its YAML block), or the defaults."""
    from pr2_drake.camera import CameraSettings

    if scenario.task is None:
        return CameraSettings()
    from pr2_drake.tasks import get_task

    block = dict(get_task(scenario.task).spec.camera)
    block.pop("enabled", None)
    return CameraSettings(**block)


def _build(scenario: Scenario, wire: Wiring | None, meshcat) -> Episode:
    """An Episode, with wiring faults (a port of the agent that fits no testbed port) named."""
    try:
        return Episode(scenario, wire, meshcat)
    except ScenarioError:
        raise
    except ValueError as e:
        raise ScenarioError(" ".join(str(e).split())) from None
    except RuntimeError as e:
        raise ScenarioError(f"could not build the episode: {' '.join(str(e).split())}") from None

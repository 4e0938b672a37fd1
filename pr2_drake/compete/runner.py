"""``pr2-drake compete``: every submission x task x seed, each episode's agent sandboxed.

A submissions folder holds one subfolder per submission, each with a ``submission.yaml``::

    agent: my_solver:Solver            # one agent for every task, or
    agents: {1: walker:Walker, 3: jumper:Jumper}   # one per task (ids or names); others: none
    agent_params: {params: gains.yaml}  # optional keyword arguments of the constructors

The subfolder is bound read-only into the sandbox and put on its agent's import path (its cwd
too); the harness itself reads only its ``submission.yaml`` (a regular file, never through a
link). Results go to ``OUT/episodes.jsonl`` as each episode ends, each row with a MAC
(:mod:`.ledger`), so a killed run resumes where it stopped (finished episodes are not run
again; a row without a valid MAC is), then ``OUT/results.json`` and ``OUT/results.csv`` (one
row per episode). Only the harness writes them, from outside every sandbox.

Scenario switches (``sets``, the CLI's ``--set scene.variation=true`` and ``--set
randomize.enabled=true``) are the same for every submission and episode; each row names the
switches on as ``scenario`` (:meth:`pr2_drake.scenario.Scenario.switches`), and a results
folder holds the episodes of one set of switches (resuming with others is refused). With
domain randomisation (``randomize``, :mod:`pr2_drake.randomize`) each episode's physics is
drawn from its seed, reported in its row as ``physics``, and never sent to the sandbox.

Backends (``jobs`` episodes at once on either): ``local`` runs episodes in this process or a
pool of spawned processes; ``ray`` sends each episode as a Ray task (:func:`run_job`, the same
function: the episode's agent is still sandboxed in a child process of the worker) to a local
Ray started for the run, or to a running cluster (``ray_address``, e.g. ``ray://head:10001`` or
``auto``). On a cluster every node needs pr2-drake (and Ray) installed and the submissions
folder at the same path (a shared file system); results are written here by the driver.
"""

from __future__ import annotations

import csv
import json
import os
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Iterable, TextIO

from pr2_drake.compete import ledger
from pr2_drake.compete.isolation import IsolationUnavailable
from pr2_drake.compete.limits import SandboxLimits
from pr2_drake.compete.sandbox import isolation_note
from pr2_drake.compete.submission import read_submission_yaml

CSV_FIELDS = ("submission", "task", "seed", "scenario", "score", "max_score", "termination",
              "items", "sim_time", "wall_time", "agent_compute_mean_ms", "agent_compute_max_ms",
              "step_time_mean_ms", "ipc_overhead_mean_us", "steps", "sandbox", "message")


@dataclass
class Submission:
    """One submission: its folder and its agent per task (None = every task)."""

    name: str
    folder: Path
    agents: dict[int | None, str] = field(default_factory=dict)
    agent_params: dict[str, Any] = field(default_factory=dict)

    def agent_for(self, task: int) -> str | None:
        return self.agents.get(task, self.agents.get(None))


def load_submissions(root: str | Path) -> list[Submission]:
    """Every subfolder of ``root`` with a ``submission.yaml``, sorted by name.

    Raises:
        ValueError: ``root`` is not a folder, holds no submission, or a submission.yaml is
            malformed (naming the file and the fault).
    """
    from pydrake.common.yaml import yaml_load

    from pr2_drake.tasks import task_id

    root = Path(root)
    if not root.is_dir():
        raise ValueError(f"submissions folder {root} does not exist")
    subs = []
    for folder in sorted(p for p in root.iterdir() if p.is_dir()):
        file = folder / "submission.yaml"
        if not (file.exists() or file.is_symlink()):
            continue
        if folder.is_symlink():
            raise ValueError(f"{folder}: a submission folder may not be a symbolic link")
        text = read_submission_yaml(file)
        try:
            data = yaml_load(data=text) or {}
        except Exception as e:
            raise ValueError(f"{file}: not valid YAML: {' '.join(str(e).split())}") from None
        if not isinstance(data, dict) or not (("agent" in data) ^ ("agents" in data)):
            raise ValueError(f"{file}: give either 'agent: module:Class' or 'agents: "
                             f"{{task: module:Class, ...}}'")
        unknown = set(data) - {"agent", "agents", "agent_params", "name"}
        if unknown:
            raise ValueError(f"{file}: unknown keys {sorted(unknown)}")
        agents: dict[int | None, str] = {}
        if "agent" in data:
            agents[None] = _spec(data["agent"], file)
        else:
            if not isinstance(data["agents"], dict) or not data["agents"]:
                raise ValueError(f"{file}: 'agents' must map task ids to module:Class")
            for task, spec in data["agents"].items():
                try:
                    agents[task_id(task)] = _spec(spec, file)
                except ValueError as e:
                    raise ValueError(f"{file}: {e}") from None
        params = data.get("agent_params") or {}
        if not isinstance(params, dict):
            raise ValueError(f"{file}: agent_params must be a mapping")
        subs.append(Submission(str(data.get("name") or folder.name), folder.absolute(), agents,
                               {str(k): v for k, v in params.items()}))
    if not subs:
        raise ValueError(f"no submission in {root}: each subfolder needs a submission.yaml")
    names = [s.name for s in subs]
    if len(set(names)) != len(names):
        raise ValueError(f"{root}: two submissions have the same name: {names}")
    return subs


def _spec(spec: Any, file: Path) -> str:
    if not isinstance(spec, str) or spec.count(":") != 1 or not all(spec.split(":")):
        raise ValueError(f"{file}: an agent is 'module:Class', got {spec!r}")
    return spec


def parse_tasks(text: str) -> list[int]:
    """``all`` or a comma list of task ids/names -> sorted task ids."""
    from pr2_drake.tasks import list_tasks, task_id

    if text.strip().lower() == "all":
        return [i for i, _ in list_tasks()]
    try:
        return sorted({task_id(t.strip()) for t in text.split(",") if t.strip()})
    except ValueError as e:
        raise ValueError(f"--tasks: {e}") from None


@dataclass
class Job:
    submission: Submission
    task: int
    seed: int
    seconds: float | None
    limits: SandboxLimits
    hide: tuple[str, ...] = ()
    sets: tuple[str, ...] = ()  # scenario overrides of every episode (scene.*, randomize.*)

    @property
    def key(self) -> tuple[str, int, int]:
        return (self.submission.name, self.task, self.seed)


def run_job(job: Job) -> dict[str, Any]:
    """One sandboxed episode -> its results row (the report plus ``submission``)."""
    from pr2_drake.compete.proxy import run_sandboxed_episode
    from pr2_drake.scenario import Scenario, load_scenario

    spec = job.submission.agent_for(job.task)
    scenario = load_scenario(None, overrides=job.sets, defaults=Scenario(
        task=job.task, seed=job.seed, agent=spec, seconds=job.seconds,
        agent_params=dict(job.submission.agent_params)))
    start = time.perf_counter()
    try:
        report = run_sandboxed_episode(scenario, submission=job.submission.folder,
                                       limits=job.limits, hide=tuple(map(Path, job.hide)))
    except IsolationUnavailable:
        raise
    except ValueError as e:  # the scenario could not start (a bad agent_params, ...)
        from pr2_drake.tasks import get_task

        report = {"task": job.task, "seed": job.seed, "agent": spec, "score": 0.0,
                  "max_score": float(get_task(job.task).spec.max_score), "success": False,
                  "termination": "agent_error", "items": [], "sim_time": 0.0,
                  "wall_time": round(time.perf_counter() - start, 3),
                  "message": " ".join(str(e).split())}
        if scenario.switches():
            report["scenario"] = scenario.switches()
    return {"submission": job.submission.name, **report}


BACKENDS = ("local", "ray")


def run_competition(root: str | Path, tasks: Iterable[int], seeds: Iterable[int],
                    out: str | Path, *, jobs: int = 1, seconds: float | None = None,
                    limits: SandboxLimits | None = None,
                    progress: TextIO | None = sys.stderr, backend: str = "local",
                    ray_address: str | None = None,
                    sets: tuple[str, ...] = ()) -> list[dict[str, Any]]:
    """Run (or resume) a competition; returns all rows and writes the results files.

    Args:
        sets: scenario overrides of every episode (``scene.variation=true``, ...; checked by
            :func:`pr2_drake.compete.command.scenario_sets`).
        backend: "local" (processes here) or "ray" (Ray tasks; see the module docstring).
        ray_address: with ``backend="ray"``, a running cluster's address (None: start a local
            Ray with ``jobs`` CPUs for this run).

    Raises:
        ValueError: a bad folder or submission, an unknown backend, or Ray not installed.
    """
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
    if ray_address is not None and backend != "ray":
        raise ValueError("ray_address (--ray-address) needs backend 'ray'")
    if backend == "ray":
        _import_ray()
    limits = limits or SandboxLimits()
    note = isolation_note(limits)  # raises IsolationUnavailable before anything runs
    subs = load_submissions(root)
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {out}: is a file; give a folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise ValueError(f"--out {out}: cannot make the folder ({os.strerror(e.errno)})") \
            from None
    log = out / "episodes.jsonl"
    key = ledger.run_key(out)
    done, rejected = ledger.read_rows(log, key)
    from pr2_drake.scenario import load_scenario

    switched = load_scenario(None, overrides=sets)
    switches = _check_switches(done.values(), switched.switches(), out)
    hide = tuple(str(p.resolve()) for p in (Path(root), out))
    todo = [Job(s, t, seed, seconds, limits, hide, tuple(sets)) for s in subs for t in tasks for seed in seeds
            if s.agent_for(t) is not None]
    todo = [j for j in todo if j.key not in done]
    say = (lambda text: print(text, file=progress, flush=True)) if progress else (lambda _: 0)
    say(note)
    if rejected:
        say(f"{rejected} line(s) of {log} without a valid MAC (cut off, or not written by "
            f"this harness) ignored: those episodes run again")
    say(f"{len(subs)} submissions, tasks {list(tasks)}, seeds {list(seeds)}: "
        f"{len(done)} episodes done before, {len(todo)} to run with {jobs} job(s)"
        + (f", scenario {'+'.join(switches)}" if switches else "")
        + (f" on Ray ({ray_address or 'local'})" if backend == "ray" else ""))
    start = time.perf_counter()
    results = (_ray_results(todo, jobs, ray_address) if backend == "ray"
               else _results(todo, jobs))
    with open(log, "a") as f:
        for i, row in enumerate(results, 1):
            ledger.append(f, row, key)
            done[(row["submission"], int(row["task"]), int(row["seed"]))] = row
            say(f"  {row['submission']:<20} task {row['task']} seed {row['seed']:>3}: score "
                f"{row['score']:>4g}/{row['max_score']:g} {row['termination']:<14} "
                f"t = {row['sim_time']:6.2f} s  ({i}/{len(todo)}, "
                f"{time.perf_counter() - start:.0f} s)")
    rows = sorted(done.values(), key=lambda r: (r["submission"], r["task"], r["seed"]))
    write_results(rows, out, meta={"submissions": [s.name for s in subs], "tasks": list(tasks),
                                   "seeds": list(seeds), "seconds": seconds,
                                   "limits": vars(limits), "isolation": note,
                                   "trust_submissions": limits.trust,
                                   "scenario": switches,
                                   "randomize": asdict(switched.randomize)
                                   if switched.randomize.enabled else None})
    return rows


def _check_switches(rows, switches: list[str], out: Path) -> list[str]:
    """``switches`` (:meth:`Scenario.switches`); ValueError when the episodes already in
    ``out`` were run with others (one results folder, one scenario)."""
    for r in rows:
        if r.get("scenario", []) != switches:
            had = "+".join(r.get("scenario", [])) or "none"
            raise ValueError(f"--out {out}: holds episodes run with scenario switches {had}, "
                             f"this run has {'+'.join(switches) or 'none'}: give another "
                             f"folder")
    return switches


def _results(todo: list[Job], jobs: int):
    if jobs <= 1 or len(todo) <= 1:
        yield from map(run_job, todo)
        return
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor, as_completed

    with ProcessPoolExecutor(max_workers=jobs, mp_context=mp.get_context("spawn")) as pool:
        futures = [pool.submit(run_job, j) for j in todo]
        for fut in as_completed(futures):
            yield fut.result()


def _import_ray():
    try:
        import ray
    except ImportError:
        raise ValueError("--backend ray needs Ray: pip install 'pr2-drake[ray]' (or 'ray')") \
            from None
    return ray


def _ray_results(todo: list[Job], jobs: int, address: str | None):
    """Rows of ``todo`` run as Ray tasks, at most ``jobs`` in flight, as they finish."""
    if not todo:
        return
    ray = _import_ray()
    started = False
    if not ray.is_initialized():
        if address is None:  # a local Ray for this run; the workers see our import path
            ray.init(num_cpus=max(1, jobs), include_dashboard=False, logging_level="ERROR",
                     runtime_env={"env_vars": {"PYTHONPATH": os.pathsep.join(
                         p for p in sys.path if p)}})
        else:
            ray.init(address=address, logging_level="ERROR")
        started = True
    try:
        task = ray.remote(num_cpus=1, max_retries=0)(run_job)
        queue = list(todo)
        pending = []
        while queue or pending:
            while queue and len(pending) < max(1, jobs):
                pending.append(task.remote(queue.pop(0)))
            ready, pending = ray.wait(pending, num_returns=1)
            yield ray.get(ready[0])
    finally:
        if started:
            ray.shutdown()


def csv_row(r: dict[str, Any]) -> dict[str, Any]:
    def ms(key, scale=1e3):
        v = r.get(key)
        return "" if v is None else round(v * scale, 3)

    return {
        "submission": r["submission"], "task": r["task"], "seed": r["seed"],
        "scenario": "+".join(r.get("scenario", [])),
        "score": r["score"], "max_score": r["max_score"], "termination": r["termination"],
        "items": ";".join(f"{e['item']}@{e['time']:.2f}" for e in r.get("items", [])),
        "sim_time": r.get("sim_time"), "wall_time": r.get("wall_time"),
        "agent_compute_mean_ms": ms("agent_compute_mean"),
        "agent_compute_max_ms": ms("agent_compute_max"),
        "step_time_mean_ms": ms("step_time_mean"),
        "ipc_overhead_mean_us": ms("ipc_overhead_mean", 1e6),
        "steps": r.get("steps", 0), "sandbox": r.get("sandbox", ""),
        "message": r.get("message", ""),
    }


def write_results(rows: list[dict[str, Any]], out: Path, meta: dict[str, Any]) -> None:
    """``results.json`` ({competition, episodes}) and ``results.csv`` (one row per episode)."""
    tmp = out / "results.json.tmp"
    tmp.write_text(json.dumps({"competition": meta, "episodes": rows}, indent=1))
    tmp.replace(out / "results.json")
    with open(out / "results.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=CSV_FIELDS)
        w.writeheader()
        for r in rows:
            w.writerow(csv_row(r))

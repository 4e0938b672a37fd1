"""``pr2-drake pr2-launch FOLDER N``: an original PR2 solver folder, run unchanged.

What the original's ``launch_task.sh`` did, on pr2-drake:

1. start task N's controller server (``pr2-drake controller-server --task N``, a process of
   its own, one request per 1 ms step of :class:`pr2.env.Env`) on ``port`` (default 8800,
   the original's; with 0, a free one);
2. run the folder's own ``task_launcher.py N`` from the folder's parent (as the original ran
   ``python examples/task_launcher.py N`` from its root), or, if the folder has none,
   :mod:`pr2.launcher`, which does the same; its ``Task passed`` / ``Task failed`` line is
   the launcher's own;
3. stop the server, and summarise the report that :class:`pr2.env.Env` wrote.

The launcher learns the rest from its environment (:func:`launch_settings`): where to write
the report, the seed and time limit given here, and the server's address: a ``pr2.tcp``
client asking for port 8800 on any host reaches it, so the solvers' own ``("0.0.0.0", 8800)``
works whatever port the server got. The solver runs in the launcher's process, with the
simulation, as on the original platform: run only your own code this way; a competition runs
submissions sandboxed (``pr2-drake compete``).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

#: Environment variables from ``pr2-launch`` to the launcher it runs.
REPORT_ENV = "PR2_DRAKE_REPORT"  # where pr2.env.Env writes the report
SEED_ENV = "PR2_DRAKE_SEED"  # the episode seed, replacing the launcher's
SECONDS_ENV = "PR2_DRAKE_SECONDS"  # the episode's time limit [s]
AGENT_ENV = "PR2_DRAKE_AGENT"  # the solver's name in the report
CONTROLLER_ENV = "PR2_DRAKE_CONTROLLER"  # host:port of the started controller server
#: [s] a launcher interrupted by Ctrl-C has this long to write its report.
INTERRUPT_GRACE = 10.0


@dataclass
class LaunchSettings:
    """What ``pr2-launch`` tells the launcher (None: not run by it, or not given)."""

    report: str | None = None
    seed: int | None = None
    seconds: float | None = None
    agent: str | None = None


def launch_settings() -> LaunchSettings:
    """This process's :class:`LaunchSettings`, from its environment."""
    env = os.environ
    seed, seconds = env.get(SEED_ENV), env.get(SECONDS_ENV)
    return LaunchSettings(report=env.get(REPORT_ENV) or None,
                          seed=int(seed) if seed else None,
                          seconds=float(seconds) if seconds else None,
                          agent=env.get(AGENT_ENV) or None)


@dataclass
class LaunchOptions:
    """A ``pr2-launch`` command line.

    Attributes:
        folder: the original's ``examples/`` layout (``task_N_solver/task_solver.py``, and
            optionally ``task_launcher.py``).
        task: 1..6 (id or name).
        report: the report's path (None: ``taskN_report.json`` in the current folder).
        port: the controller server's port (0: a free one).
        seed: episode seed (None: the launcher's).
        seconds: episode time limit [s] (None: the task's).
    """

    folder: str
    task: int | str
    report: str | None = None
    port: int = 8800
    seed: int | None = None
    seconds: float | None = None


def launch(options: LaunchOptions) -> int:
    """Run the folder's launcher for one task; the launcher's exit status.

    Raises:
        ValueError: a bad option or folder, or a server that did not start (named).
    """
    from pr2_drake.run import check_output_path
    from pr2_drake.tasks import task_id

    task = task_id(options.task)
    folder = Path(options.folder).resolve()
    if not folder.is_dir():
        raise ValueError(f"pr2-launch: {options.folder}: not a folder")
    solver = folder / f"task_{task}_solver" / "task_solver.py"
    if not solver.is_file():
        raise ValueError(f"pr2-launch: {options.folder}: no task_{task}_solver/task_solver.py")
    if options.seconds is not None and not options.seconds > 0:
        raise ValueError(f"--seconds must be > 0, got {options.seconds!r}")
    report = Path(options.report or f"task{task}_report.json").resolve()
    check_output_path(str(report), "--report")
    report.unlink(missing_ok=True)
    launcher = folder / "task_launcher.py"
    command = [sys.executable, str(launcher), str(task)] if launcher.is_file() else \
        [sys.executable, "-m", "pr2.launcher", str(folder), str(task)]
    server, address = start_server(task, options.port)
    try:
        env = {**os.environ, REPORT_ENV: str(report), CONTROLLER_ENV: address,
               AGENT_ENV: str(solver.parent)}
        if options.seed is not None:
            env[SEED_ENV] = str(options.seed)
        if options.seconds is not None:
            env[SECONDS_ENV] = repr(float(options.seconds))
        rc, interrupted = run_launcher(command, folder.parent, env)
    finally:
        server.terminate()
        server.wait(timeout=30)
    rc = summarise(report, rc)
    if interrupted:
        raise KeyboardInterrupt
    return rc


def run_launcher(command: list[str], cwd: Path, env: dict[str, str]) -> tuple[int, bool]:
    """Run the launcher; (its exit status, whether Ctrl-C interrupted it). On Ctrl-C (which
    reaches the launcher too) it is given :data:`INTERRUPT_GRACE` seconds to write its report."""
    child = subprocess.Popen(command, cwd=cwd, env=env)
    try:
        return child.wait(), False
    except KeyboardInterrupt:
        try:
            return child.wait(timeout=INTERRUPT_GRACE), True
        except subprocess.TimeoutExpired:
            child.kill()
            return child.wait(), True


def start_server(task: int, port: int) -> tuple[subprocess.Popen, str]:
    """Task ``task``'s controller server, a process of its own, and its "host:port" once it
    listens.

    Raises:
        ValueError: it exited instead (its own error line is on stderr).
    """
    from pr2.env.env import PHYSICS_DT  # the launcher's Env calls the server once per step

    server = subprocess.Popen([sys.executable, "-m", "pr2_drake.cli", "controller-server",
                               "--task", str(task), "--port", str(port),
                               "--request-period", repr(PHYSICS_DT)],
                              stdout=subprocess.PIPE, text=True)
    line = server.stdout.readline()
    if "listening on " not in line:
        server.kill()
        server.wait()
        raise ValueError(f"pr2-launch: the controller server for task {task} did not start "
                         f"on port {port} (see its message above)")
    address = line.split("listening on ")[1].split()[0]
    print(f"pr2-launch: controller server for task {task} on {address}", flush=True)
    return server, address


def summarise(report_path: Path, rc: int) -> int:
    """Print the report's one-line summary; the exit status (the launcher's, or 1 when it
    left no report)."""
    if not report_path.is_file():
        print(f"pr2-launch: the launcher exited with status {rc} and wrote no report "
              f"(did it build pr2.env.Env?)", file=sys.stderr)
        return rc or 1
    r = json.loads(report_path.read_text())
    note = f" ({r['message']})" if r.get("message") else ""
    print(f"pr2-launch: task {r['task']} ({r['task_name']}), seed {r['seed']}: ended "
          f"{r['termination']} at t = {r['sim_time']:.3f} s, score {r['score']:g} / "
          f"{r['max_score']:g}{note}; report in {report_path}", flush=True)
    return rc

"""The original PR2 platform's Python names, implemented on pr2-drake.

This package exists so that solver folders written for the original platform (its
``examples/`` layout: ``task_launcher.py`` and ``task_N_solver/task_solver.py``) run
unchanged: ``import pr2``, ``pr2.env.Env``, ``pr2.sim``, ``pr2.shutdown()``,
``pr2.solver.TaskSolverBase`` and ``pr2.tcp``. It is not the preferred API for new code: use
:class:`pr2_drake.env.Env` and ``pr2-drake run`` (see the README, "Porting a PR2 solver").

``import pr2`` is light: the simulation (pydrake) loads when an :class:`pr2.env.Env` is built.
"""

from pathlib import Path

from pr2 import sim

__version__ = "0.1.0"
#: This package's folder (the original's ``pr2.ROOT_PATH``).
ROOT_PATH = Path(__file__).parent


def shutdown() -> None:
    """End the run as the original's ``pr2.shutdown()``: the loaded environment's report is
    written (``pr2-drake pr2-launch``), then the process exits with status 0."""
    sim.finish()
    raise SystemExit(0)


__all__ = ["ROOT_PATH", "shutdown", "sim"]

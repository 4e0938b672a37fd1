"""``pr2.solver``: the original platform's solver interface."""

from pr2.solver.task_solver_base import TaskSolverBase

__all__ = ["TaskSolverBase"]

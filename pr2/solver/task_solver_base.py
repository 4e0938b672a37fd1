"""The solver interface of the original platform's launcher."""

from abc import ABC, abstractmethod


class TaskSolverBase(ABC):
    """A task solver: the launcher calls :meth:`next_action` once per physics step (1 ms).

    The observation and action dictionaries are those of :mod:`pr2_drake.observation`
    (``obs["agent"]["joint_state"]``, ``["body_state"]``, ``obs["pick"]``, ``obs["cam"]``...;
    actions ``{"arms": {...}, "legs": {...}, "pick": ..., "release": ...}``).
    """

    @abstractmethod
    def next_action(self, obs: dict) -> dict:
        """The action to apply for the next physics step, given the latest observation."""
        return {}

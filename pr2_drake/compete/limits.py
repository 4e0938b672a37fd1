"""What an agent may use in its sandbox, and how its episode ends when it does not keep to it."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

from pr2_drake.compete.isolation import ISOLATIONS
from pr2_drake.drive import AgentEnded

MIN_MEMORY_MB = 512  # an agent's Python with pydrake imported maps about 400 MiB [MiB]


@dataclass
class SandboxLimits:
    """What an agent may use (YAML: the ``limits`` of a competition).

    Attributes:
        memory_mb: all the memory of the agent's processes [MiB]: a cgroup memory limit
            (heap, shared memory and tmpfs files alike) where the machine lets the harness
            make one, else the address space of its process (``RLIMIT_AS``). Its tmpfs work
            folder holds at most this much too.
        processes: processes and threads at once in the sandbox.
        cpu_seconds: CPU time of the agent's process per episode [s].
        step_seconds: budget for one action [s], charged in the agent process's CPU time:
            a busy machine that starves the agent does not use it up.
        step_wall_seconds: wall-clock cap of one action [s] (catches an agent that sleeps
            or blocks instead of computing); None: ten times ``step_seconds``.
        startup_seconds: wall-clock budget to import and build the agent [s].
        episode_seconds: wall-clock limit of an episode once the agent is built (simulation
            included) [s].
        isolation: "auto" (bubblewrap, else util-linux unshare), "bwrap", "unshare" or
            "none" (see :mod:`pr2_drake.compete.isolation`).
        trust: run the agents unisolated where no isolation works (``--trust-submissions``);
            needed for ``isolation: none``.
    """

    memory_mb: int = 4096
    processes: int = 64
    cpu_seconds: int = 3600
    step_seconds: float = 2.0
    step_wall_seconds: float | None = None
    startup_seconds: float = 120.0
    episode_seconds: float = 3600.0
    isolation: str = "auto"
    trust: bool = False

    def __post_init__(self):
        self.validate()

    def validate(self) -> None:
        """Raise ValueError naming the first bad field (negative, zero, NaN, infinite)."""
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name == "isolation":
                if value not in ISOLATIONS:
                    raise ValueError(f"isolation must be one of {ISOLATIONS}, got {value!r}")
            elif f.name == "trust":
                if not isinstance(value, bool):
                    raise ValueError(f"trust must be true or false, got {value!r}")
            elif not (value is None and f.name == "step_wall_seconds"):
                integer = f.name in ("memory_mb", "processes", "cpu_seconds")
                if (isinstance(value, bool) or not isinstance(value, (int, float))
                        or (integer and value != int(value)) or not math.isfinite(value)
                        or value <= 0):
                    kind = "a positive integer" if integer else "a positive finite number"
                    raise ValueError(f"limits.{f.name} must be {kind}, got {value!r}")
        if self.memory_mb < MIN_MEMORY_MB:
            raise ValueError(f"limits.memory_mb must be at least {MIN_MEMORY_MB} (an agent's "
                             f"Python with pydrake needs about 400 MiB), got {self.memory_mb}")

    @property
    def memory_bytes(self) -> int:
        return int(self.memory_mb) << 20

    @property
    def step_wall_cap(self) -> float:
        """The wall-clock cap of one action [s]."""
        if self.step_wall_seconds is not None:
            return max(float(self.step_wall_seconds), float(self.step_seconds))
        return 10.0 * float(self.step_seconds)


class AgentFault(AgentEnded):
    """The sandbox ended the agent's episode: ``termination`` (one of the agent_* names or
    invalid_action) and a one-line ``message``. An :class:`pr2_drake.drive.AgentEnded`, so
    the driver (:func:`pr2_drake.drive.call_agent`) ends the episode with it."""

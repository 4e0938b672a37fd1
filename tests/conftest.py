"""Shared fixtures: small builders used across the test suite; the number of test processes."""

import math
import os

import numpy as np
import pytest

from pr2_drake.controllers.standing import StandingController
from pr2_drake.episode import Episode, wire_system
from pr2_drake.scenario import Scenario


# Each test process holds its own Drake diagrams (up to about 1.2 GB of memory at the suite's
# peak): ``-n auto`` starts one per core this process may use, at most one per this much
# available memory.
MEMORY_PER_WORKER = 1.5e9  # [bytes]


def pytest_xdist_auto_num_workers(config):
    """Workers for ``-n auto`` (pyproject.toml's addopts): the cores this process may run on
    (its affinity, and a cgroup CPU quota where there is one), capped by available memory."""
    n = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    n = n or 1
    try:
        quota, period = open("/sys/fs/cgroup/cpu.max").read().split()[:2]
        if quota != "max":
            n = min(n, max(1, int(quota) // int(period)))
    except (OSError, ValueError):
        pass
    try:  # MemAvailable: free memory plus the page cache the kernel can drop
        with open("/proc/meminfo") as f:
            kb = next(int(line.split()[1]) for line in f if line.startswith("MemAvailable:"))
        n = min(n, max(1, int(kb * 1024 // MEMORY_PER_WORKER)))
    except (OSError, ValueError, StopIteration):
        pass
    return n


def standing_simulator(scenario: Scenario | None = None):
    """Testbed + StandingController; returns (simulator, testbed, testbed context)."""
    episode = Episode(scenario or Scenario(seconds=math.inf), wire_system(StandingController()))
    episode.simulator.Initialize()
    return episode.simulator, episode.testbed, episode.tb_context


def wire_standing_legs(builder, testbed, controller: StandingController) -> None:
    """Add ``controller`` and let it drive the legs only (the test drives the arms)."""
    builder.AddSystem(controller)
    for n in ("joint_state", "body_state"):
        builder.Connect(testbed.GetOutputPort(n), controller.GetInputPort(n))
    builder.Connect(controller.GetOutputPort("legs_command"), testbed.GetInputPort("legs_command"))


@pytest.fixture
def rng():
    return np.random.default_rng(0)

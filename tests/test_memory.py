"""No diagram leak per episode: a Testbed (plant, scene graph, contexts: ~35 MB) must be freed
by the garbage collector once nothing refers to it (see :mod:`pr2_drake.lifetime`)."""

import gc
import importlib
import inspect
import pkgutil
import weakref

import pytest
from pydrake.systems.framework import System

import pr2_drake
from pr2_drake.camera import CameraSettings
from pr2_drake.testbed import Testbed, TestbedConfig

MAX_GROWTH_MB = 5.0  # allowed resident-memory growth per episode after the warm-up ones
# Python System subclasses known to lack ``__slots__ = ()`` (each keeps its whole diagram
# alive). Remove an entry once its class declares the slots.
PENDING_SLOTS: set[str] = set()


def _rss_mb() -> float:
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    pytest.skip("no /proc/self/status (resident memory unavailable)")


def _live_testbeds() -> int:
    gc.collect()
    return sum(isinstance(o, Testbed) for o in gc.get_objects())


def _run_episode(task, seed: int, seconds: float):
    """One short episode through the public run_episode."""
    from pr2_drake.run import run_episode
    from pr2_drake.scenario import Scenario

    return run_episode(Scenario(task=task, seed=seed, seconds=seconds))


@pytest.mark.parametrize("task", [None, 1, 2, 3, 4, 5, 6])
def test_testbed_is_collected(task):
    tb = Testbed(TestbedConfig(task=task, seed=3, camera=CameraSettings(enabled=False)))
    ref = weakref.ref(tb)
    del tb
    gc.collect()
    assert ref() is None, f"task {task}: the Testbed outlived del + gc.collect()"


def test_system_subclasses_declare_slots():
    """Every Python class in the MRO of a pr2_drake System subclass declares ``__slots__``:
    without it CPython visits the instance dict twice and the collector never frees it."""
    missing = set()
    for info in pkgutil.walk_packages(pr2_drake.__path__, "pr2_drake."):
        try:
            module = importlib.import_module(info.name)
        except Exception:  # an optional dependency (e.g. gymnasium) is missing
            continue
        for _, cls in inspect.getmembers(module, inspect.isclass):
            if not issubclass(cls, System) or not cls.__module__.startswith("pr2_drake."):
                continue
            for k in cls.__mro__:
                if k.__module__.startswith("pr2_drake.") and "__slots__" not in vars(k):
                    missing.add(f"{k.__module__}.{k.__qualname__}")
    assert missing - PENDING_SLOTS == set()


def _episode_growth_mb(collect_each: bool) -> float:
    """Resident-memory growth per short task-1 episode after two warm-up episodes."""
    for seed in range(2):  # warm-up: imports, caches, allocator pools
        _run_episode(1, seed, 0.05)
    gc.collect()
    start = _rss_mb()
    n = 6
    for seed in range(2, 2 + n):
        _run_episode(1, seed, 0.05)
        if collect_each:
            gc.collect()
    return (_rss_mb() - start) / n


def test_episodes_free_their_diagrams():
    """With a collection after each episode nothing of it survives (no leak)."""
    before = _live_testbeds()
    growth = _episode_growth_mb(collect_each=True)
    assert _live_testbeds() == before, "run_episode left its Testbed alive"
    assert growth < MAX_GROWTH_MB, f"resident memory grows {growth:.1f} MB per episode"


def test_episodes_in_a_plain_loop_do_not_grow_memory():
    """The eval loop as users write it: no gc.collect() of their own."""
    growth = _episode_growth_mb(collect_each=False)
    assert growth < MAX_GROWTH_MB, f"resident memory grows {growth:.1f} MB per episode"


def test_testbed_with_camera_is_collected():
    tb = Testbed(TestbedConfig(task=6, seed=3, camera=CameraSettings(enabled=True, width=64,
                                                                       height=48)))
    ref = weakref.ref(tb)
    del tb
    gc.collect()
    assert ref() is None, "a Testbed with the head camera outlived del + gc.collect()"


def test_env_reset_with_new_seed_frees_the_old_testbed():
    from pr2_drake.env import Env

    env = Env(task=None, seed=0)  # tasks 1-5 reset in place (pr2_drake.env.reseed)
    ref = weakref.ref(env.testbed)
    env.reset(seed=1)  # without a task a new seed rebuilds the scene
    gc.collect()
    assert ref() is None, "Env.reset(seed=new) kept the previous Testbed alive"
    ref = weakref.ref(env.testbed)
    del env
    gc.collect()
    assert ref() is None, "a deleted Env kept its Testbed alive"


def test_a_system_agent_without_slots_is_warned_about():
    from pr2_drake.controllers.standing import StandingController
    from pr2_drake.episode import Episode, wire_system
    from pr2_drake.scenario import Scenario

    class Leaky(StandingController):  # no __slots__: its diagram would outlive the episode
        pass

    with pytest.warns(UserWarning, match=r"Leaky does not declare __slots__"):
        Episode(Scenario(seconds=0.1), wire_system(Leaky()))

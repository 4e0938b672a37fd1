"""Keeping Python-defined Drake systems collectable (no diagram leak per episode).

pydrake joins a diagram, its builder and every subsystem in reference cycles that Python's
garbage collector frees. Three things in Python code around a pydrake System make the whole
cycle (diagram, MultibodyPlant, SceneGraph, contexts: ~35 MB an episode) immortal instead:

1. The subclass's instance ``__dict__`` is visited twice by the type's ``tp_traverse`` (once by
   CPython 3.11's subclass traverse, once by pybind11's base traverse), so the collector
   counts the dict as referenced from outside the cycle and keeps everything reachable from
   it. Cure: every such class declares ``__slots__ = ()`` (attributes still work: they live
   in the pybind11 base's own instance dict, which is then visited once).
2. An output port's ``calc`` callback is held by the C++ port as a ``std::function`` that the
   collector cannot see; a bound method (``self._calc``) or a lambda that captures ``self``
   there is a strong, invisible reference back to the system. Cure: :func:`weak_calc`.
   (Event callbacks are fine: pydrake links them visibly.)
3. A multibody element (``plant.GetBodyByName(...)``, a joint, a frame) keeps its plant
   alive through pybind11's keep-alive list, which the collector cannot see either;
   stored on a system of the same diagram (or in a closure the scene keeps) it closes an
   invisible cycle. Cure: store its ``index()`` and look it up with ``plant.get_body``
   (``get_joint``, ``get_frame``) when needed.

Cycles are freed by a full collection only, so a loop of episodes also needs a
``gc.collect()`` between them (at the start of each Episode). Check with
``weakref.ref(testbed)`` + ``del`` + ``gc.collect()`` (tests/test_memory.py).
"""

from __future__ import annotations

import weakref
from typing import Callable


def weak_calc(method) -> Callable:
    """An output-port calc callback that calls the bound ``method`` without keeping its
    system alive. The port belongs to that system, so the system outlives every call."""
    # The plain function and a weak reference to the system (not weakref.WeakMethod, whose
    # __call__ is a Python frame of its own on every evaluation of the port).
    func = method.__func__
    ref = weakref.ref(method.__self__)

    def calc(context, output):
        return func(ref(), context, output)

    calc.__qualname__ = f"weak_calc({method.__qualname__})"
    return calc

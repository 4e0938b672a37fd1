"""glibc's allocator tuned for the physics step, set before a ``pr2-drake`` process starts.

Drake's SAP solver allocates and frees hundreds of mid-size blocks in every physics step (its
contact problem, Hessian and Context). glibc keeps at most 7 freed blocks of each size in a
thread's cache by default, so most of those calls go to the slower shared bins. With 200
(:data:`TUNABLES`) the closed loop runs about 4.5 % fewer instructions (flat walking, callgrind:
docs/benchmarks.md, "Closed-loop speed"); allocation does not change any computed value, so
every episode stays the same bit for bit.

glibc reads ``GLIBC_TUNABLES`` only when a process starts. The ``pr2-drake`` command therefore
starts itself once more with it set (:func:`restart_tuned`), before it imports anything heavy;
the processes it spawns (``eval --jobs``, ``compete``, ``bench``) inherit it. It does nothing
where it cannot help or should not act:

- the C library is not glibc 2.30 or newer (``tcache_count`` above 127 needs 2.30);
- ``GLIBC_TUNABLES`` already names ``glibc.malloc.tcache_count`` (the user's value wins);
- ``PR2_DRAKE_MALLOC_TUNING=0`` is set (the opt-out);
- the process was already restarted (:data:`MARKER`).

Library use (``run_episode`` in a notebook) gets the same figure by starting Python with the
variable set: ``GLIBC_TUNABLES=glibc.malloc.tcache_count=200 jupyter lab``.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Mapping

#: The tunable this module sets (glibc's syntax: ``name=value`` pairs joined by ``:``).
TUNABLES = "glibc.malloc.tcache_count=200"
#: Set in the restarted process, so that it never restarts again.
MARKER = "PR2_DRAKE_MALLOC_TUNED"
#: ``PR2_DRAKE_MALLOC_TUNING=0`` turns the restart off.
OPT_OUT = "PR2_DRAKE_MALLOC_TUNING"
#: Oldest glibc whose thread cache takes a count of 200 (2.30 widened it from 127).
MIN_GLIBC = (2, 30)


def glibc_version() -> tuple[int, int] | None:
    """(major, minor) of the running glibc, or None when the C library is not glibc."""
    try:
        text = os.confstr("CS_GNU_LIBC_VERSION") or ""
    except (AttributeError, ValueError, OSError):
        return None
    name, _, version = text.partition(" ")
    parts = version.split(".")
    if name != "glibc" or len(parts) < 2:
        return None
    try:
        return int(parts[0]), int(parts[1])
    except ValueError:
        return None


def tuned_env(env: Mapping[str, str], version: tuple[int, int] | None = None) -> dict[str, str]:
    """A copy of ``env`` with :data:`TUNABLES` added to ``GLIBC_TUNABLES`` (kept as it is when it
    already sets the thread cache's count, on the opt-out, or where glibc is older than
    :data:`MIN_GLIBC` or absent; ``version`` None: the running one)."""
    out = dict(env)
    version = glibc_version() if version is None else version
    current = out.get("GLIBC_TUNABLES", "")
    if (version is None or version < MIN_GLIBC or out.get(OPT_OUT, "") == "0"
            or "glibc.malloc.tcache_count" in current):
        return out
    out["GLIBC_TUNABLES"] = f"{current}:{TUNABLES}" if current else TUNABLES
    return out


def plain_env(env: Mapping[str, str]) -> dict[str, str]:
    """A copy of ``env`` without what :func:`restart_tuned` added (the environment this process
    had before the restart; ``bench speed`` starts a baseline tree's runs from it)."""
    out = dict(env)
    if out.pop(MARKER, None) is None:
        return out
    kept = [t for t in out.get("GLIBC_TUNABLES", "").split(":") if t and t != TUNABLES]
    if kept:
        out["GLIBC_TUNABLES"] = ":".join(kept)
    else:
        out.pop("GLIBC_TUNABLES", None)
    return out


def restart_tuned() -> None:
    """Replace this process with the same command line under :func:`tuned_env`, once; return
    without doing anything when the environment would not change (see the module docstring)
    or the command line is not known."""
    if os.environ.get(MARKER) or not getattr(sys, "orig_argv", None):
        return
    env = tuned_env(os.environ)
    if env.get("GLIBC_TUNABLES") == os.environ.get("GLIBC_TUNABLES"):
        return
    env[MARKER] = "1"
    sys.stdout.flush()
    sys.stderr.flush()
    os.execve(sys.executable, list(sys.orig_argv), env)

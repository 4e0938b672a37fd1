"""The command lines of the harness: ``pr2-drake compete`` and ``pr2-drake run --isolate``.

``run --isolate`` runs the agent in the same sandbox as ``compete``
(:func:`pr2_drake.compete.proxy.run_sandboxed_episode`): whatever it does (``os._exit``, a
segfault, a hang, raising ``KeyboardInterrupt``, eating memory), the run ends with a report
that names the end and keeps the points earned before; the user's own Ctrl-C writes the report
as ``interrupted``.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

from pr2_drake.compete.isolation import ISOLATIONS
from pr2_drake.flags import positive_float, positive_int


def add_limit_args(p: argparse.ArgumentParser, *, memory_help: str) -> None:
    """The sandbox's limits as flags (``compete``, ``run --isolate``)."""
    p.add_argument("--step-budget", type=positive_float,
                   help="CPU-time budget of one agent step [s] (default 2)")
    p.add_argument("--step-wall", type=positive_float,
                   help="wall-clock cap of one agent step [s] (default 10 x the step budget)")
    p.add_argument("--episode-wall", type=positive_float,
                   help="wall-clock limit of one episode [s] (default 3600)")
    p.add_argument("--memory-mb", type=positive_int, help=memory_help)
    p.add_argument("--isolation", choices=ISOLATIONS,
                   help="auto (default): bubblewrap, else util-linux unshare; none needs "
                        "--trust-submissions")
    p.add_argument("--trust-submissions", action="store_true",
                   help="run agents unisolated where no isolation works (recorded in the "
                        "results)")


def limits_from_args(args) -> Any:
    """The :class:`SandboxLimits` of the flags (ValueError naming a bad one)."""
    from pr2_drake.compete.limits import SandboxLimits

    changes = {"step_seconds": args.step_budget, "step_wall_seconds": args.step_wall,
               "episode_seconds": args.episode_wall, "memory_mb": args.memory_mb,
               "isolation": args.isolation}
    try:
        return SandboxLimits(trust=bool(args.trust_submissions),
                             **{k: v for k, v in changes.items() if v is not None})
    except ValueError as e:
        flag = {"memory_mb": "--memory-mb", "step_seconds": "--step-budget",
                "episode_seconds": "--episode-wall", "step_wall_seconds": "--step-wall"}
        text = str(e)
        for field, name in flag.items():
            text = text.replace(f"limits.{field}", name)
        raise ValueError(text) from None


def add_compete_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("submissions", metavar="SUBMISSIONS_DIR",
                   help="one subfolder per submission, each with a submission.yaml")
    p.add_argument("--tasks", default="all", help="all, or a comma list of ids/names")
    p.add_argument("--seeds", default="0:5", help="A:B (B exclusive) or a comma list")
    p.add_argument("--jobs", type=positive_int, default=1, help="episodes at once (processes)")
    p.add_argument("--out", required=True, metavar="DIR", help="results folder (resumes)")
    p.add_argument("--seconds", type=positive_float, help="cut every episode to this many "
                                                          "simulated seconds (default: the "
                                                          "task's limit)")
    add_limit_args(p, memory_help="all memory of an agent [MiB] (default 4096)")
    p.add_argument("--backend", choices=("local", "ray"), default="local",
                   help="local processes (default) or Ray tasks (pip install 'pr2-drake[ray]')")
    p.add_argument("--ray-address", metavar="ADDR",
                   help="with --backend ray: a running cluster (e.g. ray://head:10001, auto); "
                        "default: a local Ray with --jobs CPUs")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="a scenario switch for every episode: --set scene.variation=true, "
                        "--set randomize.enabled=true (repeatable; scene.* and randomize.* "
                        "keys only; the leaderboard states them)")


SWITCH_KEYS = ("scene.", "randomize.")  # the scenario sections compete's --set may change


def scenario_sets(sets: list[str]) -> tuple[str, ...]:
    """compete's ``--set`` overrides, checked: every key in :data:`SWITCH_KEYS` and the
    scenario they make valid (the submissions and the flags set the rest of each episode).

    Raises:
        ValueError: a key outside them, or a value the scenario refuses (named).
    """
    from pr2_drake.scenario import load_scenario

    for item in sets:
        if not item.split("=", 1)[0].strip().startswith(SWITCH_KEYS):
            keys = " and ".join(f"{k}*" for k in SWITCH_KEYS)
            raise ValueError(f"--set {item}: compete takes {keys} keys only (the submissions "
                             f"and the flags set the rest of each episode)")
    load_scenario(None, overrides=sets).validate()
    return tuple(sets)


def cmd_compete(args, seeds: list[int]) -> int:
    from pr2_drake.compete.runner import parse_tasks, run_competition

    tasks = parse_tasks(args.tasks)
    limits = limits_from_args(args)
    sets = scenario_sets(args.set)
    rows = run_competition(args.submissions, tasks, seeds, args.out, jobs=args.jobs,
                           seconds=args.seconds, limits=limits, backend=args.backend,
                           ray_address=args.ray_address, sets=sets)
    print(f"{len(rows)} episodes in {args.out}/results.json and results.csv; "
          f"`pr2-drake leaderboard {args.out}` ranks them")
    return 0


def add_isolate_args(p: argparse.ArgumentParser) -> None:
    """``run``'s flags for the sandboxed agent."""
    p.add_argument("--isolate", action="store_true",
                   help="run the agent in the competition sandbox: any fault of the agent "
                        "ends the episode with a named end and the report is written")
    add_limit_args(p, memory_help="with --isolate: all memory of the agent [MiB] "
                                  "(default 4096)")


def run_isolated(args, scenario, write_report) -> int:
    """``run --isolate``: the episode with the agent sandboxed; ``write_report(report)`` prints
    and saves it, also when the user stops the run (the report then ends ``interrupted``,
    and the exit status is 130)."""
    from pr2_drake.compete.proxy import Interrupted, run_sandboxed_episode

    for flag in ("meshcat", "record", "record_camera"):
        if getattr(args, flag, None):
            raise ValueError(f"--{flag.replace('_', '-')} does not work with --isolate (the "
                             f"agent is in another process; run without --isolate)")
    limits = limits_from_args(args)
    if not args.quiet:
        from pr2_drake.compete.sandbox import isolation_note

        print(isolation_note(limits), file=sys.stderr, flush=True)
    try:
        report = run_sandboxed_episode(scenario, limits=limits)
    except Interrupted as stop:
        write_report(stop.report)
        return 130
    write_report(report)
    return 0


def check_isolate_flags(args) -> None:
    """Limits given without ``--isolate`` are an error (they bound the sandbox only)."""
    if args.isolate:
        return
    given = [f"--{name.replace('_', '-')}" for name in
             ("step_budget", "step_wall", "episode_wall", "memory_mb", "isolation")
             if getattr(args, name) is not None]
    if args.trust_submissions:
        given.append("--trust-submissions")
    if given:
        raise ValueError(f"{', '.join(given)}: only with --isolate (limits of the sandboxed "
                         f"agent)")

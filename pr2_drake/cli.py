"""The ``pr2-drake`` command line.

    pr2-drake run [SCENARIO.yaml | DIAGRAM.yaml] [--task N] [--seed S] [--agent module:Class]
                  [--seconds T] [--set key=value ...] [--meshcat] [--record replay.html]
                  [--report report.json]
    pr2-drake eval [SCENARIO.yaml] --task N --seeds A:B [--agent module:Class] [--jobs J]
                   [--out results.json]

Every episode is a :class:`pr2_drake.scenario.Scenario`: the YAML file, then the flags, then
the ``--set`` overrides.
    pr2-drake compete SUBMISSIONS_DIR --tasks all|1,3 --seeds A:B [--jobs J] --out DIR
                      [--backend local|ray] [--ray-address ADDR]
    pr2-drake leaderboard DIR
    pr2-drake controller-server [--task N] [--port 8800] [...]   (pr2_drake.porting.cli)
    pr2-drake pr2-launch FOLDER N [--report JSON] [--port P] [--seed S]
    pr2-drake bench {sim,camera,startup,walking,whole-body,perception,...} [...]
    pr2-drake render [YAML] --task N (--times 2.0,5.5 | --every 0.5 | --video out.mp4) [...]
    pr2-drake tasks

Heavy imports (pydrake) happen inside the commands so that ``--help`` answers at once.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from typing import Any

from pr2_drake.compete.command import add_compete_args, add_isolate_args
from pr2_drake.flags import OneLineErrors, positive_int


def _camera_settings(args, current):
    """The scenario's camera after the --camera, --camera-fps and --render-quality flags."""
    if args.camera is None and args.camera_fps is None and args.render_quality is None:
        return current
    from dataclasses import replace

    from pr2_drake.camera import CameraSettings

    cam = replace(current) if current is not None else CameraSettings(enabled=True)
    if args.camera is not None:
        cam.enabled = args.camera != "off"
    if args.camera not in (None, "on", "off"):
        try:
            w, h = (int(v) for v in args.camera.lower().split("x"))
        except ValueError:
            w = h = 0
        if w <= 0 or h <= 0:
            raise ValueError(f"--camera: expected WIDTHxHEIGHT (positive), 'on' or 'off', got "
                             f"{args.camera!r}")
        cam.width, cam.height = w, h
    if args.camera_fps is not None:
        cam.fps = args.camera_fps
    if args.render_quality is not None:
        cam.quality = args.render_quality
    return cam


def _add_episode_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("file", nargs="?", metavar="YAML",
                   help="a scenario YAML (see scenarios/) or a diagram YAML (see diagrams/)")
    p.add_argument("--task", help="task id 1..6 or name (default: flat ground, no referee)")
    p.add_argument("--agent", help="agent as module:Class or path/to/file.py:Class "
                                   "(default: the task's built-in agent)")
    p.add_argument("--seconds", type=float, help="simulated seconds (default: the task's limit)")
    p.add_argument("--time-step", type=float,
                   help="physics step [s] (default: the task's: 0.004, task 6 0.002)")
    p.add_argument("--camera", help="head camera: on, off or WIDTHxHEIGHT (default: the task's)")
    p.add_argument("--camera-fps", type=float, help="camera frames per simulated second")
    p.add_argument("--render-quality", choices=("low", "medium", "high"))
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scenario field, e.g. --set plant.time_step=0.002 "
                        "(repeatable; applied last)")


def scenario_from_args(args, seed: int | None = None):
    """The scenario of a ``run``/``eval`` command line: the YAML file (if a scenario), then
    the flags, then the ``--set`` overrides."""
    from pr2_drake.scenario import Scenario, load_scenario

    scenario, diagram = Scenario(), None
    if args.file:
        if _is_diagram_yaml(args.file):
            diagram = args.file
        else:
            scenario = load_scenario(args.file)
    changes = {}
    for flag, key in (("task", "task"), ("agent", "agent"), ("seconds", "seconds")):
        if getattr(args, flag) is not None:
            changes[key] = getattr(args, flag)
    if diagram is not None:
        changes["diagram"] = diagram
    if seed is not None:
        changes["seed"] = seed
    from dataclasses import replace

    scenario = replace(scenario, **changes)
    if args.time_step is not None:
        scenario.plant = replace(scenario.plant, time_step=args.time_step)
    scenario.camera = _camera_settings(args, scenario.camera)
    return load_scenario(None, overrides=args.set, defaults=scenario)


def _is_diagram_yaml(path: str) -> bool:
    """Whether a YAML file is a diagram (it has ``blocks``) rather than a scenario."""
    from pydrake.common.yaml import yaml_load_file

    from pr2_drake.paths import resolve_user_path

    file = resolve_user_path(path, "scenario or diagram YAML")
    try:
        raw = yaml_load_file(str(file))
    except Exception as e:
        raise ValueError(f"{path}: not valid YAML: {' '.join(str(e).split())}") from None
    return isinstance(raw, dict) and ("blocks" in raw or "connect" in raw)


def _print_report(report: dict[str, Any], out=sys.stdout) -> None:
    task = report["task"]
    title = f"task {task} ({report['task_name']})" if task is not None else "flat ground"
    print(f"\n{title}, seed {report['seed']}, agent {report['agent']}", file=out)
    if task is not None:
        from pr2_drake.tasks import get_task

        spec = get_task(task).spec
        earned = {e["item"]: e for e in report["items"]}
        print(f"  {'rubric item':<34}{'points':>8}{'earned':>8}{'at [s]':>9}", file=out)
        for r in spec.rubric:
            e = earned.get(r.item)
            got = f"{e['points']:g}" if e else "-"
            at = f"{e['time']:.2f}" if e else ""
            print(f"  {r.item:<34}{r.points:>8g}{got:>8}{at:>9}", file=out)
        extra = [e for e in report["items"] if e["item"] not in {r.item for r in spec.rubric}]
        for e in extra:
            print(f"  {e['item']:<34}{'':>8}{e['points']:>8g}{e['time']:>9.2f}", file=out)
    print(f"  score {report['score']:g} / {report['max_score']:g}   success {report['success']}"
          f"   ended: {report['termination']} at t = {report['sim_time']:.2f} s", file=out)
    rtf = report.get("real_time_factor")
    print(f"  wall time {report['wall_time']:.1f} s, real-time factor "
          f"{rtf if rtf is not None else 'n/a'}", file=out)
    if report.get("message"):
        print(f"  note: {report['message']}", file=out)


def cmd_run(args) -> int:
    from pydrake.geometry import Meshcat

    from pr2_drake.compete.command import check_isolate_flags, run_isolated
    from pr2_drake.run import check_output_path, run_episode

    check_isolate_flags(args)
    scenario = scenario_from_args(args, seed=args.seed)
    check_output_path(args.report, "--report")
    check_output_path(args.record, "--record")
    if args.isolate:
        return run_isolated(args, scenario, lambda r: _write_report(r, args.report))
    meshcat = None
    if args.meshcat:
        meshcat = Meshcat()
        print(f"Meshcat: {meshcat.web_url()}", flush=True)
    report = run_episode(scenario, meshcat=meshcat, record=args.record,
                         record_camera=args.record_camera, camera_depth=args.camera_depth,
                         progress=None if args.quiet else sys.stderr)
    _write_report(report, args.report)
    if args.record:
        print(f"  replay written to {args.record}")
    if args.record_camera:
        print(f"  head-camera video written to {args.record_camera}")
    if args.meshcat and not args.no_wait:
        try:
            input("Simulation done; press Enter to close Meshcat.")
        except EOFError:
            pass
    return 0


def _write_report(report: dict[str, Any], path: str | None) -> None:
    _print_report(report)
    if path:
        with open(path, "w") as f:
            json.dump(report, f, indent=2)
        print(f"  report written to {path}")


def _parse_seeds(text: str) -> list[int]:
    try:
        if ":" in text:
            a, b = text.split(":")
            seeds = list(range(int(a), int(b)))
        else:
            seeds = [int(s) for s in text.split(",")]
    except ValueError:
        raise ValueError(f"--seeds: expected A:B (B exclusive) or a comma list, got "
                         f"{text!r}") from None
    if not seeds:
        raise ValueError(f"--seeds {text!r} selects no seed")
    if min(seeds) < 0:
        raise ValueError(f"--seeds {text!r}: seeds are non-negative")
    return seeds


def _eval_one(scenario):
    from pr2_drake.run import run_episode

    return run_episode(scenario)


def summarize(reports: list[dict[str, Any]], rubric: list[str] = ()) -> dict[str, Any]:
    """Success rate, mean score, per-item rates, completion times and the failures by class
    (:mod:`pr2_drake.failures`; ``rubric``: the task's item names in order) over episodes."""
    import numpy as np

    from pr2_drake.failures import failures_by_class

    n = len(reports)
    items: dict[str, int] = {}
    terminations: dict[str, int] = {}
    for r in reports:
        for e in r["items"]:
            items[e["item"]] = items.get(e["item"], 0) + 1
        terminations[r["termination"]] = terminations.get(r["termination"], 0) + 1
    done_times = [r["sim_time"] for r in reports if r["success"]]
    return {
        "episodes": n,
        "success_rate": sum(r["success"] for r in reports) / n,
        "full_marks_rate": sum(r["score"] >= r["max_score"] for r in reports) / n,
        "mean_score": float(np.mean([r["score"] for r in reports])),
        "max_score": reports[0]["max_score"],
        "item_rates": {k: v / n for k, v in sorted(items.items())},
        "terminations": terminations,
        "completion_time_mean": float(np.mean(done_times)) if done_times else None,
        "completion_time_median": float(np.median(done_times)) if done_times else None,
        "mean_real_time_factor": float(np.mean([r["real_time_factor"] or 0 for r in reports])),
        "scenario": reports[0].get("scenario", []),  # the switches on (Scenario.switches)
        "failures": failures_by_class(reports, list(rubric)),
    }


def _collect(results, n: int) -> list[dict[str, Any]]:
    """The reports of ``results`` as they come, with a line each on stderr."""
    reports: list[dict[str, Any]] = []
    start = time.perf_counter()
    for r in results:
        reports.append(r)
        print(f"  seed {r['seed']:>4}: score {r['score']:>5g}/{r['max_score']:g} "
              f"{r['termination']:<12} t = {r['sim_time']:6.2f} s  "
              f"({len(reports)}/{n}, {time.perf_counter() - start:.0f} s)",
              file=sys.stderr, flush=True)
    return reports


def cmd_eval(args) -> int:
    from dataclasses import replace

    from pr2_drake.agents import load_agent_class
    from pr2_drake.run import agent_spec, check_output_path
    from pr2_drake.tasks import get_task, task_id

    seeds = _parse_seeds(args.seeds)
    base = scenario_from_args(args)
    if base.task is None:
        raise ValueError("eval: --task is required (or a scenario file with a task)")
    check_output_path(args.out, "--out")
    if not base.diagram:
        load_agent_class(agent_spec(base))  # a bad spec fails here, once, not in every worker
    task = task_id(base.task)
    jobs = args.jobs
    work = [replace(base, seed=s) for s in seeds]
    switches = "+".join(base.switches()) or "none"
    print(f"evaluating task {task} over {len(seeds)} seeds with {jobs} job(s), scenario "
          f"switches: {switches}", file=sys.stderr)
    if jobs == 1:
        reports = _collect(map(_eval_one, work), len(work))
    else:
        import multiprocessing as mp
        from concurrent.futures import ProcessPoolExecutor

        # Shut down before returning: a pool left to the interpreter's exit closes its
        # wake-up pipe under its own thread ("Exception ignored ... Bad file descriptor").
        with ProcessPoolExecutor(max_workers=jobs, mp_context=mp.get_context("spawn")) as pool:
            reports = _collect(pool.map(_eval_one, work), len(work))
    summary = summarize(reports, [r.item for r in get_task(task).spec.rubric])
    print(f"\ntask {task}: {summary['episodes']} episodes (scenario switches: {switches})")
    print(f"  success rate      {100 * summary['success_rate']:.1f} %")
    print(f"  full marks        {100 * summary['full_marks_rate']:.1f} %")
    print(f"  mean score        {summary['mean_score']:.2f} / {summary['max_score']:g}")
    for item, rate in summary["item_rates"].items():
        print(f"  item {item:<28} {100 * rate:5.1f} %")
    for reason, count in summary["terminations"].items():
        print(f"  ended {reason:<27} {count}")
    if summary["completion_time_mean"] is not None:
        print(f"  completion time   mean {summary['completion_time_mean']:.1f} s, "
              f"median {summary['completion_time_median']:.1f} s")
    _print_failures(summary["failures"])
    if args.out:
        with open(args.out, "w") as f:
            json.dump({"summary": summary, "episodes": reports}, f, indent=2)
        print(f"  results written to {args.out}")
    return 0


def _print_failures(failures: dict[str, list[dict]]) -> None:
    """The failure classes, each with its seeds and the first item each missed."""
    if not failures:
        return
    print("  failures (seed: first item missed)")
    for label, episodes in failures.items():
        seeds = ", ".join(f"{e['seed']}: {e['missed'] or '-'}" for e in episodes)
        print(f"    {label:<36} {len(episodes):>3}  ({seeds})")


def cmd_compete(args) -> int:
    from pr2_drake.compete.command import cmd_compete as compete

    return compete(args, _parse_seeds(args.seeds))


def cmd_leaderboard(args) -> int:
    from pr2_drake.compete.leaderboard import write_leaderboard

    print(write_leaderboard(args.dir, plots=not args.no_plots))
    return 0


def cmd_bench(args) -> int:
    from pr2_drake.bench import run_benchmark

    return run_benchmark(args.what, args.rest)


def cmd_tasks(args) -> int:
    from pr2_drake.tasks import get_task, list_tasks

    for i, name in list_tasks():
        try:
            spec = get_task(i).spec
            print(f"  {i}  {name:<16} {spec.title:<44} {spec.max_score:>4g} points, "
                  f"limit {spec.time_limit:g} s")
        except Exception as e:  # a task module not available
            print(f"  {i}  {name:<16} (unavailable: {e})")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineErrors(prog="pr2-drake", description="Drake-native PR2 humanoid testbed")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("run", help="run one scored episode (a scenario or diagram YAML, or flags)")
    _add_episode_args(p)
    p.add_argument("--seed", type=int, help="episode seed (default 0)")
    p.add_argument("--meshcat", action="store_true", help="start Meshcat and print its URL")
    p.add_argument("--no-wait", action="store_true", help="with --meshcat: exit when done")
    p.add_argument("--record", metavar="HTML", help="write a self-contained replay")
    p.add_argument("--record-camera", metavar="MP4",
                   help="write the head camera's colour stream (mp4v) at the camera's rate")
    p.add_argument("--camera-depth", action="store_true",
                   help="with --record-camera: depth as a colour map beside the colour")
    p.add_argument("--report", metavar="JSON", help="write the report as JSON")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    add_isolate_args(p)
    p.set_defaults(func=cmd_run)

    p = sub.add_parser("eval", help="run many seeded episodes and summarise")
    _add_episode_args(p)
    p.add_argument("--seeds", default="0:10", help="A:B (B exclusive) or a comma list")
    p.add_argument("--jobs", type=positive_int, default=1, help="parallel processes")
    p.add_argument("--out", metavar="JSON", help="write all reports and the summary")
    p.set_defaults(func=cmd_eval)

    p = sub.add_parser("compete", help="run every submission of a folder, sandboxed, over "
                                       "tasks and seeds (resumable)")
    add_compete_args(p)
    p.set_defaults(func=cmd_compete)

    p = sub.add_parser("leaderboard", help="rank a compete results folder; tables and plots")
    p.add_argument("dir", metavar="DIR", help="the --out folder of pr2-drake compete")
    p.add_argument("--no-plots", action="store_true", help="tables only")
    p.set_defaults(func=cmd_leaderboard)

    from pr2_drake.porting.cli import add_controller_server_parser, add_pr2_launch_parser

    add_controller_server_parser(sub)
    add_pr2_launch_parser(sub)

    from pr2_drake.bench import BENCHMARKS

    p = sub.add_parser("bench", help="benchmarks: " + ", ".join(BENCHMARKS))
    p.add_argument("what", choices=(*BENCHMARKS, "all"))
    p.add_argument("rest", nargs=argparse.REMAINDER, help="options of that benchmark")
    p.set_defaults(func=cmd_bench)

    from pr2_drake.render.command import add_parser as add_render_parser

    add_render_parser(sub, _add_episode_args, scenario_from_args)

    p = sub.add_parser("tasks", help="list the tasks")
    p.set_defaults(func=cmd_tasks)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except (ValueError, FileNotFoundError) as e:
        print(f"pr2-drake: error: {' '.join(str(e).split())}", file=sys.stderr)
        return 2
    except SystemExit as e:  # a command refusing its input before running: one line, 2
        if not isinstance(e.code, str):
            raise
        print(f"pr2-drake: error: {' '.join(e.code.split())}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


def console_main() -> int:
    """The ``pr2-drake`` program: :func:`main` in a process whose allocator is tuned for the
    physics step (:func:`pr2_drake.malloc_tuning.restart_tuned` starts it once more)."""
    import os

    from pr2_drake.malloc_tuning import restart_tuned

    restart_tuned()
    try:
        return main()
    except BrokenPipeError:  # the reader left early (``pr2-drake tasks | head -1``): no traceback
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # nor at the final flush
        return 141  # 128 + SIGPIPE, as a shell reports a program that a closed pipe stopped


if __name__ == "__main__":
    sys.exit(console_main())

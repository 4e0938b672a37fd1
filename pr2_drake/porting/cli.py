"""The porting subcommands of ``pr2-drake``: ``controller-server`` and ``pr2-launch``.

    pr2-drake controller-server [--task N] [--port 8800] [--host 127.0.0.1] [--overrides YAML]
                                [--terrain flat|rough|slope|stairs] [--max-clients 16]
                                [--idle-timeout 60] ...
    pr2-drake pr2-launch FOLDER N [--report JSON] [--port 8800] [--seed S]

Each ``add_*`` function adds its parser (to ``pr2_drake.cli``'s subparsers); the parser's
``func`` runs it. Imports of pydrake happen inside the runners.
"""

from __future__ import annotations

import argparse

from pr2_drake.flags import positive_float, positive_int


def add_controller_server_parser(sub) -> None:
    """``pr2-drake controller-server``."""
    p = sub.add_parser("controller-server",
                       help="the original PR2 walking controller's TCP protocol, answered by "
                            "the built-in walking/jump controller")
    p.add_argument("--task", help="set up as the original's taskN_controller (terrain, gains, "
                                  "jumps) for task 1..6; the flags below override it")
    p.add_argument("--port", type=int, default=8800, help="TCP port (0: a free one; default 8800)")
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1)")
    p.add_argument("--walking", metavar="YAML", help="walking parameters (default: the "
                                                     "built-in walking.yaml)")
    p.add_argument("--overrides", metavar="YAML", help="partial walking YAML on top (e.g. the "
                                                       "built-in walking_rough.yaml)")
    p.add_argument("--terrain", choices=("flat", "rough", "slope", "stairs"),
                   help="footholds: flat (default), rough (unknown stones, task 1), slope or "
                        "stairs (from --task's priors: 4, 5)")
    p.add_argument("--jumping", metavar="YAML", help="jump parameters (default: the built-in "
                                                     "jumping.yaml)")
    p.add_argument("--jump-apex", type=positive_float, help="CoM rise of a change_state 2 jump [m] "
                                                   "(default 0.18)")
    p.add_argument("--request-period", type=positive_float,
                   help="simulated seconds per request without a 'time' field (default: "
                        "one physics step, 0.004, or --task's)")
    p.add_argument("--max-clients", type=positive_int, help="connections served at once; one more gets "
                                                   "an error reply (default 16)")
    p.add_argument("--idle-timeout", type=positive_float, help="close a connection silent this many "
                                                      "seconds (default 60)")
    p.set_defaults(func=run_controller_server)


def server_config(args: argparse.Namespace):
    """The :class:`ControllerServerConfig` of a ``controller-server`` command line."""
    from dataclasses import replace

    from pr2_drake.porting.session import ControllerServerConfig

    config = (ControllerServerConfig.for_task(args.task) if args.task is not None
              else ControllerServerConfig())
    changes = {field: getattr(args, flag) for flag, field in (
        ("walking", "walking"), ("overrides", "overrides"), ("terrain", "terrain"),
        ("jumping", "jumping"), ("jump_apex", "jump_apex"),
        ("request_period", "request_period")) if getattr(args, flag) is not None}
    config = replace(config, **changes)
    config.validate()
    return config


def server_limits(args: argparse.Namespace):
    """The :class:`ServerLimits` of a ``controller-server`` command line."""
    from dataclasses import replace

    from pr2_drake.porting.controller_server import ServerLimits

    limits = ServerLimits()
    for field, flag in (("max_clients", "--max-clients"), ("idle_timeout", "--idle-timeout")):
        if getattr(args, field) is not None:
            limits = replace(limits, **{field: getattr(args, field)})
            try:
                limits.validate()
            except ValueError as e:
                raise ValueError(f"{flag}: {e}") from None
    return limits


def run_controller_server(args: argparse.Namespace) -> int:
    from pr2_drake.porting.controller_server import ControllerServer

    limits = server_limits(args)
    server = ControllerServer(args.host, args.port, server_config(args), limits=limits)
    host, port = server.address
    task = f" for task {server.config.task}" if server.config.task is not None else ""
    print(f"controller-server: listening on {host}:{port}{task} (Ctrl-C stops)", flush=True)
    try:
        server.serve_forever()
    finally:
        server.close()
    return 0


def add_pr2_launch_parser(sub) -> None:
    """``pr2-drake pr2-launch``."""
    p = sub.add_parser("pr2-launch", help="run an original PR2 solver folder unchanged: the "
                                          "task's controller server, then its task_launcher.py")
    p.add_argument("folder", metavar="FOLDER",
                   help="the original's examples/ layout: task_launcher.py (optional) and "
                        "task_N_solver/task_solver.py")
    p.add_argument("task", metavar="N", help="task 1..6")
    p.add_argument("--report", metavar="JSON",
                   help="write the episode's report here (default taskN_report.json)")
    p.add_argument("--port", type=int, default=8800,
                   help="the controller server's port (0: a free one; the solver's own 8800 "
                        "is sent there); default 8800")
    p.add_argument("--seed", type=int, help="episode seed (default: the launcher's)")
    p.add_argument("--seconds", type=float, help="end the episode after this many simulated "
                                                 "seconds (default: the task's limit)")
    p.set_defaults(func=run_pr2_launch)


def run_pr2_launch(args: argparse.Namespace) -> int:
    from pr2_drake.porting.launch import LaunchOptions, launch

    return launch(LaunchOptions(folder=args.folder, task=args.task, report=args.report,
                                port=args.port, seed=args.seed, seconds=args.seconds))

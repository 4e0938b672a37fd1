"""``pr2-drake render``: re-simulate an episode and render it, path traced or raster.

    pr2-drake render [YAML] --task N [--seed S] [--agent module:Class] [--set key=value ...]
                     (--times 2.0,5.5 | --every 0.5 | --video out.mp4 [--fps 24])
                     [--view follow|head] [--size 640x480] [--samples 64] [--no-denoise]
                     [--engine cycles|vtk] [--quality high] [--f-stop F] [--out DIR]

The episode is the one ``pr2-drake run`` runs with the same scenario flags
(:mod:`pr2_drake.render.resim`). ``--view head --every 0.5 --out dataset/`` writes a dataset:
colour, the simulator's depth and per-object masks (:class:`FrameWriter`).
"""

from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path

from pr2_drake.render import INSTALL_HINT
from pr2_drake.render.view import ENGINES, VIEWS

MAX_FRAMES = 100000


def add_parser(sub, add_episode_args: callable, scenario_from_args: callable) -> None:
    """Add the ``render`` subcommand to ``sub`` (the CLI's subparsers), with the episode flags
    of ``run`` (``add_episode_args``) and their reader (``scenario_from_args``)."""
    p = sub.add_parser("render", help="re-simulate an episode and render stills, a video or "
                                      "a dataset (path traced: pip install "
                                      "'pr2-drake[photoreal]')")
    add_episode_args(p)
    p.add_argument("--seed", type=int, help="episode seed (default 0)")
    when = p.add_mutually_exclusive_group(required=True)
    when.add_argument("--times", help="stills at these simulated times [s], e.g. 2.0,5.5")
    when.add_argument("--every", type=float, metavar="DT",
                      help="a still every DT simulated seconds, from 0 to the episode's end")
    when.add_argument("--video", metavar="MP4", help="write a video (mp4v) of the episode")
    p.add_argument("--fps", type=float, default=24.0, help="video frames per simulated second "
                                                           "(default 24)")
    p.add_argument("--view", choices=VIEWS, default="follow",
                   help="follow: a third-person camera framing the robot (default); head: the "
                        "head camera")
    p.add_argument("--size", default="640x480", help="WIDTHxHEIGHT (default 640x480)")
    p.add_argument("--samples", type=int, default=64, help="path-traced samples per pixel "
                                                           "(default 64)")
    p.add_argument("--no-denoise", action="store_true", help="turn OpenImageDenoise off")
    p.add_argument("--engine", choices=ENGINES, default="cycles",
                   help="cycles: CPU path tracer (default); vtk: Drake's raster, same framing")
    p.add_argument("--quality", choices=("low", "medium", "high"), default="high",
                   help="raster preset of --engine vtk (default high)")
    p.add_argument("--f-stop", type=float, help="depth of field with this aperture (default: "
                                                "none)")
    p.add_argument("--out", metavar="DIR", help="write PNG files (and frames.json) here; with "
                                                "--view head also depth and object masks")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(func=lambda args: run(args, scenario_from_args))


def path_tracer_available() -> bool:
    """Whether ``bpy`` can be imported (found, not imported: it loads a whole Blender)."""
    return importlib.util.find_spec("bpy") is not None


def _request(args):
    from pr2_drake.render.view import RenderRequest

    try:
        w, h = (int(v) for v in args.size.lower().split("x"))
    except ValueError:
        raise ValueError(f"--size: expected WIDTHxHEIGHT, got {args.size!r}") from None
    request = RenderRequest(view=args.view, width=w, height=h, engine=args.engine,
                            samples=args.samples, denoise=not args.no_denoise,
                            quality=args.quality, f_stop=args.f_stop)
    try:
        request.validate()
    except ValueError as e:
        raise ValueError(f"render: {e}") from None
    return request


def _times(args, limit: float) -> list[float]:
    """The simulated times to render [s]."""
    if args.times is not None:
        try:
            times = [float(t) for t in args.times.split(",") if t.strip()]
        except ValueError:
            raise ValueError(f"--times: expected comma-separated seconds, got {args.times!r}") \
                from None
        bad = [t for t in times if not (math.isfinite(t) and 0 <= t <= limit)]
        if not times or bad:
            raise ValueError(f"--times must lie in [0, {limit:g}] s (the episode's limit), "
                             f"got {args.times!r}")
        return times
    step = args.every if args.every is not None else 1.0 / args.fps
    name = "--every" if args.every is not None else "--fps"
    if not (math.isfinite(step) and step > 0):
        raise ValueError(f"{name} must be a positive number")
    count = int(math.floor(limit / step + 1e-9)) + 1
    if count > MAX_FRAMES:
        raise ValueError(f"{name}: {count} frames over {limit:g} s; at most {MAX_FRAMES}")
    return [round(k * step, 9) for k in range(count)]


def run(args, scenario_from_args) -> int:
    """Run ``pr2-drake render``; returns the exit status."""
    from pr2_drake.render.resim import episode_limit

    if args.engine == "cycles" and not path_tracer_available():
        raise ValueError(INSTALL_HINT)
    request = _request(args)
    if args.out is None and args.video is None:
        raise ValueError("render: give --out DIR (PNG files) or --video FILE")
    if args.video is not None and not (math.isfinite(args.fps) and 0 < args.fps <= 1000):
        raise ValueError(f"--fps must be in (0, 1000], got {args.fps}")
    scenario = scenario_from_args(args, seed=args.seed)
    times = _times(args, episode_limit(scenario))
    from pr2_drake.run import check_output_path

    check_output_path(args.video, "--video")
    if args.out is not None and Path(args.out).is_file():
        raise ValueError(f"--out {args.out}: is a file; give a folder")
    progress = None if args.quiet else sys.stderr
    from dataclasses import replace

    from pr2_drake.render.resim import resimulate

    if args.times is not None:  # stills: the episode up to the last one is enough
        scenario = replace(scenario, seconds=max(max(times), 1e-3))
    report, states = resimulate(scenario, times, progress)
    missed = len(times) - len(states)
    print(f"episode: task {report['task']}, seed {report['seed']}, {report['termination']} at "
          f"t = {report['sim_time']:.2f} s, score {report['score']:g}/{report['max_score']:g}"
          + (f"; {missed} time(s) after its end not rendered" if missed else ""), flush=True)
    return _render(scenario, states, request, args, report, progress)


def _render(scenario, states, request, args, report, progress) -> int:
    from pr2_drake.render.frames import FOLLOW_SMOOTHING, FrameWriter, render_frames
    from pr2_drake.render.rig import RenderRig

    rig = RenderRig(scenario.testbed_config(),
                    quality=request.quality if request.engine == "vtk" else "high")
    dataset = args.out is not None and request.view == "head"
    sinks, writer, video = [], None, None
    if args.out is not None:
        writer = FrameWriter(Path(args.out), dataset, rig.object_labels() if dataset else {})
        sinks.append(writer.write)
    if args.video is not None:
        video = VideoSink(args.video, args.fps, request.width, request.height)
        sinks.append(video.write)
    try:
        view = render_frames(rig, states, request, sinks, dataset=dataset,
                             smoothing=0.0 if args.video is None else FOLLOW_SMOOTHING,
                             progress=progress)
    finally:
        if video is not None:
            video.close()
    if writer is not None:
        writer.close(view, report)
        print(f"  {len(states)} frame(s) written to {args.out}")
    if video is not None:
        print(f"  video written to {args.video} ({video.frames} frames at {args.fps:g} fps)")
    return 0


class VideoSink:
    """Writes colour frames to an mp4 file (mp4v, as the head-camera recorder)."""

    def __init__(self, path: str, fps: float, width: int, height: int):
        import cv2

        from pr2_drake.video import FOURCC

        self.frames = 0
        self._writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*FOURCC), float(fps),
                                       (width, height))
        if not self._writer.isOpened():
            raise ValueError(f"--video: cannot open a video writer for {path!r}")

    def write(self, state, view, color, raster) -> None:
        import cv2

        self._writer.write(cv2.cvtColor(color, cv2.COLOR_RGB2BGR))
        self.frames += 1

    def close(self) -> None:
        self._writer.release()

"""``pr2-drake bench camera``: colour + depth renders per wall-clock second of the head camera.

    pr2-drake bench camera [--resolutions paper|640x480,...] [--task 6,1] [--quality low,high]

Per task, render preset and resolution, beside the paper's figures (``paper``: its eight
resolutions). No physics: each frame is what the RgbdSensor renders per sample.
"""

from __future__ import annotations

import argparse
import math
import time

from pr2_drake.bench.sim import standing_episode

# The paper's head-camera rates (i9-13900KF + RTX 4090, Isaac Sim, physics step 1 ms) [frames/s].
PAPER_CAMERA_FPS = {"640x480": 17.363, "1024x768": 17.683, "1280x720": 17.361,
                    "1600x1200": 16.263, "1920x1080": 14.918, "2560x1440": 15.033,
                    "3440x1440": 13.973, "3840x2160": 13.697}


def _resolutions(text: str) -> list[tuple[int, int]]:
    """``paper`` (the paper's eight) or a comma list of WIDTHxHEIGHT."""
    names = list(PAPER_CAMERA_FPS) if text == "paper" else text.split(",")
    try:
        return [tuple(int(v) for v in r.lower().split("x")) for r in names]
    except ValueError:
        raise SystemExit(f"--resolutions: expected 'paper' or WIDTHxHEIGHT,..., got {text!r}")


def _render_rate(task, quality: str, sizes, frames: int, budget: float):
    """(colour + depth renders per wall-clock second, CPU seconds per render) of the head
    camera, one pair per size (CPU time: of every thread of this process, llvmpipe's too).

    The testbed of ``task`` is built once per quality (robot at its start); each frame is one
    ``RenderColorImage`` plus one ``RenderDepthImage`` of the head camera's renderer at the
    head camera's pose: what the RgbdSensor does per sample, without the physics. At most
    ``frames`` frames or ``budget`` [s] per size (after one warm-up frame)."""
    from pydrake.geometry import (ClippingRange, ColorRenderCamera, DepthRange,
                                  DepthRenderCamera, RenderCameraCore)
    from pydrake.math import RigidTransform
    from pydrake.systems.sensors import CameraInfo

    from pr2_drake.camera import RENDERER_NAME, CameraSettings

    cam = CameraSettings(enabled=True, width=64, height=48, quality=quality)
    episode = standing_episode(task, camera=cam)
    simulator, testbed = episode.simulator, episode.testbed
    sensor = testbed.GetSubsystemByName("head_camera")
    camera_sg = testbed.camera_scene_graph
    query = camera_sg.get_query_output_port().Eval(
        camera_sg.GetMyContextFromRoot(simulator.get_context()))
    parent, X_PB = sensor.default_parent_frame_id(), sensor.default_X_PB()
    rates = []
    for w, h in sizes:
        core = RenderCameraCore(RENDERER_NAME, CameraInfo(w, h, math.radians(cam.fov_y_deg)),
                                ClippingRange(0.5 * cam.z_near, 2 * cam.z_far),
                                RigidTransform())
        color = ColorRenderCamera(core, False)
        depth = DepthRenderCamera(core, DepthRange(cam.z_near, cam.z_far))

        def render():
            query.RenderColorImage(color, parent, X_PB)
            query.RenderDepthImage(depth, parent, X_PB)

        render()  # warm-up: buffers of this size, shadow map
        n, start, cpu = 0, time.perf_counter(), time.process_time()
        while n < frames and (n < 2 or time.perf_counter() - start < budget):
            render()
            n += 1
        rates.append((n / (time.perf_counter() - start), (time.process_time() - cpu) / n))
    return rates


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(
        prog="pr2-drake bench camera",
        description="head-camera colour + depth renders per wall-clock second (no physics)")
    p.add_argument("--resolutions", default="640x480,1280x720",
                   help="'paper' (its eight, 640x480 to 3840x2160) or WIDTHxHEIGHT,...")
    p.add_argument("--task", default=None, help="task id, or a comma list (e.g. 6,1)")
    p.add_argument("--quality", default="low",
                   help="render preset, or a comma list: low,medium,high")
    p.add_argument("--frames", type=int, default=30, help="frames per case at most")
    p.add_argument("--budget", type=float, default=10.0,
                   help="[s] of rendering per case at most (at least 2 frames)")
    a = p.parse_args(argv)
    sizes = _resolutions(a.resolutions)
    tasks = a.task.split(",") if a.task else [None]
    qualities = a.quality.split(",")
    for q in qualities:
        if q not in ("low", "medium", "high"):
            raise SystemExit(f"--quality: expected low, medium or high, got {q!r}")
    print("head camera, colour + depth renders per second (RenderEngineVtk, no physics); "
          "CPU ms: CPU time per render, all threads (steadier than wall time on a shared "
          "machine)")
    head = (f"  {'task':<6}{'quality':<9}{'resolution':<12}{'frames/s':>9}{'Mpx/s':>8}"
            f"{'CPU ms':>8}{'paper':>8}")
    print(head)
    for task in tasks:
        for q in qualities:
            rates = _render_rate(task, q, sizes, a.frames, a.budget)
            for (w, h), (fps, cpu) in zip(sizes, rates):
                res = f"{w}x{h}"
                paper = PAPER_CAMERA_FPS.get(res)
                print(f"  {task or 'flat':<6}{q:<9}{res:<12}{fps:>9.1f}{fps * w * h / 1e6:>8.1f}"
                      f"{1e3 * cpu:>8.0f}{'' if paper is None else f'{paper:.1f}':>8}", flush=True)
    return 0

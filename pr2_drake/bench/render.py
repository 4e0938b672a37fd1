"""Path-tracer benchmark: seconds per frame by size and samples, and noise against samples.

    pr2-drake bench render [--task 2] [--view follow] [--sizes 320x240,640x480,1280x720]
                           [--samples 1,4,16,64] [--noise-size 320x240] [--reference 1024]
                           [--speed-only] [--quick]

The scene: the task's testbed (seed 0) at its start state, seen by ``pr2-drake render``'s
camera (no simulation). For each size and samples per pixel: the wall time of one Cycles frame
(denoiser off, and on at the largest count), after one warm-up frame; beside it, Drake's VTK
raster of the same view (``high``: colour, depth and labels). Then the image error against a
reference frame of ``--reference`` samples (denoiser off) at ``--noise-size``: RMSE on 0-255
and PSNR [dB], with OpenImageDenoise off and on. The load average is printed with each row:
other processes share the cores.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np


def _sizes(text: str) -> list[tuple[int, int]]:
    try:
        return [tuple(int(v) for v in s.lower().split("x")) for s in text.split(",")]
    except ValueError:
        raise SystemExit(f"--sizes: expected WIDTHxHEIGHT,..., got {text!r}") from None


def _load() -> str:
    return "load " + " ".join(f"{v:.2f}" for v in os.getloadavg())


def _cpu() -> str:
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def _error(image: np.ndarray, reference: np.ndarray) -> tuple[float, float]:
    """(RMSE on 0-255, PSNR [dB]) of an 8-bit image against a reference."""
    rmse = float(np.sqrt(np.mean((image.astype(float) - reference.astype(float)) ** 2)))
    return rmse, float(20 * np.log10(255.0 / max(rmse, 1e-9)))


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="pr2-drake bench render", description=__doc__.split("\n")[0])
    p.add_argument("--task", type=int, default=2)
    p.add_argument("--view", choices=("follow", "head"), default="follow")
    p.add_argument("--sizes", default="320x240,640x480,1280x720")
    p.add_argument("--samples", default="1,4,16,64", help="samples per pixel, comma list")
    p.add_argument("--noise-size", default="320x240")
    p.add_argument("--reference", type=int, default=1024,
                   help="samples of the noise reference frame (default 1024)")
    p.add_argument("--speed-only", action="store_true", help="no noise table")
    p.add_argument("--quick", action="store_true",
                   help="160x120 only, 1 and 4 samples, a 64-sample reference")
    a = p.parse_args(argv)
    from pr2_drake.render import INSTALL_HINT
    from pr2_drake.render.command import path_tracer_available

    if not path_tracer_available():
        raise ValueError(INSTALL_HINT)
    if a.quick:
        a.sizes, a.samples, a.noise_size, a.reference = "160x120", "1,4", "160x120", 64
    sizes = _sizes(a.sizes)
    samples = [int(s) for s in a.samples.split(",")]
    (noise_w, noise_h), = _sizes(a.noise_size)
    print(f"pr2-drake bench render: task {a.task}, {a.view} view, start state; "
          f"{os.cpu_count()} cores ({_cpu()}); {_load()}")
    frame, rig = _setup(a.task)
    _speed_table(frame, rig, a.view, sizes, samples)
    if not a.speed_only:
        _noise_table(frame, rig, a.view, noise_w, noise_h, samples, a.reference)
    return 0


def _setup(task: int):
    """The rig and a function (view, samples, denoise) -> image, with setup times printed."""
    from pr2_drake.render.frames import Engine
    from pr2_drake.render.rig import RenderRig
    from pr2_drake.render.view import RenderRequest
    from pr2_drake.scenario import Scenario

    t0 = time.perf_counter()
    rig = RenderRig(Scenario(task=task, seed=0).testbed_config())
    t1 = time.perf_counter()
    engine = Engine(rig, RenderRequest())
    t2 = time.perf_counter()
    print(f"setup: testbed and raster {t1 - t0:.1f} s; scene export and Cycles scene "
          f"{t2 - t1:.1f} s")

    def frame(view, spp: int, denoise: bool) -> tuple[np.ndarray, float]:
        engine.request.samples, engine.request.denoise = spp, denoise
        start = time.perf_counter()
        image = engine.color(view)
        return image, time.perf_counter() - start

    return frame, rig


def _view(rig, name: str, w: int, h: int):
    return rig.follow_view(w, h) if name == "follow" else rig.head_view(w, h)


def _speed_table(frame, rig, view_name, sizes, samples) -> None:
    w0, h0 = sizes[0]
    start = time.perf_counter()
    rig.raster(_view(rig, view_name, w0, h0))
    raster = time.perf_counter() - start
    _, warm = frame(_view(rig, view_name, w0, h0), 1, True)
    print(f"warm-up frames (the first of each engine): Cycles {warm:.2f} s (kernels, scene "
          f"sync, denoiser), VTK {raster:.2f} s")
    print("\nseconds per frame, Cycles on the CPU (denoiser off; 'dn' = on at the most samples)")
    head = "".join(f"{f'{s} spp':>10}" for s in samples)
    print(f"  {'size':<11}{'vtk high':>10}{head}{f'{samples[-1]} dn':>10}   load")
    for w, h in sizes:
        view = _view(rig, view_name, w, h)
        start = time.perf_counter()
        rig.raster(view)
        cells = [time.perf_counter() - start]
        cells += [frame(view, s, False)[1] for s in samples]
        cells.append(frame(view, samples[-1], True)[1])
        print(f"  {f'{w}x{h}':<11}" + "".join(f"{c:>10.2f}" for c in cells) + f"   {_load()}",
              flush=True)


def _noise_table(frame, rig, view_name, w, h, samples, reference_spp) -> None:
    view = _view(rig, view_name, w, h)
    reference, took = frame(view, reference_spp, False)
    print(f"\nimage error against a {reference_spp}-sample reference ({took:.1f} s) at {w}x{h}: "
          "RMSE on 0-255 / PSNR [dB]")
    print(f"  {'samples':<9}{'denoiser off':>22}{'denoiser on':>22}   load")
    for s in samples:
        cells = []
        for denoise in (False, True):
            image, t = frame(view, s, denoise)
            rmse, psnr = _error(image, reference)
            cells.append(f"{rmse:6.2f} / {psnr:4.1f} ({t:5.2f} s)")
        print(f"  {s:<9}" + "".join(f"{c:>22}" for c in cells) + f"   {_load()}", flush=True)

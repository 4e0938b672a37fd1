"""Path-traced gallery: every task's overview and head-camera view (seed 0, the robot at its
start), Drake's VTK raster (``high``) beside Cycles, the same frames as ``docs/gallery/task<N>.jpg``
(:mod:`pr2_drake.assets.make_gallery`).

    python -m pr2_drake.render.gallery [--size 400x300] [--samples 128] [--out docs/gallery]

writes ``task<N>_pathtraced.jpg`` per task: overview on the top row, head camera below;
raster on the left, path traced on the right. Needs the ``[photoreal]`` extra.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np

from pr2_drake.render.view import CameraView, RenderRequest, look_at_matrix

OVERVIEW_FOV_DEG = 55.0  # that of pr2_drake.viz.render_task_views


def _label(image: np.ndarray, text: str) -> np.ndarray:
    image = image.copy()
    for colour, width in (((0, 0, 0), 3), ((255, 255, 255), 1)):
        cv2.putText(image, text, (8, 24), cv2.FONT_HERSHEY_SIMPLEX, 0.7, colour, width,
                    cv2.LINE_AA)
    return image


def task_sheet(task: int, size: tuple[int, int], samples: int) -> np.ndarray:
    """RGB image: (raster | path traced) of the overview, then of the head camera."""
    from pr2_drake.render.frames import Engine
    from pr2_drake.render.rig import RenderRig
    from pr2_drake.scenario import Scenario
    from pr2_drake.viz import overview_eye_target

    w, h = size
    rig = RenderRig(Scenario(task=task, seed=0).testbed_config())
    engine = Engine(rig, RenderRequest(width=w, height=h, samples=samples))
    overview = CameraView(look_at_matrix(*overview_eye_target(rig.testbed)), w, h,
                          OVERVIEW_FOV_DEG)
    rows = []
    for view in (overview, rig.head_view(w, h)):
        rows.append(np.hstack([_label(rig.raster(view).color, "raster (vtk high)"),
                               _label(engine.color(view), f"path traced ({samples} spp)")]))
    return np.vstack(rows)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--size", default="400x300", help="WIDTHxHEIGHT of each view")
    p.add_argument("--samples", type=int, default=128, help="samples per pixel")
    p.add_argument("--out", default="docs/gallery")
    p.add_argument("--tasks", default=None, help="comma list (default: all)")
    a = p.parse_args(argv)
    from pr2_drake.tasks import list_tasks

    w, h = (int(v) for v in a.size.split("x"))
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    tasks = [int(t) for t in a.tasks.split(",")] if a.tasks else [i for i, _ in list_tasks()]
    for task in tasks:
        sheet = task_sheet(task, (w, h), a.samples)
        path = out / f"task{task}_pathtraced.jpg"
        cv2.imwrite(str(path), sheet[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, 82])
        print(f"{path}  {path.stat().st_size // 1024} KiB", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

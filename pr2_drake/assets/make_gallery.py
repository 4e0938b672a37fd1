"""Render the gallery of docs/gallery: every task's overview and head-camera view (seed 0, the
robot at its start) at each render preset, the same frame side by side.

    PYTHONPATH=. python -m pr2_drake.assets.make_gallery [--size 400x300] [--out docs/gallery]

writes ``task<N>.jpg`` per task: one row per preset (low, medium, high), overview on the left,
head camera on the right, the preset's name in the corner.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np

from pr2_drake.camera import QUALITIES, CameraSettings
from pr2_drake.tasks import list_tasks
from pr2_drake.testbed import TestbedConfig
from pr2_drake.viz import render_task_views


def task_sheet(task: int, size: tuple[int, int], qualities=QUALITIES) -> np.ndarray:
    """RGB image: one row per preset, (overview | head camera) at ``size`` (width, height)."""
    rows = []
    for q in qualities:
        overview, head = render_task_views(
            TestbedConfig(task=task, seed=0, camera=CameraSettings(quality=q)), size=size)
        row = np.hstack([overview, head])
        cv2.putText(row, q, (8, 24), cv2.FONT_HERSHEY_SIMPLEX, 0.7, (0, 0, 0), 3, cv2.LINE_AA)
        cv2.putText(row, q, (8, 24), cv2.FONT_HERSHEY_SIMPLEX, 0.7, (255, 255, 255), 1,
                    cv2.LINE_AA)
        rows.append(row)
    return np.vstack(rows)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--size", default="400x300", help="WIDTHxHEIGHT of each view")
    p.add_argument("--out", default="docs/gallery")
    p.add_argument("--tasks", default=None, help="comma list (default: all)")
    a = p.parse_args(argv)
    w, h = (int(v) for v in a.size.split("x"))
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    tasks = [int(t) for t in a.tasks.split(",")] if a.tasks else [i for i, _ in list_tasks()]
    for task in tasks:
        sheet = task_sheet(task, (w, h))
        path = out / f"task{task}.jpg"
        cv2.imwrite(str(path), sheet[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, 82])
        print(f"{path}  {path.stat().st_size // 1024} KiB", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

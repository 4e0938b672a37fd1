"""Perception benchmark: the task-6 ObjectDetector on rendered head-camera views.

    pr2-drake bench perception [--views 100] [--qualities low,medium,high] [--seed 0]
                               [--width 640 --height 480] [--save DIR]

For each render-quality preset, ``--views`` head-camera frames of the task-6 house: the nine
objects at random poses on their tables (drawn like an episode), sometimes the target moved to
the coffee table or the floor; the robot standing (default joint pose) 0.5-1.6 m in front of a
random table, heading +-20 deg off it. The target of a view is a random object visible in it.
The detector sees the colour + depth images and X_WC from forward kinematics of the robot's
body_state + joint_state; the simulator's object poses are used only to score it.

Printed per preset: detection rate (a detection labelled as the target within 0.10 m of it),
mislabels (the target's detection is elsewhere), false detections per view (any detection not
within 0.10 m of an object of its label), position error median / 95th percentile, time.

:class:`pr2_drake.bench.rigs.ViewRig` renders the posed views (no simulation).
"""

import argparse
import statistics
import sys
import time

import numpy as np

from pr2_drake.bench.rigs import ViewRig

MATCH_RADIUS = 0.10  # [m] a detection this close to an object of its label is a true one


def evaluate(quality: str, views: int, seed: int, width: int, height: int,
             save: str | None = None) -> dict:
    from pr2_drake.agents.search.perception import (
        CameraIntrinsics,
        HeadCameraKinematics,
        ObjectDetector,
        object_models_from_priors,
    )

    rig = ViewRig(quality, seed, width, height)
    detector = ObjectDetector(object_models_from_priors(rig.tb.scene.priors),
                              CameraIntrinsics.from_settings(rig.settings))
    kin = HeadCameraKinematics()
    rng = np.random.default_rng(seed)
    n = found = mislabel = false = 0
    errors, seconds = [], []
    while n < views:
        view = rig.random_view(rng)
        if not view.visible:
            continue
        target = view.visible[int(rng.integers(len(view.visible)))]
        n += 1
        t0 = time.perf_counter()
        X_WC = kin.camera_pose(view.body_state, view.joint_state)
        dets = detector.detect(view.rgb, view.depth, X_WC)
        seconds.append(time.perf_counter() - t0)
        hit = next((d for d in dets if d.label == target), None)
        if hit is not None:
            err = float(np.linalg.norm(hit.p_WO - view.objects[target]))
            if err <= MATCH_RADIUS:
                found += 1
                errors.append(err)
            else:
                mislabel += 1
        false += sum(1 for d in dets
                     if np.linalg.norm(d.p_WO - view.objects[d.label]) > MATCH_RADIUS)
        if save:
            import cv2

            img = view.rgb[:, :, ::-1].copy()
            for d in dets:
                u0, v0, u1, v1 = d.bbox
                cv2.rectangle(img, (u0, v0), (u1, v1), (0, 255, 0), 1)
                cv2.putText(img, f"{d.label} {d.score:.2f}", (u0, max(10, v0 - 3)),
                            cv2.FONT_HERSHEY_SIMPLEX, 0.35, (0, 255, 0), 1)
            cv2.imwrite(f"{save}/{quality}_{n:03d}_{target}.png", img)
    return {"quality": quality, "views": n, "found": found, "mislabel": mislabel,
            "false": false, "errors": errors, "seconds": seconds}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="pr2-drake bench perception")
    p.add_argument("--views", type=int, default=100)
    p.add_argument("--qualities", default="low,medium,high")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--width", type=int, default=640)
    p.add_argument("--height", type=int, default=480)
    p.add_argument("--save", metavar="DIR", help="write annotated frames here")
    a = p.parse_args(argv)
    if a.views < 1:
        p.error("--views must be at least 1")
    print(f"ObjectDetector on rendered task-6 head-camera views, {a.width}x{a.height}, "
          f"seed {a.seed}")
    print(f"{'quality':8s} {'views':>5s} {'detected':>9s} {'mislabel':>8s} {'false/view':>10s} "
          f"{'err med':>8s} {'err p95':>8s} {'ms/frame':>8s}")
    for q in a.qualities.split(","):
        r = evaluate(q.strip(), a.views, a.seed, a.width, a.height, a.save)
        e = np.asarray(r["errors"]) * 100
        med = f"{np.median(e):.1f} cm" if len(e) else "-"
        p95 = f"{np.percentile(e, 95):.1f} cm" if len(e) else "-"
        print(f"{r['quality']:8s} {r['views']:5d} {100 * r['found'] / r['views']:8.1f}% "
              f"{r['mislabel']:8d} {r['false'] / r['views']:10.2f} {med:>8s} {p95:>8s} "
              f"{1000 * statistics.median(r['seconds']):8.0f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

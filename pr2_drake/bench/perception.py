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

:class:`ViewRig` (render a posed view without simulating) is also used by the tests.
"""

import argparse
import math
import statistics
import sys
import time
from dataclasses import dataclass

import numpy as np
from pydrake.math import RigidTransform, RollPitchYaw

from pr2_drake.camera import CameraSettings

MATCH_RADIUS = 0.10  # [m] a detection this close to an object of its label is a true one


@dataclass
class View:
    """A rendered frame with what the robot knows (states) and the truth (object centres)."""

    rgb: np.ndarray
    depth: np.ndarray
    body_state: np.ndarray
    joint_state: np.ndarray
    objects: dict  # name -> p_WO [m] (truth, scoring only)
    visible: list  # names whose centre projects into the image unoccluded
    table: str


class ViewRig:
    """A task-6 testbed whose robot and objects are posed by hand and whose head camera is
    rendered directly (no simulation)."""

    def __init__(self, quality: str = "low", seed: int = 0, width: int = 640, height: int = 480):
        from pr2_drake.testbed import Testbed, TestbedConfig

        self.settings = CameraSettings(enabled=True, width=width, height=height, fps=10.0,
                                       quality=quality)
        self.tb = Testbed(TestbedConfig(task=6, seed=seed, camera=self.settings))
        self.ctx = self.tb.CreateDefaultContext()
        self.pc = self.tb.plant.GetMyMutableContextFromRoot(self.ctx)
        self.sensor = self.tb.GetSubsystemByName("head_camera")
        self.sc = self.sensor.GetMyContextFromRoot(self.ctx)
        self.scene = self.tb.task.spec.scene
        self.tables = self.tb.scene.data["tables"]

    def body(self, name: str):
        return self.tb.plant.get_body(self.tb.scene.data["bodies"][name])

    def pose_robot(self, x: float, y: float, yaw: float) -> None:
        from pr2_drake.robot.model import BASE_BODY, standing_base_pose

        plant, robot = self.tb.plant, self.tb.robot
        X = standing_base_pose(plant, robot, self.tb.default_joints, (x, y), yaw)
        plant.SetFreeBodyPose(self.pc, plant.GetBodyByName(BASE_BODY, robot), X)

    def set_object(self, name: str, X_WO: RigidTransform) -> None:
        self.tb.plant.SetFreeBodyPose(self.pc, self.body(name), X_WO)

    def render(self) -> tuple[np.ndarray, np.ndarray]:
        rgb = self.sensor.color_image_output_port().Eval(self.sc).data[:, :, :3].copy()
        depth = self.sensor.depth_image_32F_output_port().Eval(self.sc).data[:, :, 0].copy()
        return rgb, depth

    def states(self) -> tuple[np.ndarray, np.ndarray]:
        return (self.tb.GetOutputPort("body_state").Eval(self.ctx).copy(),
                self.tb.GetOutputPort("joint_state").Eval(self.ctx).copy())

    def random_view(self, rng: np.random.Generator) -> View:
        """Objects as in an episode draw, maybe one moved; robot facing a random table."""
        from pr2_drake.tasks.t6_object_search import model_extent, sample_layout

        _, poses, _, _ = sample_layout(self.scene, self.tables, rng)
        names = list(poses)
        move = rng.uniform()
        if move < 0.3:  # one object on the coffee table or the floor of the living room
            name = names[int(rng.integers(len(names)))]
            half_h, _ = model_extent(self.tb.scene.priors["object_models"][name]["sdf"])
            ct = self.tables["coffee_table"]
            if move < 0.2:
                p = [ct.center[0] + rng.uniform(-0.35, 0.35), ct.center[1] + rng.uniform(-0.18, 0.18),
                     ct.height + half_h + 0.002]
            else:
                p = [rng.uniform(-3.0, -1.0), rng.uniform(-1.2, -0.5), half_h + 0.002]
            poses[name] = RigidTransform(RollPitchYaw(0, 0, rng.uniform(-np.pi, np.pi)), p)
        for name, X in poses.items():
            self.set_object(name, X)
        table = ["kitchen_table", "play_table", "desk", "coffee_table"][int(rng.integers(4))]
        t = self.tables[table]
        side = -1.0 if table in ("play_table", "desk") else 1.0  # the room's open side
        d = rng.uniform(0.5, 1.6)
        x = t.center[0] + rng.uniform(-0.4, 0.4)
        y = t.center[1] + side * (t.size[1] / 2 + d)
        yaw = math.atan2(t.center[1] - y, t.center[0] - x) + math.radians(rng.uniform(-20, 20))
        self.pose_robot(x, y, yaw)
        rgb, depth = self.render()
        body, joints = self.states()
        objects = {n: self.body(n).EvalPoseInWorld(self.pc).translation().copy() for n in poses}
        return View(rgb, depth, body, joints, objects, self._visible(objects, depth), table)

    def _visible(self, objects: dict, depth: np.ndarray) -> list:
        from pr2_drake.agents.search.perception import CameraIntrinsics

        K = CameraIntrinsics.from_settings(self.settings)
        X_WC = self.sensor_pose()
        out = []
        for name, p in objects.items():
            p_C = X_WC.inverse().multiply(p)
            if p_C[2] < 0.3:
                continue
            u, v = K.fx * p_C[0] / p_C[2] + K.cx, K.fy * p_C[1] / p_C[2] + K.cy
            m = 8  # pixels of margin
            if not (m <= u < K.width - m and m <= v < K.height - m):
                continue
            if abs(float(depth[int(v), int(u)]) - p_C[2]) < 0.08:
                out.append(name)
        return out

    def sensor_pose(self) -> RigidTransform:
        """X_WC from the simulator (scoring only: the detector gets it from kinematics)."""
        frame = self.tb.plant.GetFrameByName("head_camera", self.tb.robot)
        return frame.CalcPoseInWorld(self.pc)


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

"""Stairs benchmark: up then down a staircase, per riser height and step count.

    pr2-drake bench stairs [--quick] [--repeats 5] [--heights 0.05 0.10 0.12 0.15]
                           [--counts 2 4]
    python -m pr2_drake.bench.stairs [--quick]

Builds its own scene (the testbed's ``scene_builder``): flat ground, ``count`` steps of one riser
height and 0.40 m treads up along +x, a 1.2 m floor, the same steps down. The robot starts
in front of the first step (``repeats`` starts, slightly shifted in x, y and yaw, seeded) and
walks with the walking controller, :class:`pr2_drake.controllers.tread_steps.
TreadFootstepPlanner` and the staircase's :class:`PatchTerrain` (controllers/walking_stairs.yaml)
at a constant forward command with heading hold, until its base is past the last step.

Prints one row per (riser, count): falls out of the repeats, mean simulated time to cross, the
wall-clock real-time factor while climbing; then the highest riser climbed up and down without
a fall in all repeats. :class:`StairsSim` (the closed loop on a staircase) is also used by
tests/test_stairs.py and notebooks/05_stairs.ipynb.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import dataclass

import numpy as np
from pydrake.geometry import Box
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from pr2_drake.controllers.posture import ArmPosture
from pr2_drake.controllers.terrain_model import PatchTerrain, stairs_terrain
from pr2_drake.controllers.tread_steps import TreadFootstepPlanner
from pr2_drake.controllers.walking import WalkingController
from pr2_drake.controllers.walking_params import WalkingParams
from pr2_drake.robot.model import BASE_BODY
from pr2_drake.scene import GROUND_FRICTION, Scene, StartPose, add_flat_ground
from pr2_drake.tasks.base import FALL_HEIGHT
from pr2_drake.tasks.regions import rgba
from pr2_drake.testbed import Testbed, TestbedConfig

WALKING_OVERRIDES = "controllers/walking_stairs.yaml"
FLOOR_LENGTH = 1.2  # [m] level top between the way up and the way down
TREAD = 0.40  # [m]
START_X = 1.0  # [m] first riser; the robot starts at x = 0
FALL_TILT = 0.8  # [rad] pelvis roll or pitch beyond this = fallen
FINITE_LENGTH = 3.0  # [m] boxes drawn for a patch that goes on
COLORS = ([0.30, 0.45, 0.75], [0.25, 0.62, 0.68])


def add_patch_terrain(plant: MultibodyPlant, terrain: PatchTerrain) -> None:
    """Collision and visual boxes on the world body for the level patches of ``terrain``
    (each a box from z = 0 up to the patch; infinite extents drawn FINITE_LENGTH long)."""
    for k, p in enumerate(terrain.patches):
        if p.gx or p.gy or p.z <= 0.0:
            continue
        x0, x1 = p.x_min, p.x_max if math.isfinite(p.x_max) else p.x_min + FINITE_LENGTH
        y0, y1 = (p.y_min, p.y_max) if math.isfinite(p.y_min + p.y_max) else (-1.0, 1.0)
        box = Box(x1 - x0, y1 - y0, p.z)
        X = RigidTransform([0.5 * (x0 + x1), 0.5 * (y0 + y1), 0.5 * p.z])
        name = p.name or f"patch_{k}"
        plant.RegisterCollisionGeometry(plant.world_body(), X, box, name, GROUND_FRICTION)
        plant.RegisterVisualGeometry(plant.world_body(), X, box, name,
                                     rgba(COLORS[k % len(COLORS)]))


class StairsSim:
    """Testbed on a :class:`PatchTerrain` + walking controller on treads + arm posture.

    Args:
        terrain: the ground (its level patches become boxes).
        start: the robot's start pose.
        params: walking parameters (None: walking.yaml with walking_stairs.yaml).
        planner_params: :class:`TreadPlannerParams` (None: controllers/tread_planner.yaml).
    """

    def __init__(self, terrain: PatchTerrain, start: StartPose | None = None,
                 params: WalkingParams | None = None, planner_params=None, meshcat=None):
        self.terrain = terrain
        self.params = params or WalkingParams.load().with_overrides(WALKING_OVERRIDES)
        footsteps = TreadFootstepPlanner(self.params.gait, self.params.limits.start_threshold,
                                         terrain, planner_params)

        def scene(plant, rng):
            add_flat_ground(plant)
            add_patch_terrain(plant, terrain)
            return Scene(name="stairs", start=start or StartPose(),
                         ground_height=terrain.height)

        self.testbed = tb = Testbed(TestbedConfig(scene_builder=scene), meshcat)
        self.walker = WalkingController(self.params, footsteps=footsteps, terrain=terrain)
        self.arms = ArmPosture(stiffness=self.params.arm_stiffness,
                               damping=self.params.arm_damping)
        builder = DiagramBuilder()
        builder.AddSystem(tb)
        builder.AddSystem(self.walker)
        builder.AddSystem(self.arms)
        builder.Connect(tb.GetOutputPort("joint_state"), self.walker.GetInputPort("joint_state"))
        builder.Connect(tb.GetOutputPort("body_state"), self.walker.GetInputPort("body_state"))
        builder.Connect(self.walker.GetOutputPort("legs_command"), tb.GetInputPort("legs_command"))
        builder.Connect(self.arms.GetOutputPort("arms_command"), tb.GetInputPort("arms_command"))
        self.diagram = builder.Build()
        self.simulator = Simulator(self.diagram)
        self.context = self.simulator.get_mutable_context()
        self.plant = tb.plant
        self.plant_context = self.plant.GetMyMutableContextFromRoot(self.context)
        self.walker_context = self.walker.GetMyMutableContextFromRoot(self.context)
        self.base = self.plant.GetBodyByName(BASE_BODY, tb.robot)
        self.soles = [self.plant.GetFrameByName(n, tb.robot) for n in ("l_sole", "r_sole")]
        self.set_command(0.0, 0.0, 0.0)
        self.simulator.Initialize()

    def set_command(self, vx: float, vy: float, yaw_rate: float) -> None:
        self.walker.GetInputPort("velocity_command").FixValue(
            self.walker_context, np.array([vx, vy, yaw_rate], dtype=float))

    @property
    def time(self) -> float:
        return self.context.get_time()

    def base_pose(self):
        """(p_WB (3), roll, pitch, yaw) of base_link."""
        X = self.plant.EvalBodyPoseInWorld(self.plant_context, self.base)
        rpy = RollPitchYaw(X.rotation())
        return X.translation().copy(), rpy.roll_angle(), rpy.pitch_angle(), rpy.yaw_angle()

    def fallen(self) -> bool:
        p, roll, pitch, _ = self.base_pose()
        ground = self.terrain.height(p[0], p[1])
        return bool(p[2] - ground < FALL_HEIGHT or abs(roll) > FALL_TILT
                    or abs(pitch) > FALL_TILT)

    def sole_points(self, side: int) -> np.ndarray:
        """Heel and toe of a sole (2 x 3, W) [m]: the sole's ends on its x axis."""
        X = self.soles[side].CalcPoseInWorld(self.plant_context)
        half = 0.5 * self.terrain.foot_length
        return np.array([X @ np.array([-half, 0.0, 0.0]), X @ np.array([half, 0.0, 0.0])])

    def status(self) -> np.ndarray:
        return self.walker.GetOutputPort("status").Eval(self.walker_context)

    def walk(self, speed: float, x_end: float, timeout: float, heading_gain: float = 1.0,
             check_every: float = 0.1, log=None) -> bool:
        """Walk forward at ``speed`` [m/s] holding heading 0 until the base passes ``x_end``
        [m], then stop and settle 2 s. Returns False on a fall or the timeout.
        ``log(sim)`` is called every ``check_every`` s."""
        t_end = self.time + timeout
        while self.time < t_end:
            p, _, _, yaw = self.base_pose()
            done = p[0] >= x_end
            self.set_command(0.0 if done else speed, 0.0,
                             0.0 if done else float(np.clip(-heading_gain * yaw, -0.3, 0.3)))
            self.simulator.AdvanceTo(self.time + check_every)
            if log is not None:
                log(self)
            if self.fallen():
                return False
            if done:
                self.simulator.AdvanceTo(self.time + 2.0)
                return not self.fallen()
        return False


@dataclass
class Row:
    height: float
    count: int
    falls: int
    repeats: int
    time: float  # mean simulated time to cross [s] (runs without a fall)
    rtf: float  # wall-clock real-time factor while walking


def starts(repeats: int, seed: int = 0) -> list[StartPose]:
    """Slightly different starts: x in [-0.05, 0.05], y in [-0.05, 0.05] m, yaw +-3 deg."""
    rng = np.random.default_rng(seed)
    return [StartPose(float(rng.uniform(-0.05, 0.05)), float(rng.uniform(-0.05, 0.05)),
                      float(np.radians(rng.uniform(-3.0, 3.0)))) for _ in range(repeats)]


def run_stairs(height: float, count: int, start: StartPose, speed: float = 0.25,
               meshcat=None) -> tuple[bool, float, float]:
    """Up then down one staircase: (no fall, simulated time [s], real-time factor)."""
    terrain = stairs_terrain(START_X, count, height, TREAD, 2.0, floor_length=FLOOR_LENGTH,
                             down=True)
    sim = StairsSim(terrain, start, meshcat=meshcat)
    x_end = START_X + 2 * count * TREAD + FLOOR_LENGTH - TREAD + 0.4
    wall = time.perf_counter()
    ok = sim.walk(speed, x_end, timeout=20.0 + 8.0 * count)
    rtf = sim.time / max(time.perf_counter() - wall, 1e-9)
    return ok, sim.time, rtf


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="pr2-drake bench stairs", description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="0.10 m, 2 steps, 1 repeat")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--heights", type=float, nargs="+", default=[0.05, 0.10, 0.12, 0.15])
    ap.add_argument("--counts", type=int, nargs="+", default=[2, 4])
    args = ap.parse_args(argv)
    if args.repeats < 1:
        ap.error("--repeats must be at least 1")
    heights, counts, repeats = args.heights, args.counts, args.repeats
    if args.quick:
        heights, counts, repeats = [0.10], [2], 1
    rows = []
    print(f"{'riser [m]':>9} {'steps':>5} {'falls':>7} {'time [s]':>9} {'RTF':>6}")
    for h in heights:
        for n in counts:
            results = [run_stairs(h, n, s) for s in starts(repeats)]
            ok = [r for r in results if r[0]]
            row = Row(h, n, len(results) - len(ok), len(results),
                      float(np.mean([r[1] for r in ok])) if ok else float("nan"),
                      float(np.median([r[2] for r in results])))
            rows.append(row)
            print(f"{h:9.2f} {n:5d} {row.falls:3d}/{row.repeats:<3d} {row.time:9.1f} "
                  f"{row.rtf:6.3f}", flush=True)
    safe = [h for h in heights if all(r.falls == 0 for r in rows if r.height == h)]
    best = max(safe) if safe else None
    print("highest riser climbed up and down without a fall in all repeats: "
          + ("none" if best is None else f"{best:.2f} m"))
    return 0


if __name__ == "__main__":
    sys.exit(main())

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

The walk holds the start's y (``--lane-gain``, 0.8 1/s as StepsButtonAgent; 0 = off): without
it the robot drifts 0.1-0.2 m sideways at each riser (the pelvis rolls while the swing leg
lifts fast over the riser) and walks off the side of 2 m wide stairs. ``--overrides`` applies a
YAML of walking parameters after walking_stairs.yaml (tuning).

Prints one row per (riser, count): falls out of the repeats, mean simulated time to cross, the
wall-clock real-time factor while climbing; for each fall where it happened (going up / top
floor / going down, which riser, sim time) and the first sign of trouble in the last second
(:meth:`StairsSim.diagnose`: a knee at its limit, a swing toe caught on a riser's nosing, heel
or toe off an edge, a sole off the side, the DCM outside the support); then the highest riser
climbed up and down without a fall in all repeats.

What limits step height now: the planner refuses risers over 0.12 m
(controllers/tread_planner.yaml ``max_step_height``), the highest measured without a fall:
``pr2-drake bench stairs --max-step-height 0.15`` (5 repeats, up then down): 0.05, 0.10 and
0.12 m, 2 and 4 steps, 0/5 falls each; 0.15 m, 2 and 4 steps, 5/5 falls, all at the first
riser going up: the swing toe caught on the nosing (8 of 10) or the stance knee at its limit
(2 of 10). With the CoM-height weight at 300 (before) 0.12 m x 4 fell 2/5 going up: the
stance knee reached its limit while the swing sole lifted fast over the riser (the CoM
overshot its height target by ~5 cm), or the rear toe pitched down at lift-off and caught the
nosing. :class:`StairsSim` (the closed loop on a staircase) is also used by
tests/test_stairs.py and notebooks/05_stairs.ipynb.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import dataclass, replace

import numpy as np
from pydrake.geometry import Box
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from pr2_drake.controllers.posture import ArmPosture
from pr2_drake.controllers.terrain_model import PatchTerrain, stairs_terrain
from pr2_drake.controllers.tread_steps import TreadFootstepPlanner, TreadPlannerParams
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
#: [1/s] the bench walk holds the start's y like StepsButtonAgent (lateral_gain 0.8 1/s,
#: max 0.08 m/s): without it the robot drifts 0.1-0.2 m sideways per riser crossing.
LANE_GAIN = 0.8
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
        footsteps: the footstep planner (None: :class:`TreadFootstepPlanner` on ``terrain``).
        obstacles: :class:`pr2_drake.controllers.step_over.Obstacle` boxes added to the scene
            (not to the terrain model); their geometry ids in ``obstacle_ids``.
        start: the robot's start pose.
        params: walking parameters (None: walking.yaml with walking_stairs.yaml).
        planner_params: :class:`TreadPlannerParams` (None: controllers/tread_planner.yaml).
    """

    def __init__(self, terrain: PatchTerrain, start: StartPose | None = None,
                 params: WalkingParams | None = None, planner_params=None, meshcat=None,
                 footsteps=None, obstacles=()):
        self.terrain = terrain
        self.params = params or WalkingParams.load().with_overrides(WALKING_OVERRIDES)
        if footsteps is None:
            footsteps = TreadFootstepPlanner(self.params.gait,
                                             self.params.limits.start_threshold, terrain,
                                             planner_params)
        self.obstacle_ids: list = []  # GeometryId of each obstacle box

        def scene(plant, rng):
            add_flat_ground(plant)
            add_patch_terrain(plant, terrain)
            for k, o in enumerate(obstacles):
                box = Box(o.x_max - o.x_min, o.y_max - o.y_min, o.top)
                X = RigidTransform([0.5 * (o.x_min + o.x_max), 0.5 * (o.y_min + o.y_max),
                                    0.5 * o.top])
                name = o.name or f"obstacle_{k}"
                self.obstacle_ids.append(plant.RegisterCollisionGeometry(
                    plant.world_body(), X, box, name, GROUND_FRICTION))
                plant.RegisterVisualGeometry(plant.world_body(), X, box, name,
                                             rgba([0.8, 0.3, 0.2]))
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
        self.fall: Fall | None = None  # the last walk's failure (walk)
        self.snapshots: list[Snapshot] = []

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

    def touching(self, geometry_ids) -> bool:
        """Whether any contact pair (last plant step) involves one of ``geometry_ids``."""
        ids = set(geometry_ids)
        res = self.plant.get_contact_results_output_port().Eval(self.plant_context)
        for i in range(res.num_point_pair_contacts()):
            info = res.point_pair_contact_info(i).point_pair()
            if info.id_A in ids or info.id_B in ids:
                return True
        return False

    def status(self) -> np.ndarray:
        return self.walker.GetOutputPort("status").Eval(self.walker_context)

    def walk(self, speed: float, x_end: float, timeout: float, heading_gain: float = 1.0,
             check_every: float = 0.1, log=None, lane_gain: float = 0.0,
             lane_speed: float = 0.08) -> bool:
        """Walk forward at ``speed`` [m/s] holding heading 0 until the base passes ``x_end``
        [m], then stop and settle 2 s. Returns False on a fall or the timeout (then
        :attr:`fall` says where and why, :meth:`diagnose`). ``lane_gain`` [1/s] > 0 also holds
        the start's y (a sideways command ``lane_gain`` times the base's y error, at most
        ``lane_speed`` [m/s], as StepsButtonAgent does). ``log(sim)`` is called every
        ``check_every`` s."""
        t_end = self.time + timeout
        lane_y = self.base_pose()[0][1]
        self.fall = None
        self.snapshots = []
        while self.time < t_end:
            p, _, _, yaw = self.base_pose()
            done = p[0] >= x_end
            vy = float(np.clip(lane_gain * (lane_y - p[1]), -lane_speed, lane_speed))
            self.set_command(0.0 if done else speed, 0.0 if done else vy,
                             0.0 if done else float(np.clip(-heading_gain * yaw, -0.3, 0.3)))
            self.simulator.AdvanceTo(self.time + check_every)
            self.snapshots = self.snapshots[-(SNAPSHOTS - 1):] + [self.snapshot()]
            if log is not None:
                log(self)
            if self.fallen():
                self.fall = self.diagnose()
                return False
            if done:
                self.simulator.AdvanceTo(self.time + 2.0)
                if self.fallen():
                    self.fall = self.diagnose()
                    return False
                return True
        self.fall = Fall(self.time, *self.where(self.base_pose()[0][0]), "timeout (no fall)")
        return False

    # ---- where and why a fall happens ---------------------------------------------------------
    def snapshot(self) -> "Snapshot":
        """The state the fall diagnosis reads (see :class:`Snapshot`)."""
        gp = self.walker.core.planner
        com = self.plant.CalcCenterOfMassPositionInWorld(self.plant_context)
        vcom = self.plant.CalcCenterOfMassTranslationalVelocityInWorld(self.plant_context)
        omega = math.sqrt(self.walker.core.model.gravity / self.params.gait.com_height)
        knees = [self.plant.GetJointByName(n, self.testbed.robot).get_angle(self.plant_context)
                 for n in ("l_knee", "r_knee")]
        swing = gp.swing
        return Snapshot(self.time, com.copy(), com[:2] + vcom[:2] / omega,
                        [self.sole_points(0), self.sole_points(1)], knees, int(gp.phase),
                        gp.stance, None if swing is None else swing.target.copy())

    def where(self, x: float) -> tuple[str, int, int]:
        """(section, riser number, risers in that flight) of a point at x [m]: "up" / "down"
        with the nearest riser of that flight (1 = first crossed), or "top floor" / "start"
        / "end" (riser 0) when farther than half a tread from every riser."""
        risers = self.terrain.risers()
        up = [r for r in risers if r[1] > 0]
        down = [r for r in risers if r[1] < 0]
        near = min(risers, key=lambda r: abs(r[0] - x), default=None)
        if near is None or abs(near[0] - x) > 0.5 * TREAD:
            if up and x < up[0][0]:
                return "start", 0, len(up)
            if down and x > down[-1][0]:
                return "end", 0, len(down)
            return "top floor", 0, len(up)
        flight = up if near[1] > 0 else down
        return ("up" if near[1] > 0 else "down"), flight.index(near) + 1, len(flight)

    def diagnose(self) -> "Fall":
        """Where the fall happened and the first sign of trouble in the last
        :data:`SNAPSHOTS` snapshots (see :class:`Fall`)."""
        snaps = self.snapshots
        last = snaps[-1] if snaps else self.snapshot()
        section, riser, n = self.where(float(last.com[0]))
        cause = "unclear"
        knee_lo = math.radians(-120.0) + self.params.qp.joint_limit_margin + 0.05
        knee_hi = self.params.qp.knee_max - 0.05
        t = self.terrain
        half_w = [0.5 * (p.y_max - p.y_min) for p in t.patches if math.isfinite(p.y_max)]
        for s in snaps[:-2] or snaps:  # the last ones show the fall itself, not its cause
            reasons = []
            for side, pts in enumerate(s.soles):
                name = ("left", "right")[side]
                if half_w and max(abs(pts[:, 1])) > min(half_w) and max(
                        t.height(x, y) for x, y, _ in pts) > t.base + 0.01:
                    reasons.append(f"{name} sole off the side of the stairs "
                                   f"(y = {pts[:, 1].mean():+.2f} m)")
                stance = s.phase != 2 or s.stance == side
                under = [t.height(x, y) for x, y, _ in pts]
                if stance and min(under) < max(under) - 0.01 and pts[:, 2].max() > min(under) \
                        + 0.01:
                    end = "heel" if under[0] < under[1] else "toe"
                    reasons.append(f"{name} {end} off the edge")
                if not stance:  # swing sole below the ground ahead of it: caught on a riser
                    x_front = pts[1, 0] + 0.01
                    if pts[:, 2].min() < t.height(x_front, pts[1, 1]) - 0.005:
                        reasons.append(f"{name} swing toe caught on a riser/nosing")
                if s.knees[side] > knee_hi or s.knees[side] < knee_lo:
                    role = "stance" if stance else "swing"
                    reasons.append(f"{name} ({role}) knee at its limit "
                                   f"({math.degrees(s.knees[side]):.0f} deg)")
            if not reasons:
                soles = np.vstack([p for side, p in enumerate(s.soles)
                                   if s.phase != 2 or s.stance == side])
                lo, hi = soles[:, :2].min(axis=0), soles[:, :2].max(axis=0)
                if np.any(s.dcm < lo - DCM_MARGIN) or np.any(s.dcm > hi + DCM_MARGIN):
                    reasons.append("DCM far outside the support (x, y = "
                                   f"{s.dcm[0]:.2f}, {s.dcm[1]:.2f} m)")
            if reasons:
                cause = f"t = {s.t:.2f} s: " + "; ".join(reasons)
                break
        return Fall(self.time, section, riser, n, cause)


#: [m] a DCM this far outside the soles' box (heel/toe, xy) is a sign of a fall coming (a
#: walk at 0.25 m/s keeps it within about 0.15 m of the stance sole).
DCM_MARGIN = 0.25
#: Snapshots (one per ``check_every``) the fall diagnosis looks back over.
SNAPSHOTS = 10


@dataclass
class Snapshot:
    """One look at the walk: time [s], CoM p_WCcm (3), DCM xy (W) [m], heel and toe of each
    sole (2 x 3 each, W), knee angles [rad], gait phase, stance side, swing target."""

    t: float
    com: np.ndarray
    dcm: np.ndarray
    soles: list
    knees: list
    phase: int
    stance: int
    target: np.ndarray | None


@dataclass
class Fall:
    """Where a walk failed: sim time [s], section ("up", "top floor", "down", "start",
    "end"), riser number in that flight (0 off the risers) of ``risers``, and the cause."""

    t: float
    section: str
    riser: int
    risers: int
    cause: str

    def __str__(self) -> str:
        where = (f"{self.section} riser {self.riser}/{self.risers}" if self.riser
                 else self.section)
        return f"t = {self.t:.1f} s, {where}; first sign: {self.cause}"


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
               meshcat=None, lane_gain: float = LANE_GAIN, overrides: str | None = None,
               max_step_height: float | None = None) -> tuple[bool, float, float, Fall | None]:
    """Up then down one staircase: (no fall, simulated time [s], real-time factor, where and
    why it failed or None). ``overrides``: a YAML file of walking parameters applied after
    controllers/walking_stairs.yaml (tuning); ``max_step_height`` [m]: the planner's limit in
    place of controllers/tread_planner.yaml's (to measure beyond it).

    Raises:
        ValueError: a riser taller than the planner's limit (the planner refuses it)."""
    terrain = stairs_terrain(START_X, count, height, TREAD, 2.0, floor_length=FLOOR_LENGTH,
                             down=True)
    params = WalkingParams.load().with_overrides(WALKING_OVERRIDES)
    if overrides:
        params = params.with_overrides(overrides)
    planner = TreadPlannerParams.load()
    if max_step_height is not None:
        planner = replace(planner, max_step_height=float(max_step_height))
    sim = StairsSim(terrain, start, params=params, planner_params=planner, meshcat=meshcat)
    x_end = START_X + 2 * count * TREAD + FLOOR_LENGTH - TREAD + 0.4
    wall = time.perf_counter()
    ok = sim.walk(speed, x_end, timeout=20.0 + 8.0 * count, lane_gain=lane_gain)
    rtf = sim.time / max(time.perf_counter() - wall, 1e-9)
    return ok, sim.time, rtf, sim.fall


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="pr2-drake bench stairs", description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="0.10 m, 2 steps, 1 repeat")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--heights", type=float, nargs="+", default=[0.05, 0.10, 0.12, 0.15])
    ap.add_argument("--counts", type=int, nargs="+", default=[2, 4])
    ap.add_argument("--lane-gain", type=float, default=LANE_GAIN,
                    help="[1/s] sideways command per m of drift from the start's y (0: none)")
    ap.add_argument("--overrides", default=None,
                    help="YAML of walking parameters applied after walking_stairs.yaml")
    ap.add_argument("--max-step-height", type=float, default=None,
                    help="[m] the planner's riser limit in place of tread_planner.yaml's "
                         "(taller risers are refused; raise it to measure beyond)")
    args = ap.parse_args(argv)
    if args.repeats < 1:
        ap.error("--repeats must be at least 1")
    heights, counts, repeats = args.heights, args.counts, args.repeats
    if args.quick:
        heights, counts, repeats = [0.10], [2], 1
    rows: list[Row] = []
    falls: list[str] = []
    refused: set[float] = set()
    print(f"{'riser [m]':>9} {'steps':>5} {'falls':>7} {'time [s]':>9} {'RTF':>6}")
    for h in heights:
        for n in counts:
            results = []
            try:
                for k, s in enumerate(starts(repeats)):
                    results.append(run_stairs(h, n, s, lane_gain=args.lane_gain,
                                              overrides=args.overrides,
                                              max_step_height=args.max_step_height))
                    if results[-1][3] is not None:
                        falls.append(f"  {h:.2f} m x {n}, repeat {k} (start x {s.x:+.3f} m, "
                                     f"y {s.y:+.3f} m, yaw {math.degrees(s.yaw):+.1f} deg): "
                                     f"{results[-1][3]}")
                        print(falls[-1], flush=True)
            except ValueError as e:  # the planner refuses the riser
                print(f"{h:9.2f} {n:5d} refused: {e}", flush=True)
                refused.add(h)
                continue
            ok = [r for r in results if r[0]]
            row = Row(h, n, len(results) - len(ok), len(results),
                      float(np.mean([r[1] for r in ok])) if ok else float("nan"),
                      float(np.median([r[2] for r in results])))
            rows.append(row)
            print(f"{h:9.2f} {n:5d} {row.falls:3d}/{row.repeats:<3d} {row.time:9.1f} "
                  f"{row.rtf:6.3f}", flush=True)
    safe = [h for h in heights
            if h not in refused and all(r.falls == 0 for r in rows if r.height == h)]
    best = max(safe) if safe else None
    if falls:
        print("falls (where, and the first sign of trouble in the last second):")
        print("\n".join(falls))
    print("highest riser climbed up and down without a fall in all repeats: "
          + ("none" if best is None else f"{best:.2f} m"))
    return 0


if __name__ == "__main__":
    sys.exit(main())

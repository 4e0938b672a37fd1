"""The benchmarks' and tests' rigs: an :class:`pr2_drake.episode.Episode` with the blocks under
test, and handles to drive and read it.

- :class:`Rig`: the base. The episode's diagram, simulator and contexts, the base pose, the fall
  test (:meth:`Rig.fallen`: base below :data:`FALL_HEIGHT` over the ground, or tilted beyond
  :data:`FALL_TILT`) and :meth:`Rig.run` (advance, stop at a fall). A rig advances the
  simulator itself: a fall is a measurement here, not the end of an episode.
- :class:`WalkerRig`: a walking (or jump) controller and the arm posture on the testbed, its
  velocity command settable.
- :class:`WalkingSim` (pushes, hand targets), :class:`JumpSim` (jump commands) and
  :class:`StairsSim` (its own staircase scene, walks with a fall diagnosis).
- :class:`ViewRig`: no episode; a task-6 testbed posed by hand whose head camera renders
  :class:`View` s (the perception benchmark and tests).

Tests and notebooks import rigs from here; the benchmarks that use them are
:mod:`pr2_drake.bench.walking`, ``.whole_body``, ``.jumping`` and ``.stairs``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np
from pydrake.geometry import Box
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.math import SpatialForce
from pydrake.multibody.plant import ExternallyAppliedSpatialForce, MultibodyPlant
from pydrake.systems.framework import DiagramBuilder

from pr2_drake.bench.stair_falls import SNAPSHOTS, Fall, diagnose, snapshot, where
from pr2_drake.controllers.jump_params import JumpParams
from pr2_drake.controllers.jumping import JumpController
from pr2_drake.controllers.posture import ArmPosture
from pr2_drake.controllers.planning.terrain import PatchTerrain
from pr2_drake.controllers.planning.tread_steps import TreadFootstepPlanner
from pr2_drake.controllers.walking import WalkingController
from pr2_drake.controllers.walking_params import WalkingParams
from pr2_drake.camera import CameraSettings
from pr2_drake.episode import Episode
from pr2_drake.ports import EFFORT_LEGS
from pr2_drake.robot.model import BASE_BODY
from pr2_drake.scenario import Scenario
from pr2_drake.scene import GROUND_FRICTION, Scene, StartPose, add_flat_ground
from pr2_drake.tasks.base import FALL_HEIGHT
from pr2_drake.tasks.regions import rgba

FALL_TILT = 0.8  # [rad] base roll or pitch beyond this = fallen
PUSH_POINT_B = np.array([0.0, 0.0, 0.20])  # [m] torso centre in base_link
STAIRS_WALKING = "params/controllers/walking_stairs.yaml"  # walking overrides of the stairs rig
FINITE_LENGTH = 3.0  # [m] boxes drawn for a patch that goes on
PATCH_COLORS = ([0.30, 0.45, 0.75], [0.25, 0.62, 0.68])


class Rig:
    """An episode under test (see the module docstring).

    Args:
        scenario: what to build (no agent: ``wire`` adds the blocks under test).
        wire: ``wire(builder, testbed)``, as for :class:`Episode`.
        scene_builder: a scene instead of the scenario's (a rig's own terrain).
    """

    def __init__(self, scenario: Scenario, wire, meshcat=None,
                 scene_builder: Callable | None = None):
        episode = Episode(scenario, wire, meshcat, scene_builder=scene_builder)
        self.episode, self.testbed = episode, episode.testbed
        self.diagram, self.simulator, self.context = (episode.diagram, episode.simulator,
                                                      episode.context)
        self.plant = self.testbed.plant
        self.plant_context = episode.plant_context
        self.tb_context = episode.tb_context
        self.base = self.plant.GetBodyByName(BASE_BODY, self.testbed.robot)

    @property
    def time(self) -> float:
        return self.context.get_time()

    def advance(self, t: float) -> None:
        """Simulate to ``t`` [s]."""
        self.simulator.AdvanceTo(t)

    def base_pose(self):
        """(p_WB (3), roll, pitch, yaw) of base_link [m, rad]."""
        X = self.plant.EvalBodyPoseInWorld(self.plant_context, self.base)
        rpy = RollPitchYaw(X.rotation())
        return X.translation().copy(), rpy.roll_angle(), rpy.pitch_angle(), rpy.yaw_angle()

    def fallen(self) -> bool:
        """Base below FALL_HEIGHT over the scene's ground, or rolled or pitched beyond
        FALL_TILT."""
        p, roll, pitch, _ = self.base_pose()
        ground = self.testbed.scene.ground_height(p[0], p[1])
        return bool(p[2] - ground < FALL_HEIGHT or abs(roll) > FALL_TILT
                    or abs(pitch) > FALL_TILT)

    def run(self, duration: float, check_every: float = 0.1) -> bool:
        """Advance by ``duration`` s; stop early and return False if the robot falls."""
        end = self.time + duration
        while self.time < end - 1e-9:
            self.advance(min(end, self.time + check_every))
            if self.fallen():
                return False
        return True


class WalkerRig(Rig):
    """The testbed with ``walker`` (a WalkingController or JumpController) on the legs, and
    the arm posture block on the arms, or, with ``walker_arms``, the walker's own arms (its
    QP; its ``pick_state`` from the testbed when ``pick_state_from_testbed``).
    ``add_systems(builder, testbed)`` may add systems before the build."""

    def __init__(self, walker, scenario: Scenario, meshcat=None, walker_arms: bool = False,
                 pick_state_from_testbed: bool = True, add_systems=None, scene_builder=None):
        self.walker = walker
        self.arms = None if walker_arms else ArmPosture(stiffness=walker.params.arm_stiffness,
                                                        damping=walker.params.arm_damping)
        self._pick_state_from_testbed = pick_state_from_testbed
        self._add_systems = add_systems
        super().__init__(scenario, self._wire, meshcat, scene_builder)
        self.walker_context = walker.GetMyMutableContextFromRoot(self.context)
        self.set_command(0.0, 0.0, 0.0)

    def _wire(self, builder: DiagramBuilder, tb) -> None:
        w = self.walker
        builder.AddSystem(w)
        builder.Connect(tb.GetOutputPort("joint_state"), w.GetInputPort("joint_state"))
        builder.Connect(tb.GetOutputPort("body_state"), w.GetInputPort("body_state"))
        builder.Connect(w.GetOutputPort("legs_command"), tb.GetInputPort("legs_command"))
        if self.arms is None:
            builder.Connect(w.GetOutputPort("arms_command"), tb.GetInputPort("arms_command"))
            if self._pick_state_from_testbed and w.HasInputPort("pick_state"):
                builder.Connect(tb.GetOutputPort("pick_state"), w.GetInputPort("pick_state"))
        else:
            builder.AddSystem(self.arms)
            builder.Connect(self.arms.GetOutputPort("arms_command"),
                            tb.GetInputPort("arms_command"))
        if self._add_systems is not None:
            self._add_systems(builder, tb)

    def set_command(self, vx: float, vy: float, yaw_rate: float) -> None:
        """The walker's velocity command (heading frame) [m/s, m/s, rad/s]."""
        self.walker.GetInputPort("velocity_command").FixValue(
            self.walker_context, np.array([vx, vy, yaw_rate], dtype=float))

    def status(self) -> np.ndarray:
        """The walker's ``status`` output (see its ``STATUS_FIELDS``)."""
        return self.walker.GetOutputPort("status").Eval(self.walker_context)


class WalkingSim(WalkerRig):
    """Flat ground + WalkingController + ArmPosture, with a settable command and pushes.

    With ``arms="effort"`` the walking controller's QP drives the arms (no ArmPosture); then
    :meth:`set_hand_targets` sets its ``hand_targets`` input and its ``pick_state`` input
    follows the testbed's. With ``arms="balance"`` the QP drives the arms towards their pose
    only (no hand inputs). ``controller_kwargs`` go to the WalkingController (footsteps,
    terrain). ``add_systems(builder, testbed)`` may add systems before the build.
    """

    def __init__(self, params: WalkingParams | None = None, meshcat=None, arms: str = "position",
                 add_systems=None, pick_state_from_testbed: bool = True, **controller_kwargs):
        walker = WalkingController(params, arms=arms, **controller_kwargs)
        super().__init__(walker, Scenario(seconds=math.inf), meshcat, arms != "position",
                         pick_state_from_testbed, add_systems)
        self._force_port = self.plant.get_applied_spatial_force_input_port()
        if arms == "effort":
            self.set_hand_targets([None, None])
        self.push(None)
        self.simulator.Initialize()

    def set_hand_targets(self, targets) -> None:
        """[left, right] hand targets p_WH [m] (None each: no target); arms="effort" only."""
        self.walker.GetInputPort("hand_targets").FixValue(self.walker_context, list(targets))

    def push(self, force_W: np.ndarray | None, body=None, p_BQ=PUSH_POINT_B) -> None:
        """Apply a constant force [N] (in W) at the torso centre (or at point p_BQ [m] of
        ``body``), or None to stop."""
        forces = []
        if force_W is not None:
            body = self.base if body is None else body
            f = ExternallyAppliedSpatialForce()
            f.body_index = body.index()
            f.p_BoBq_B = np.asarray(p_BQ, dtype=float)
            f.F_Bq_W = SpatialForce(np.zeros(3), np.asarray(force_W, dtype=float))
            forces.append(f)
        self._force_port.FixValue(self.plant_context, forces)


class JumpSim(WalkerRig):
    """Testbed (flat ground or a task) + JumpController + ArmPosture, with settable commands."""

    def __init__(self, params: WalkingParams | None = None,
                 jump_params: JumpParams | None = None, task=None, seed: int = 0, start=None):
        kw = {} if start is None else {"start": start}
        super().__init__(JumpController(params, jump_params),
                         Scenario(task=task, seed=seed, seconds=math.inf, **kw))
        self.soles = [self.plant.GetFrameByName(f"{s}_sole", self.testbed.robot)
                      for s in ("l", "r")]
        self.set_jump(None)
        self.simulator.Initialize()

    def set_jump(self, command) -> None:
        """(t_takeoff, vx, vy, apex) or None (no jump)."""
        c = np.zeros(4) if command is None else np.asarray(command, dtype=float)
        self.walker.GetInputPort("jump_command").FixValue(self.walker_context, c)

    def com(self) -> tuple[np.ndarray, np.ndarray]:
        p = self.plant.CalcCenterOfMassPositionInWorld(self.plant_context)
        v = self.plant.CalcCenterOfMassTranslationalVelocityInWorld(self.plant_context)
        return p, v

    def sole_heights(self) -> np.ndarray:
        """Lowest contact point height of each sole above z = 0 [m]."""
        m = self.walker.core.model
        out = []
        for f in self.soles:
            X = f.CalcPoseInWorld(self.plant_context)
            out.append(float(((X.rotation().matrix() @ m.p_SC)[2] + X.translation()[2]).min()))
        return np.array(out)

    def sole_positions(self) -> list[np.ndarray]:
        return [f.CalcPoseInWorld(self.plant_context).translation().copy() for f in self.soles]

    def leg_torques(self) -> np.ndarray:
        js = self.testbed.GetOutputPort("joint_state").Eval(self.tb_context)
        return np.asarray(js[EFFORT_LEGS], dtype=float)

    def jump_status(self) -> np.ndarray:
        return self.walker.GetOutputPort("jump_status").Eval(self.walker_context)


def add_patch_terrain(plant: MultibodyPlant, terrain: PatchTerrain) -> None:
    """Collision and visual boxes on the world body for the level patches of ``terrain``
    (each a box from z = 0 up to the patch; infinite extents drawn FINITE_LENGTH long): the
    scene of the controller's terrain model."""
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
                                     rgba(PATCH_COLORS[k % len(PATCH_COLORS)]))


class StairsSim(WalkerRig):
    """Its own scene: flat ground, the level patches of a :class:`PatchTerrain` as boxes, and
    obstacle boxes; the walking controller on treads, its QP swinging the arms about their
    pose as in task 5 (``arms="balance"``, walking_stairs.yaml's ``arms.posture``; task 5's
    agent runs ``"effort"``, which adds the hand target for the press).

    Args:
        terrain: the ground (its level patches become boxes).
        footsteps: the footstep planner (None: :class:`TreadFootstepPlanner` on ``terrain``).
        obstacles: :class:`pr2_drake.controllers.planning.step_over.Obstacle` boxes added to the scene
            (not to the terrain model); their geometry ids in ``obstacle_ids``.
        start: the robot's start pose.
        params: walking parameters (None: walking.yaml with walking_stairs.yaml).
        planner_params: :class:`TreadPlannerParams` (None: params/controllers/tread_planner.yaml).
    """

    def __init__(self, terrain: PatchTerrain, start: StartPose | None = None,
                 params: WalkingParams | None = None, planner_params=None, meshcat=None,
                 footsteps=None, obstacles=()):
        self.terrain = terrain
        self.params = params or WalkingParams.load().with_overrides(STAIRS_WALKING)
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

        walker = WalkingController(self.params, footsteps=footsteps, terrain=terrain,
                                   arms="balance")
        super().__init__(walker, Scenario(seconds=math.inf), meshcat, walker_arms=True,
                         scene_builder=scene)
        self.soles = [self.plant.GetFrameByName(n, self.testbed.robot)
                      for n in ("l_sole", "r_sole")]
        self.simulator.Initialize()
        self.fall: Fall | None = None  # the last walk's failure (walk)
        self.snapshots: list = []

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

    def walk(self, speed: float, x_end: float, timeout: float, heading_gain: float = 1.0,
             check_every: float = 0.1, log=None, lane_gain: float = 0.0,
             lane_speed: float = 0.08) -> bool:
        """Walk forward at ``speed`` [m/s] holding heading 0 until the base passes ``x_end``
        [m], then stop and settle 2 s. Returns False on a fall or the timeout (then
        :attr:`fall` says where and why, :func:`pr2_drake.bench.stair_falls.diagnose`).
        ``lane_gain`` [1/s] > 0 also holds the start's y (a sideways command ``lane_gain``
        times the base's y error, at most ``lane_speed`` [m/s], as StepsButtonAgent does).
        ``log(sim)`` is called every ``check_every`` s."""
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
            self.advance(self.time + check_every)
            self.snapshots = self.snapshots[-(SNAPSHOTS - 1):] + [snapshot(self)]
            if log is not None:
                log(self)
            if self.fallen():
                self.fall = diagnose(self)
                return False
            if done:
                self.advance(self.time + 2.0)
                if self.fallen():
                    self.fall = diagnose(self)
                    return False
                return True
        self.fall = Fall(self.time, *where(self.terrain, self.base_pose()[0][0]),
                         "timeout (no fall)")
        return False


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

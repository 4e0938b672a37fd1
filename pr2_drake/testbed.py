"""build_testbed(): the whole testbed as one Drake Diagram with the PR2 port contract.

Inside: MultibodyPlant (discrete SAP) + SceneGraph, the task scene, KUAVO, the actuation adapter,
the grasp system, the head RGB-D camera (optional), the task referee (when a task is given),
the domain randomisation's blocks (when on: :mod:`pr2_drake.randomize_systems`) and,
optionally, a MeshcatVisualizer.

Input ports:  ``arms_command``, ``legs_command`` (JointGroupCommand), ``pick`` (str),
``release`` (bool), ``camera_capture`` (bool, when the camera is on; optional: unconnected,
the camera renders at every sample; False at a sample time: no render, ``rgbd`` keeps the last
frame).
Output ports: ``joint_state`` (54), ``body_state`` (13) (layouts in :mod:`pr2_drake.ports`),
``pick_state`` (PickState), ``plant_state`` (full plant [q; v]), ``contact_results``,
``geometry_query`` (SceneGraph queries, to attach more sensors), ``rgbd`` (RgbdFrame, when
the camera is on), and with a task: ``score`` (1), ``episode``
(EpisodeStatus), ``task_feedback`` (dict), ``instruction`` (str).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable

import numpy as np
from pydrake.geometry import Meshcat, MeshcatVisualizer, MeshcatVisualizerParams, Role, SceneGraph
from pydrake.multibody.plant import (
    AddMultibodyPlant,
    MultibodyPlant,
    MultibodyPlantConfig,
)
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.primitives import MatrixGain, Multiplexer

from pr2_drake.actuation import ActuationAdapter, add_actuation
from pr2_drake.camera import CameraSettings, add_camera_scene_graph, add_head_camera
from pr2_drake.materials import visual_style
from pr2_drake.grasp import GraspSystem
from pr2_drake.randomize import RandomizeSettings
from pr2_drake.randomize_systems import RandomizationBlocks
from pr2_drake.ports import BODY_STATE_SIZE, N_JOINTS
from pr2_drake.robot.model import BASE_BODY, KuavoMaps, add_kuavo, standing_base_pose
from pr2_drake.robot.params import RobotParams, load_robot_params
from pr2_drake.scene import Scene, StartPose, build_flat_scene

CONTACT_APPROXIMATIONS = ("lagged", "sap", "similar", "tamsi")
CONTACT_MODELS = ("point", "hydroelastic_with_fallback", "hydroelastic")
#: [s] physics step of a task whose YAML gives none, and of flat ground (README, "The testbed
#: diagram": 4 ms, the whole-body controllers' period, chosen on the fidelity table and the
#: randomised seeds of docs/benchmarks.md, issue 27; task 6's YAML keeps 2 ms).
DEFAULT_TIME_STEP = 0.004
#: SAP's contact approximation (Drake's ``discrete_contact_approximation``): "similar" keeps
#: every task's outcomes at 2 ms; "lagged", cheaper at 1 ms, lost a jump landing at 2 ms.
DEFAULT_CONTACT_APPROXIMATION = "similar"


@dataclass
class TestbedConfig:
    """How to build the testbed.

    Attributes:
        task: task id (1..6) or name; None for flat ground with no referee.
        seed: episode seed; every random choice (start pose, object placement) flows from it.
        time_step: physics step [s] of the discrete plant; None = the task's (its YAML's
            ``time_step``), else :data:`DEFAULT_TIME_STEP` (4 ms). Resolved on
            construction, so it is a number from then on.
        contact_approximation: SAP variant of MultibodyPlant (default
            :data:`DEFAULT_CONTACT_APPROXIMATION`).
        contact_model: "point" (default; rigid terrain needs no more) or
            "hydroelastic_with_fallback" (costlier; only compliant geometry benefits).
        camera: head RGB-D camera settings; None (default) = the task's choice (its YAML
            ``camera`` block, e.g. on for task 6), off when the task has none.
        start: override the start pose (None: the task's seeded start, or the origin).
        arm_gains, leg_gains: default (stiffness [Nm/rad], damping [Nm s/rad]) of the
            position/velocity modes when a command carries none.
        grasp_period: how often pick/release commands are sampled [s].
        scene_builder: without a task, ``f(plant, rng) -> Scene`` builds the scene instead of
            flat ground (benchmarks with their own terrain, e.g. ``bench stairs``).
        variation: the task's scene drawn from the seed (:meth:`TaskDefinition.varied`).
        randomize: domain randomisation (:mod:`pr2_drake.randomize`): which of its blocks
            are built; None or off = none.
    """

    __test__ = False  # not a pytest test class

    task: int | str | None = None
    seed: int = 0
    time_step: float | None = None
    contact_approximation: str = DEFAULT_CONTACT_APPROXIMATION
    contact_model: str = "point"
    camera: CameraSettings | None = None
    start: StartPose | None = None
    arm_gains: tuple[float, float] = (60.0, 3.0)
    leg_gains: tuple[float, float] = (400.0, 8.0)
    grasp_period: float = 0.01
    scene_builder: Callable[[MultibodyPlant, np.random.Generator], Scene] | None = None
    variation: bool = False
    randomize: RandomizeSettings | None = None

    def __post_init__(self) -> None:
        if self.time_step is None:
            self.time_step = task_time_step(self.task)

    def validate(self) -> None:
        if not (0 < self.time_step <= 0.02):
            raise ValueError(f"time_step must be in (0, 0.02] s, got {self.time_step}")
        if self.contact_approximation not in CONTACT_APPROXIMATIONS:
            raise ValueError(
                f"contact_approximation must be one of {CONTACT_APPROXIMATIONS}, "
                f"got {self.contact_approximation!r}"
            )
        if self.contact_model not in CONTACT_MODELS:
            raise ValueError(
                f"contact_model must be one of {CONTACT_MODELS}, got {self.contact_model!r}"
            )
        for name in ("arm_gains", "leg_gains"):
            k, d = getattr(self, name)
            if k < 0 or d < 0 or not np.isfinite([k, d]).all():
                raise ValueError(f"{name} must be finite and non-negative, got {(k, d)}")
        if self.camera is not None:
            self.camera.validate()


def task_time_step(task: int | str | None) -> float:
    """The physics step [s] a task runs at unless told otherwise (flat ground: the default)."""
    if task is None:
        return DEFAULT_TIME_STEP
    from pr2_drake.tasks import get_task

    step = get_task(task).spec.time_step
    return DEFAULT_TIME_STEP if step is None else float(step)


class Testbed(Diagram):
    """The testbed diagram. Build it with :func:`build_testbed`.

    Attributes:
        config: the configuration it was built from.
        plant: the MultibodyPlant; ``robot`` its KUAVO model instance; ``maps`` index maps.
        scene: the task scene (start pose, priors, graspables).
        task: the task definition, or None.
        meshcat: the Meshcat instance it draws to, or None.
    """

    __test__ = False
    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    def __init__(self, config: TestbedConfig, meshcat: Meshcat | None = None,
                 params: RobotParams | None = None):
        super().__init__()
        config.validate()
        self.config = config
        self.params = params or load_robot_params()
        self.meshcat = meshcat
        self.task = None
        rng = np.random.default_rng(config.seed)

        builder = DiagramBuilder()
        plant_config = MultibodyPlantConfig(
            time_step=config.time_step,
            discrete_contact_approximation=config.contact_approximation,
            penetration_allowance=0.001,
            use_sampled_output_ports=True,
            contact_model=config.contact_model,
        )
        plant, scene_graph = AddMultibodyPlant(plant_config, builder)
        self.plant: MultibodyPlant = plant
        self.scene_graph = scene_graph
        self.camera_scene_graph: SceneGraph | None = None  # with the camera: its own (camera.py)
        self.robot = add_kuavo(plant)

        if config.task is not None:
            from pr2_drake.tasks import get_task

            self.task = get_task(config.task)
            if config.variation:
                self.task = self.task.varied(config.seed)
        self.camera = _resolve_camera(config.camera, self.task)
        # The fast preset draws the scene's boxes as Phong primitives (pr2_drake.materials).
        fast = self.camera.enabled and self.camera.quality == "low"
        with visual_style("phong" if fast else "pbr"):
            if config.task is None:
                build = config.scene_builder or build_flat_scene
                self.scene: Scene = build(plant, rng)
            else:
                self.scene = self.task.build_scene(plant, rng)
        self.randomization = RandomizationBlocks(config.randomize, config.time_step, self.task)
        self.randomization.raise_effort_limits(plant, self.robot)
        _check_pd_support(plant, config.contact_approximation)
        plant.Finalize()
        self.maps = KuavoMaps.from_plant(plant, self.robot)
        self._set_default_pose(config.start or self.scene.start)

        for add_system in self.scene.add_systems:
            add_system(builder, plant)
        self.randomization.add_pushes(builder, self)
        self._add_actuation(builder)
        self._add_observations(builder)
        self._add_grasp(builder)
        if self.camera.enabled:
            self._add_camera(builder)
        if self.task is not None:
            self._add_referee(builder)
        if meshcat is not None:
            MeshcatVisualizer.AddToBuilder(
                builder, scene_graph, meshcat, MeshcatVisualizerParams(role=Role.kIllustration)
            )
        builder.ExportOutput(plant.get_state_output_port(), "plant_state")
        builder.ExportOutput(plant.get_contact_results_output_port(), "contact_results")
        builder.ExportOutput(scene_graph.get_query_output_port(), "geometry_query")
        builder.BuildInto(self)
        self.set_name("testbed")

    def set_start(self, start: StartPose, seed: int) -> None:
        """Move the robot's default start pose (a new default Context starts there) and
        record the seed it was drawn from: a built testbed reused for another seed of a task
        whose seed draws the start pose alone (``TaskDefinition.start_of``)."""
        self.config = replace(self.config, seed=int(seed), start=None)
        self.scene.start = start
        self._set_default_pose(start)

    # -- construction -------------------------------------------------------------------------
    def _set_default_pose(self, start: StartPose) -> None:
        plant, robot = self.plant, self.robot
        joints = np.concatenate(
            [self.params.default_positions("arms"), self.params.default_positions("legs")]
        )
        ground = float(self.scene.ground_height(start.x, start.y))
        X_WB = standing_base_pose(plant, robot, joints, (start.x, start.y), start.yaw, ground)
        plant.SetDefaultFloatingBaseBodyPose(plant.GetBodyByName(BASE_BODY, robot), X_WB)
        for spec, angle in zip(self.params.joints, joints):
            plant.GetJointByName(spec.name, robot).set_default_angle(float(angle))
        self.X_WB_start = X_WB
        self.default_joints = joints

    def _add_actuation(self, builder: DiagramBuilder) -> None:
        plant, maps = self.plant, self.maps
        gains = {"arms": self.config.arm_gains, "legs": self.config.leg_gains}
        adapter = builder.AddNamedSystem(
            "actuation", ActuationAdapter(self.params, maps, gains, self.stable_gain_limits(),
                                          self.randomization.effort_scale)
        )
        dr = self.randomization  # domain randomisation: delay, peak torques (or nothing)
        builder.Connect(plant.get_state_output_port(self.robot), adapter.GetInputPort("robot_state"))
        # The adapter's PortSwitch (C++), then the randomisation's peak torques (or nothing).
        builder.Connect(dr.actuation(builder, add_actuation(builder, adapter), self),
                        plant.get_actuation_input_port(self.robot))
        for name in ("arms_command", "legs_command"):
            builder.ExportInput(dr.command(builder, adapter.GetInputPort(name)), name)
        self._actuation = adapter
        # Applied efforts in the original order: the plant's sampled net actuation of the last
        # step (no direct feedthrough, so joint_state -> controller -> command is no loop).
        n_act = len(maps.actuators)
        P = np.zeros((N_JOINTS, n_act))
        P[np.arange(N_JOINTS), maps.actuators] = 1.0
        to_original = builder.AddNamedSystem("effort_to_original_order", MatrixGain(P))
        builder.Connect(plant.get_net_actuation_output_port(self.robot), to_original.get_input_port())
        self._applied_effort = to_original.get_output_port()

    def _add_observations(self, builder: DiagramBuilder) -> None:
        maps = self.maps
        n_x = maps.nq + maps.nv
        S = np.zeros((2 * N_JOINTS, n_x))
        S[np.arange(N_JOINTS), maps.q_joints] = 1.0
        S[N_JOINTS + np.arange(N_JOINTS), maps.nq + maps.v_joints] = 1.0
        select = builder.AddNamedSystem("joint_select", MatrixGain(S))
        mux = builder.AddNamedSystem("joint_state_mux", Multiplexer([2 * N_JOINTS, N_JOINTS]))
        robot_state = self.plant.get_state_output_port(self.robot)
        builder.Connect(robot_state, select.get_input_port())
        builder.Connect(select.get_output_port(), mux.get_input_port(0))
        builder.Connect(self._applied_effort, mux.get_input_port(1))
        noisy = self.randomization.observation  # domain randomisation's noise (or nothing)
        builder.ExportOutput(noisy(builder, "joint_state", mux.get_output_port()), "joint_state")

        qb, vb = maps.q_base, maps.nq + maps.v_base
        order = [qb[4], qb[5], qb[6], qb[0], qb[1], qb[2], qb[3], vb[3], vb[4], vb[5], vb[0],
                 vb[1], vb[2]]
        B = np.zeros((BODY_STATE_SIZE, n_x))
        B[np.arange(BODY_STATE_SIZE), order] = 1.0
        body = builder.AddNamedSystem("body_select", MatrixGain(B))
        builder.Connect(robot_state, body.get_input_port())
        builder.ExportOutput(noisy(builder, "body_state", body.get_output_port()), "body_state")

    def _add_grasp(self, builder: DiagramBuilder) -> None:
        grasp = builder.AddNamedSystem(
            "grasp",
            GraspSystem(self.plant, self.robot, self.scene.graspables, self.config.grasp_period),
        )
        builder.Connect(self.plant.get_state_output_port(), grasp.GetInputPort("plant_state"))
        if self.scene.graspables:
            builder.Connect(
                grasp.GetOutputPort("spatial_forces"),
                self.plant.get_applied_spatial_force_input_port(),
            )
        builder.ExportInput(grasp.GetInputPort("pick"), "pick")
        builder.ExportInput(grasp.GetInputPort("release"), "release")
        builder.ExportOutput(grasp.GetOutputPort("pick_state"), "pick_state")
        self.grasp = grasp

    def _add_camera(self, builder: DiagramBuilder) -> None:
        frame = self.plant.GetFrameByName("head_camera", self.robot)
        body_frame_id = self.plant.GetBodyFrameIdOrThrow(frame.body().index())
        # The renderer gets a SceneGraph of its own, posed only when a frame renders.
        self.camera_scene_graph, frame_ids = add_camera_scene_graph(
            builder, self.plant, self.scene_graph, extra_frames=(body_frame_id,))
        sampler = add_head_camera(
            builder,
            self.camera_scene_graph,
            frame_ids[body_frame_id],
            frame.GetFixedPoseInBodyFrame(),
            self.camera,
        )
        builder.ExportOutput(sampler.GetOutputPort("rgbd"), "rgbd")
        # Capture on demand: unconnected, every sample renders (RgbdSampler).
        builder.ExportInput(sampler.GetInputPort("capture"), "camera_capture")
        # Depth-only frames on demand: unconnected, every frame has colour.
        builder.ExportInput(sampler.GetInputPort("capture_color"), "camera_capture_color")

    def _add_referee(self, builder: DiagramBuilder) -> None:
        referee = builder.AddNamedSystem(
            "referee", self.task.make_referee(self.plant, self.robot, self.scene)
        )
        builder.Connect(self.plant.get_state_output_port(), referee.GetInputPort("plant_state"))
        builder.Connect(
            self.plant.get_contact_results_output_port(), referee.GetInputPort("contact_results")
        )
        builder.Connect(self.grasp.GetOutputPort("pick_state"), referee.GetInputPort("pick_state"))
        for name in ("score", "episode", "task_feedback", "instruction"):
            builder.ExportOutput(referee.GetOutputPort(name), name)
        self.referee = referee

    def stable_gain_limits(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Per-joint (max stiffness [Nm/rad], max damping [Nm s/rad]) of the explicit
        spring-damper at this time step: I/dt^2 and I/dt, with I the smallest joint-space
        inertia diagonal at the nominal and the zero pose."""
        plant, maps, dt = self.plant, self.maps, self.config.time_step
        ctx = plant.CreateDefaultContext()
        inertia = np.full(N_JOINTS, np.inf)
        v_full = plant.GetVelocitiesFromArray(
            self.robot, np.arange(plant.num_velocities(), dtype=float)
        ).astype(int)
        for joints in (self.default_joints, np.zeros(N_JOINTS)):
            q = plant.GetPositions(ctx, self.robot)
            q[maps.q_joints] = joints
            plant.SetPositions(ctx, self.robot, q)
            diag = np.diag(plant.CalcMassMatrix(ctx))[v_full[maps.v_joints]]
            inertia = np.minimum(inertia, diag)
        n_arms = len(self.params.group("arms"))
        arms, legs = inertia[:n_arms], inertia[n_arms:]
        return {"arms": (arms / dt**2, arms / dt), "legs": (legs / dt**2, legs / dt)}

    def joint_gains(self, context) -> tuple[np.ndarray, np.ndarray]:
        """The spring-damper gains in effect, (stiffness (18) [Nm/rad], damping (18)
        [Nm s/rad]), arms then legs in the original order, in this testbed ``context`` (see
        :meth:`pr2_drake.actuation.ActuationAdapter.gains_in_effect`)."""
        adapter = self._actuation
        return adapter.gains_in_effect(self.GetSubsystemContext(adapter, context))

    # -- conveniences -------------------------------------------------------------------------
    def has_camera(self) -> bool:
        return self.camera.enabled


def _check_pd_support(plant: MultibodyPlant, approximation: str) -> None:
    """Refuse "tamsi" when a joint actuator has PD gains: Drake models those controllers with
    SAP only, and TAMSI leaves such a joint undriven (task 3's bar would never move)."""
    if approximation != "tamsi":
        return
    driven = [plant.get_joint_actuator(i).name() for i in plant.GetJointActuatorIndices()
              if plant.get_joint_actuator(i).has_controller()]
    if driven:
        raise ValueError(
            f"contact_approximation 'tamsi' cannot drive the PD-controlled actuators "
            f"{driven} of this scene (Drake runs PD actuators with SAP only; TAMSI is also "
            f"deprecated in Drake): use 'similar', 'lagged' or 'sap'")


def _resolve_camera(camera: CameraSettings | None, task) -> CameraSettings:
    """The user's camera settings if given, else the task YAML's ``camera`` block, else off."""
    if camera is not None:
        return camera
    if task is None or not task.spec.camera:
        return CameraSettings()
    try:
        settings = CameraSettings(**task.spec.camera)
    except TypeError as e:
        raise ValueError(f"task {task.id}: bad camera block {task.spec.camera}: {e}") from None
    settings.validate()
    return settings


def build_testbed(config: TestbedConfig | None = None, meshcat: Meshcat | None = None) -> Testbed:
    """Build the testbed diagram (see the module docstring for its ports)."""
    return Testbed(config or TestbedConfig(), meshcat)

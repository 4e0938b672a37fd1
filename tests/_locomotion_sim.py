"""Test helpers for the locomotion task tests: a testbed with a switchable test controller, and
ways to put the robot somewhere (teleport) and read the referee's verdict."""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.geometry import SceneGraph
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
from pydrake.systems.framework import DiagramBuilder, LeafSystem

from pr2_drake.controllers.standing import StandingPolicy
from pr2_drake.ports import BODY_STATE_SIZE, JOINT_STATE_SIZE, N_LEGS, JointGroupCommand
from pr2_drake.robot.model import add_kuavo, standing_base_pose
from pr2_drake.scene import StartPose
from pr2_drake.tasks import get_task
from pr2_drake.bench.rigs import Rig
from pr2_drake.episode import wire_system
from pr2_drake.scenario import Scenario


class TestController(LeafSystem):
    """Standing control, with two switches set from the test between AdvanceTo calls:
    ``limp`` (zero leg effort: the robot collapses) and ``arm_targets`` (8 arm joint angles
    [rad] held in position mode instead of the nominal arm pose)."""

    __test__ = False

    __slots__ = ()  # keeps the diagram collectable (pr2_drake.lifetime)

    def __init__(self):
        super().__init__()
        self.policy = StandingPolicy()
        self.limp = False
        self.arm_targets: np.ndarray | None = None
        self._js = self.DeclareVectorInputPort("joint_state", JOINT_STATE_SIZE)
        self._bs = self.DeclareVectorInputPort("body_state", BODY_STATE_SIZE)
        self.DeclareAbstractOutputPort(
            "legs_command", lambda: AbstractValue.Make(JointGroupCommand()), self._legs)
        self.DeclareAbstractOutputPort(
            "arms_command", lambda: AbstractValue.Make(JointGroupCommand()), self._arms)

    def _legs(self, context, output) -> None:
        if self.limp:
            output.set_value(JointGroupCommand.effort(np.zeros(N_LEGS)))
            return
        legs, _ = self.policy.compute(self._js.Eval(context), self._bs.Eval(context))
        output.set_value(legs)

    def _arms(self, context, output) -> None:
        q = self.policy.q_arms_d if self.arm_targets is None else self.arm_targets
        p = self.policy.params
        output.set_value(JointGroupCommand.position(q, p.arm_kp, p.arm_kd))


class TaskSim(Rig):
    """A task testbed driven by :class:`TestController`, ready to simulate."""

    __test__ = False

    def __init__(self, task: int, seed: int = 0, start: StartPose | None = None):
        self.controller = TestController()
        super().__init__(Scenario(task=task, seed=seed, start=start),
                         wire_system(self.controller))
        tb = self.testbed
        tb.GetInputPort("pick").FixValue(self.tb_context, "")
        tb.GetInputPort("release").FixValue(self.tb_context, False)
        self.tb_ctx, self.plant_ctx = self.tb_context, self.plant_context
        self.robot = tb.robot
        self.scene = tb.scene
        self.spec = tb.task.spec
        self.simulator.Initialize()

    def advance_by(self, dt: float) -> None:
        self.advance(self.time + dt)

    def advance_to(self, t: float) -> None:
        self.advance(t)

    def verdict(self):
        """The referee's verdict (:class:`pr2_drake.tasks.base.EpisodeStatus`)."""
        return self.testbed.GetOutputPort("episode").Eval(self.tb_ctx)

    def items(self) -> list[str]:
        return [e.item for e in self.verdict().items]

    def feedback(self) -> dict:
        return self.testbed.GetOutputPort("task_feedback").Eval(self.tb_ctx)

    def standing_pose(self, x: float, y: float, yaw: float = 0.0, ground: float | None = None,
                      lift: float = 0.0) -> RigidTransform:
        """X_WB of the nominal standing pose with the lower sole ``lift`` above ``ground``
        (default: the scene's ground height under the base)."""
        if ground is None:
            ground = float(self.scene.ground_height(x, y))
        return standing_base_pose(self.plant, self.robot, self.testbed.default_joints, (x, y),
                                  yaw, ground + lift)

    def teleport(self, X_WB: RigidTransform, joints: bool = True) -> None:
        """Put the base at X_WB with zero velocity (and, by default, the nominal joint pose).

        The plant's output ports are sampled (they report the last step), so the contact
        results lag a teleport by one plant step: teleport between referee ticks (e.g. at
        t = 0.105 s, ticks every 10 ms) so that the referee sees consistent contacts.
        """
        plant, ctx = self.plant, self.plant_ctx
        if joints:
            for spec, angle in zip(self.testbed.params.joints, self.testbed.default_joints):
                plant.GetJointByName(spec.name, self.robot).set_angle(ctx, float(angle))
        plant.SetFreeBodyPose(ctx, self.base, X_WB)
        v = plant.GetVelocities(ctx, self.robot)
        plant.SetVelocities(ctx, self.robot, np.zeros_like(v))

    def stand_at(self, x: float, y: float, yaw: float = 0.0, **kw) -> None:
        self.teleport(self.standing_pose(x, y, yaw, **kw))

    def base_position(self) -> np.ndarray:
        return self.plant.EvalBodyPoseInWorld(self.plant_ctx, self.base).translation()

    def frame_position(self, name: str) -> np.ndarray:
        return self.plant.GetFrameByName(name, self.robot).CalcPoseInWorld(
            self.plant_ctx).translation()


def scene_geometry(task: int, seed: int):
    """Build only the task scene (no testbed) on a fresh plant + scene graph.

    Returns (task definition, scene, plant, scene_graph, diagram, diagram context).
    """
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, 0.001)
    add_kuavo(plant)
    task_def = get_task(task)
    scene = task_def.build_scene(plant, np.random.default_rng(seed))
    plant.Finalize()
    diagram = builder.Build()
    return task_def, scene, plant, scene_graph, diagram, diagram.CreateDefaultContext()


def world_geometry_poses(plant, scene_graph: SceneGraph) -> list[tuple[str, np.ndarray]]:
    """(name, X_WG as a 4x4) of every collision geometry on the world body, sorted by name."""
    inspector = scene_graph.model_inspector()
    out = []
    for gid in plant.GetCollisionGeometriesForBody(plant.world_body()):
        out.append((inspector.GetName(gid), inspector.GetPoseInFrame(gid).GetAsMatrix4()))
    return sorted(out, key=lambda e: e[0])


def min_distance_to_terrain(plant, scene_graph, diagram, context, p_W, body=None) -> float:
    """Smallest signed distance [m] from point p_W to the collision geometries of ``body``
    (default: the world body, i.e. the terrain)."""
    sg_ctx = scene_graph.GetMyContextFromRoot(context)
    query = scene_graph.get_query_output_port().Eval(sg_ctx)
    world_ids = set(plant.GetCollisionGeometriesForBody(body or plant.world_body()))
    results = query.ComputeSignedDistanceToPoint(np.asarray(p_W, float), threshold=1.0)
    return min(r.distance for r in results if r.id_G in world_ids)


def roll_about_sole(X_WB: RigidTransform, p_W_pivot: np.ndarray, angle: float) -> RigidTransform:
    """X_WB rotated by ``angle`` [rad] about the world x-axis through ``p_W_pivot``."""
    R = RigidTransform(RollPitchYaw(angle, 0, 0), [0, 0, 0])
    T = RigidTransform(p_W_pivot)
    return T @ R @ T.inverse() @ X_WB


def assert_starts_in_region(spec, n_seeds: int = 100) -> list[StartPose]:
    """Draw ``n_seeds`` starts: each inside the start rectangle, its heading within the task's
    noise of nominal (exactly nominal when the task has none), all distinct. Returns them."""
    cx, cy = spec.start_region["center"]
    dx, dy = spec.start_region["size"]
    starts = [spec.sample_start(np.random.default_rng(s)) for s in range(n_seeds)]
    for s in starts:
        assert abs(s.x - cx) <= dx / 2 and abs(s.y - cy) <= dy / 2
        offset = np.degrees(s.yaw) - spec.nominal_heading_deg
        if spec.heading_noise_deg == 0:
            assert s.yaw == np.radians(spec.nominal_heading_deg)
        else:
            assert abs(offset) <= spec.heading_noise_deg + 1e-9
    assert len({(s.x, s.y) for s in starts}) == n_seeds
    return starts

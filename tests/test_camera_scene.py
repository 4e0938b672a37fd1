"""The camera's own SceneGraph (pr2_drake.camera.add_camera_scene_graph): a copy of the plant's
perception geometry, posed from the plant when, and only when, a frame is rendered."""

import math

import numpy as np
import pytest
from pydrake.geometry import Role
from pydrake.math import RigidTransform
from pydrake.systems.analysis import Simulator

from pr2_drake.bench.rigs import ViewRig
from pr2_drake.camera import CameraScenePoses, CameraSettings, RENDERER_NAME
from pr2_drake.testbed import Testbed, TestbedConfig


@pytest.fixture(scope="module")
def rig():
    return ViewRig(width=64, height=48)


def test_camera_scene_graph_copies_the_perception_geometry(rig):
    plant_sg, camera_sg = rig.tb.scene_graph, rig.tb.camera_scene_graph
    plant_inspector, camera_inspector = plant_sg.model_inspector(), camera_sg.model_inspector()

    def names(inspector, role):
        return sorted(inspector.GetName(g) for g in inspector.GetAllGeometryIds(role))

    assert names(camera_inspector, Role.kPerception) == names(plant_inspector, Role.kPerception)
    assert len(names(camera_inspector, Role.kPerception)) > 50
    # Perception only: no contact, nothing drawn in Meshcat twice.
    assert camera_inspector.NumGeometriesWithRole(Role.kProximity) == 0
    assert camera_inspector.NumGeometriesWithRole(Role.kIllustration) == 0
    # The renderer sits in the camera's SceneGraph alone: the plant's pushes no pose into VTK.
    assert camera_sg.HasRenderer(RENDERER_NAME)
    assert not plant_sg.HasRenderer(RENDERER_NAME)


def test_the_camera_sees_an_object_where_the_plant_put_it(rig):
    """An object moved in the plant's context shows in the next render, at its depth."""
    rig.pose_robot(2.0, 2.0, math.pi / 2)  # in the study, facing the desk 2 m away
    X_WC = rig.sensor_pose()
    _, before = rig.render()
    assert before[24, 32] > 1.0
    for distance in (0.4, 0.6):
        # The cube (5 cm) this far along the optical axis (+z of the camera frame).
        rig.set_object("cube", RigidTransform(X_WC.multiply(np.array([0.0, 0.0, distance]))))
        _, after = rig.render()
        assert distance - 0.04 < after[24, 32] < distance  # its near face


def test_camera_scene_is_posed_only_when_a_frame_is_rendered(monkeypatch):
    calls = []
    calc = CameraScenePoses._calc

    def counted(self, context, output):
        calls.append(context.get_time())
        calc(self, context, output)

    monkeypatch.setattr(CameraScenePoses, "_calc", counted)
    camera = CameraSettings(enabled=True, width=32, height=24, fps=10.0)
    tb = Testbed(TestbedConfig(task=6, seed=0, camera=camera))
    sim = Simulator(tb)
    ctx = sim.get_mutable_context()
    tb.GetInputPort("camera_capture").FixValue(ctx, False)
    sim.Initialize()
    assert calls == [0.0]  # the initialization frame
    sim.AdvanceTo(0.25)  # 250 physics steps, samples at 0.1 and 0.2 declined
    assert calls == [0.0]
    tb.GetInputPort("camera_capture").FixValue(ctx, True)
    sim.AdvanceTo(0.45)
    assert calls == pytest.approx([0.0, 0.3, 0.4])

"""Pictures of the testbed: an overview camera anywhere in the world, next to the head camera."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from pydrake.geometry import (
    ClippingRange,
    ColorRenderCamera,
    DepthRange,
    DepthRenderCamera,
    MakeRenderEngineVtk,
    RenderCameraCore,
)

from pydrake.math import RigidTransform, RotationMatrix
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.sensors import CameraInfo, RgbdSensor

from pr2_drake.camera import CameraSettings, renderer_params
from pr2_drake.testbed import Testbed, TestbedConfig

OVERVIEW_RENDERER = "pr2_vtk_overview"


def look_at(p_WEye: np.ndarray, p_WTarget: np.ndarray) -> RigidTransform:
    """X_WC of a camera at ``p_WEye`` looking at ``p_WTarget`` (Drake convention: +z along the
    optical axis, +y down in the image), with world +z up in the image."""
    z = np.asarray(p_WTarget, float) - np.asarray(p_WEye, float)
    z /= np.linalg.norm(z)
    up = np.array([0.0, 0.0, 1.0])
    x = np.cross(z, up)
    if np.linalg.norm(x) < 1e-6:  # looking straight down: image up = world +x
        x = np.cross(z, np.array([1.0, 0.0, 0.0]))
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return RigidTransform(RotationMatrix(np.column_stack([x, y, z])), p_WEye)


def default_overview_pose(testbed: Testbed) -> RigidTransform:
    """A camera above and behind the robot's start that sees the task's arena."""
    return look_at(*overview_eye_target(testbed))


def overview_eye_target(testbed: Testbed) -> tuple[np.ndarray, np.ndarray]:
    """(eye, target) in world [m] of a view that frames the task's arena and the robot."""
    start = testbed.X_WB_start.translation()
    arena = testbed.task.spec.arena if testbed.task is not None else {}
    if arena:
        lo, hi = np.array(arena["min"], float), np.array(arena["max"], float)
        centre = np.append((lo + hi) / 2, 0.3)
        size = float(np.max(hi - lo))
    else:
        centre, size = start * np.array([1, 1, 0]) + [0, 0, 0.5], 3.0
    eye = centre + np.array([-0.55 * size, -0.65 * size, 0.6 * size + 1.0])
    return eye, centre


def render_task_views(config: TestbedConfig, X_WC: RigidTransform | None = None,
                      size: tuple[int, int] = (640, 480),
                      fov_y_deg: float = 55.0) -> tuple[np.ndarray, np.ndarray]:
    """Render (overview colour, head-camera colour) of a testbed at its start state.

    Args:
        config: the testbed to show (its camera is turned on at ``size``).
        X_WC: overview camera pose; None = :func:`default_overview_pose`.
    """
    width, height = size
    head = config.camera or CameraSettings()
    config = replace(config, camera=replace(head, enabled=True, width=width, height=height))
    builder = DiagramBuilder()
    testbed = builder.AddSystem(Testbed(config))
    X = X_WC or default_overview_pose(testbed)
    # The overview gets its own renderer: two cameras sharing one VTK engine corrupt each
    # other's shadow maps (whole rooms drawn black).
    scene_graph = testbed.scene_graph
    if not scene_graph.HasRenderer(OVERVIEW_RENDERER):
        scene_graph.AddRenderer(OVERVIEW_RENDERER,
                                MakeRenderEngineVtk(renderer_params(config.camera.quality)))
    core = RenderCameraCore(OVERVIEW_RENDERER, CameraInfo(width, height, np.radians(fov_y_deg)),
                            ClippingRange(0.05, 100.0), RigidTransform())
    sensor = builder.AddSystem(RgbdSensor(
        testbed.scene_graph.world_frame_id(), X, ColorRenderCamera(core, False),
        DepthRenderCamera(core, DepthRange(0.1, 90.0)),
    ))
    builder.Connect(testbed.GetOutputPort("geometry_query"), sensor.query_object_input_port())
    diagram = builder.Build()
    simulator = Simulator(diagram)
    simulator.Initialize()
    ctx = simulator.get_context()
    overview = sensor.color_image_output_port().Eval(sensor.GetMyContextFromRoot(ctx))
    head_frame = testbed.GetOutputPort("rgbd").Eval(testbed.GetMyContextFromRoot(ctx))
    return overview.data[:, :, :3].copy(), head_frame.color

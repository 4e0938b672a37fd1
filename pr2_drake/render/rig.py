"""The render rig: a scenario's testbed, posed from a recorded plant state, seen by the
path tracer and by Drake's VTK raster from the same camera.

The rig's testbed is built from the episode's own :class:`TestbedConfig` (same task, seed and
start, so the same geometry), with the visuals of the raster preset asked for (the textured
PBR visuals, or ``low``'s flat ones) whatever the episode's camera preset. Colour, depth and
label images of the raster come from an extra VTK renderer in its SceneGraph
(:meth:`RenderRig.raster`); depth and labels are the simulator's own, exact.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from pydrake.geometry import (ClippingRange, ColorRenderCamera, DepthRange, DepthRenderCamera,
                              MakeRenderEngineVtk, RenderCameraCore)
from pydrake.math import RigidTransform
from pydrake.systems.sensors import CameraInfo

from pr2_drake.camera import CameraSettings, renderer_params
from pr2_drake.render.view import CameraView, look_at_matrix
from pr2_drake.testbed import Testbed, TestbedConfig

RASTER_RENDERER = "pr2_render_raster"
HEAD_CAMERA_FRAME = "head_camera"  # the plant frame of the head camera (Drake convention)
Z_NEAR, Z_FAR = 0.05, 100.0  # [m] depth range of the rig's raster camera
FOLLOW_DISTANCE = 3.2  # [m] from the follow camera to the robot's base
FOLLOW_ELEVATION_DEG = 22.0  # of the follow camera above the base, seen from the base
FOLLOW_AIM_HEIGHT = 0.75  # [m] above the ground where the follow camera aims (the waist)


@dataclass
class RasterImages:
    """The VTK raster of one view: colour (H, W, 3) uint8, depth (H, W) float32 [m] (inf
    beyond the range, 0 nearer than it), labels (H, W) int16 (Drake's RenderLabel values)."""

    color: np.ndarray
    depth: np.ndarray
    label: np.ndarray


class RenderRig:
    """A testbed of ``config`` to pose and render.

    Args:
        config: the episode's testbed configuration (task, seed, start, plant settings).
        quality: the VTK preset of :meth:`raster` (``low``, ``medium``, ``high``).
    """

    def __init__(self, config: TestbedConfig, quality: str = "high"):
        # The testbed draws the fast preset's flat visuals only with its camera on (it is
        # never rendered here: nothing evaluates its port).
        camera = replace(config.camera or CameraSettings(), enabled=quality == "low",
                         quality=quality)
        self.testbed = Testbed(replace(config, camera=camera))
        self.head_settings = _head_settings(config)
        self.scene_graph = self.testbed.scene_graph
        self.scene_graph.AddRenderer(RASTER_RENDERER,
                                     MakeRenderEngineVtk(renderer_params(quality)))
        self.plant = self.testbed.plant
        self.context = self.testbed.CreateDefaultContext()
        self.plant_context = self.plant.GetMyMutableContextFromRoot(self.context)
        self.sg_context = self.scene_graph.GetMyContextFromRoot(self.context)
        self._head = self.plant.GetFrameByName(HEAD_CAMERA_FRAME, self.testbed.robot)
        self._start_yaw = float(self.testbed.config.start.yaw if self.testbed.config.start
                                else self.testbed.scene.start.yaw)

    def set_state(self, x: np.ndarray) -> None:
        """Pose the plant: its full state [q; v] (the testbed's ``plant_state``)."""
        self.plant.SetPositionsAndVelocities(self.plant_context, np.asarray(x, float))

    # -- views ----------------------------------------------------------------------------------
    def head_view(self, width: int, height: int) -> CameraView:
        """The head camera at the current state (the episode's field of view)."""
        X_WC = self._head.CalcPoseInWorld(self.plant_context).GetAsMatrix4()
        return CameraView(X_WC, width, height, self.head_settings.fov_y_deg)

    def follow_target(self) -> np.ndarray:
        """Where the follow camera aims: above the robot's base, at waist height over the
        ground beneath it [m, world]."""
        p = self.plant.GetBodyByName("base_link", self.testbed.robot).EvalPoseInWorld(
            self.plant_context).translation()
        ground = float(self.testbed.scene.ground_height(p[0], p[1]))
        return np.array([p[0], p[1], ground + FOLLOW_AIM_HEIGHT])

    def follow_view(self, width: int, height: int, target=None, fov_y_deg: float = 45.0
                    ) -> CameraView:
        """A third-person camera behind the robot's start heading, to its left, looking down
        at ``target`` (default :meth:`follow_target`) from :data:`FOLLOW_DISTANCE`."""
        target = self.follow_target() if target is None else np.asarray(target, float)
        yaw = self._start_yaw - np.radians(35.0)  # behind and to the left of the start heading
        el = np.radians(FOLLOW_ELEVATION_DEG)
        offset = FOLLOW_DISTANCE * np.array([-np.cos(el) * np.cos(yaw),
                                             -np.cos(el) * np.sin(yaw), np.sin(el)])
        return CameraView(look_at_matrix(target + offset, target), width, height, fov_y_deg)

    # -- the raster -----------------------------------------------------------------------------
    def raster(self, view: CameraView) -> RasterImages:
        """Colour, depth and labels of ``view`` from Drake's VTK renderer."""
        core = RenderCameraCore(RASTER_RENDERER,
                                CameraInfo(view.width, view.height, np.radians(view.fov_y_deg)),
                                ClippingRange(0.5 * Z_NEAR, 2.0 * Z_FAR), RigidTransform())
        query = self.scene_graph.get_query_output_port().Eval(self.sg_context)
        world = self.scene_graph.model_inspector().world_frame_id()
        X_WC = RigidTransform(np.asarray(view.X_WC))
        color = query.RenderColorImage(ColorRenderCamera(core, False), world, X_WC)
        depth = query.RenderDepthImage(DepthRenderCamera(core, DepthRange(Z_NEAR, Z_FAR)),
                                       world, X_WC)
        label = query.RenderLabelImage(ColorRenderCamera(core, False), world, X_WC)
        return RasterImages(color.data[:, :, :3].copy(), depth.data[:, :, 0].copy(),
                            label.data[:, :, 0].copy())

    def object_labels(self) -> dict[str, int]:
        """{name: RenderLabel value} of the scene's graspable objects (the label the plant
        gives the geometry of each object's body), for per-object masks."""
        inspector = self.scene_graph.model_inspector()
        out = {}
        for g in self.testbed.scene.graspables:
            body = self.plant.get_body(g.body)
            for gid in self.plant.GetVisualGeometriesForBody(body):
                props = inspector.GetPerceptionProperties(gid)
                if props is not None and props.HasProperty("label", "id"):
                    out[g.name] = int(props.GetProperty("label", "id"))
        return out


def _head_settings(config: TestbedConfig) -> CameraSettings:
    """The head camera the episode has (its scenario's, else its task's YAML block)."""
    if config.camera is not None:
        return config.camera
    if config.task is None:
        return CameraSettings()
    from pr2_drake.tasks import get_task

    block = dict(get_task(config.task).spec.camera)
    return CameraSettings(**block)

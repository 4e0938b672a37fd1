"""The head RGB-D camera: a Drake RgbdSensor on RenderEngineVtk, sampled at its own rate.

The renderer lives in a SceneGraph of its own (:func:`add_camera_scene_graph`): a copy of the
perception geometry whose frame poses are computed only when a frame is rendered. In the
plant's SceneGraph a renderer would have every geometry pose pushed into VTK at every physics
step (0.25-0.35 CPU s per simulated s measured on Task 6, standing, with no frame rendered;
docs/benchmarks.md).
"""


import math
import numbers
from dataclasses import dataclass, field

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.geometry import (
    ClippingRange,
    ColorRenderCamera,
    DepthRange,
    DepthRenderCamera,
    FramePoseVector,
    GeometryFrame,
    GeometryInstance,
    LightParameter,
    MakeRenderEngineVtk,
    RenderCameraCore,
    RenderEngineVtkParams,
    Rgba,
    Role,
    SceneGraph,
)
from pydrake.math import RigidTransform
from pydrake.systems.framework import DiagramBuilder, LeafSystem
from pydrake.systems.sensors import CameraInfo, ImageDepth32F, ImageRgba8U, RgbdSensor

from pr2_drake.lifetime import weak_calc

RENDERER_NAME = "pr2_vtk"
QUALITIES = ("low", "medium", "high")


@dataclass
class CameraSettings:
    """Head camera settings.

    Attributes:
        enabled: add the camera (tasks that need no camera leave it off: it costs time).
        width, height: image size in pixels, from 8x8 to 3840x2160 (4K UHD).
        fps: frames per second in simulated time, at most 1000; the sensor renders only at
            this rate.
        fov_y_deg: vertical field of view [deg].
        quality: "low" (flat colours, no shadows, 4 fill lights), "medium" (PBR materials,
            sun shadows, 4 sky lights and a ground bounce), "high" (as medium, larger shadow
            map, ambient occlusion, tone mapping). Sky lights are sampled from
            the sky map by median cut (:func:`environment_lights`).
            Lower quality renders faster; see :data:`PRESETS`.
        z_near, z_far: depth range [m]; depth outside it reads inf (too far) or 0 (too near).
    """

    enabled: bool = False
    width: int = 640
    height: int = 480
    fps: float = 10.0
    fov_y_deg: float = 60.0
    quality: str = "low"
    z_near: float = 0.05
    z_far: float = 30.0

    def validate(self) -> None:
        """Raise ValueError naming the first bad field (``camera.<field>``) and its bounds:
        width in [8, 3840] and height in [8, 2160] pixels (integers; 3840x2160, 4K UHD, is the
        largest resolution supported), 0 < fps <= 1000 per simulated second, quality one of
        :data:`QUALITIES`, 0 < fov_y_deg < 170, finite 0 < z_near < z_far."""
        if not isinstance(self.enabled, (bool, np.bool_)):
            raise ValueError(f"camera.enabled must be a bool, got {self.enabled!r}")
        if not isinstance(self.quality, str) or self.quality not in QUALITIES:
            raise ValueError(f"camera.quality must be one of {QUALITIES}, got {self.quality!r}")
        for name, upper in (("width", MAX_WIDTH), ("height", MAX_HEIGHT)):
            value = getattr(self, name)
            if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
                raise ValueError(f"camera.{name} must be an integer number of pixels, "
                                 f"got {value!r}")
            if not MIN_SIZE <= value <= upper:
                raise ValueError(
                    f"camera.{name} must be in [{MIN_SIZE}, {upper}] pixels (images from "
                    f"{MIN_SIZE}x{MIN_SIZE} to {MAX_WIDTH}x{MAX_HEIGHT}), got {value}")
        _real_in("fps", self.fps, 0.0, MAX_FPS, "frames per simulated second", upper_open=False)
        _real_in("fov_y_deg", self.fov_y_deg, 0.0, 170.0, "deg")
        _real_in("z_near", self.z_near, 0.0, math.inf, "m")
        _real_in("z_far", self.z_far, 0.0, math.inf, "m")
        if not self.z_near < self.z_far:
            raise ValueError(f"camera.z_near must be below camera.z_far, got z_near "
                             f"{self.z_near} m, z_far {self.z_far} m")


MIN_SIZE = 8
MAX_WIDTH, MAX_HEIGHT = 3840, 2160  # 4K UHD
MAX_FPS = 1000.0  # 1 kHz, the default physics rate: far beyond any real camera's frame rate


def _real_in(name: str, value, lower: float, upper: float, unit: str,
             upper_open: bool = True) -> None:
    """Raise ValueError unless ``value`` is a finite real number with lower < value < upper
    (value <= upper when not ``upper_open``)."""
    ok = (isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))
          and math.isfinite(value) and lower < value
          and (value < upper if upper_open else value <= upper))
    if not ok:
        bound = "" if math.isinf(upper) else (f" {'<' if upper_open else '<='} {upper:g}")
        raise ValueError(f"camera.{name} must be a finite number with {lower:g} < {name}{bound} "
                         f"[{unit}], got {value!r}")


@dataclass
class RgbdFrame:
    """One camera frame: colour HxWx3 uint8 and distance to the image plane HxW float32 [m].

    ``time``: the simulated time at which it was rendered [s] (a sampler that captures on
    demand keeps its last frame, so a consumer can tell how old it is; 0 for a blank frame)."""

    color: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 3), np.uint8))
    depth: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), np.float32))
    time: float = 0.0

    def __deepcopy__(self, memo) -> "RgbdFrame":
        return RgbdFrame(self.color.copy(), self.depth.copy(), float(self.time))


# The sun: the one light that casts shadows, from the south-west, 50 deg above the horizon (the
# sky texture's sun disc sits in the same direction).
SUN_DIRECTION = (0.53, 0.36, -0.77)  # direction the light travels, world frame


@dataclass(frozen=True)
class RenderPreset:
    """What a quality level turns on (see :func:`renderer_params`).

    Attributes:
        shadows: the sun casts shadows (one shadow map of ``shadow_map_size`` texels).
        ssao: screen-space ambient occlusion (``ssao_samples`` samples within
            ``ssao_radius`` [m]; VTK's default of 128 samples costs three times the frame).
        exposure: tone-mapping exposure (None: no tone mapping).
        sun: luminance of the sun (directional), the one light that casts shadows; its
            colour, like the sky's, is white balanced (:func:`environment_lights`; not at
            ``low``).
        sky: total luminance of the sky lights: ``sky_lights`` lights median-cut from the
            upper half of the generated sky map ``models/textures/sky.png``, its sun disc masked
            out (:mod:`pr2_drake.environment_light`); each light carries its region's share of
            this total, in its region's colour.
        bounce: luminance of the ground's bounce light: the map's lower half (a uniform warm
            grey ground) as one light from straight below, in its colour (0 = none). The map
            gives the ground 0.22 of the sky's energy; the presets use less (``bounce`` is
            about a tenth of ``sky``), as the old hand-placed bounce light did.
            With ``sky_lights`` 0 (``low``): the intensity of each of four white fill lights
            (:func:`_fill_lights`), no sampling and no white balance.
        sky_lights: number of sky lights, a power of two, or 0 for ``low``'s fixed fill
            lights (the old look: with the map's blue sky light alone, walls facing away from
            the sun turned deep blue, and the task-6 detector's colour scores fell from about
            0.6 to 0.4, so that a seed it solved timed out). Each light costs per-pixel shading
            under software rendering: at ``high``, 640x480, about 15-20 CPU ms a frame per
            sky light (16 took 430-470 CPU ms a frame against 280-300 with the five
            hand-placed lights before them, too slow for 5 fps; 8 gave 5.0-5.4 fps on two
            idle cores, at the target's edge; 4, as at ``medium``, 5.7-6.3 against 5.0-6.2 for
            the five before them, and look the same; docs/benchmarks.md).
        environment_map: Drake's own image-based lighting from ``models/textures/sky.png``
            (prefiltered diffuse and specular, so metallic surfaces reflect the sky). Off in
            every preset: VTK prefilters the map (irradiance, specular and BRDF tables of fixed
            size, whatever the map's size) when the first image is rendered, measured 57 s
            (64x32 map) to 250 CPU s under software (llvmpipe) rendering.
    """

    shadows: bool
    shadow_map_size: int
    ssao: bool
    exposure: float | None
    sun: float
    sky: float
    bounce: float
    sky_lights: int = 4
    environment_map: bool = False
    ssao_samples: int = 16
    ssao_radius: float = 0.25


PRESETS = {
    "low": RenderPreset(False, 256, False, None, sun=0.85, sky=0.3, bounce=0.0, sky_lights=0),
    "medium": RenderPreset(True, 2048, False, None, sun=1.4, sky=2.75, bounce=0.25,
                           sky_lights=4),
    "high": RenderPreset(True, 4096, True, 1.0, sun=1.6, sky=2.75, bounce=0.25, sky_lights=4),
}
SKY_DISTANCE = 60.0  # [m] of the sky point lights from the world origin
# ``low``'s fixed fill lights (sky_lights 0): (azimuth, elevation) [deg], white.
FILL_DIRECTIONS = ((45, 27), (135, 27), (225, 27), (315, 27))
SUN_COLOR = (1.0, 0.97, 0.9)  # before white balance


def _white_balance(preset: RenderPreset, sampled) -> np.ndarray:
    """RGB gains (luminance 1) that make the sun, sky and bounce together light an upward
    white surface neutral grey, as a camera's white balance would; the sky's blue is then
    seen in shade only. ``sampled``: (EnvironmentLight, luminance) pairs."""
    from pr2_drake.environment_light import LUMA

    sun = np.asarray(SUN_COLOR)
    rgb = preset.sun * sun / float(sun @ LUMA) * max(0.0, -SUN_DIRECTION[2])
    for light, luminance in sampled:
        c = np.asarray(light.color)
        rgb = rgb + luminance * c / float(c @ LUMA) * max(0.0, -light.direction[2])
    return rgb / float(rgb @ LUMA)


def _fill_lights(preset: RenderPreset) -> list[LightParameter]:
    """The sun and four white directional fill lights of intensity ``preset.sky`` from
    :data:`FILL_DIRECTIONS`: the fast preset's light (flat colours whatever a surface faces;
    the look the task-6 detector's colour models were tuned on)."""
    lights = [LightParameter(type="directional", frame="world", direction=list(SUN_DIRECTION),
                             intensity=preset.sun, color=Rgba(*SUN_COLOR))]
    for az, el in FILL_DIRECTIONS:
        a, e = np.radians(az), np.radians(el)
        lights.append(LightParameter(
            type="directional", frame="world", intensity=preset.sky,
            direction=[-np.cos(e) * np.cos(a), -np.cos(e) * np.sin(a), -np.sin(e)]))
    return lights


def environment_lights(quality: str) -> list[LightParameter]:
    """The sun (first, directional, the one light that casts shadows), then the sky and
    ground-bounce lights of a preset (see :class:`RenderPreset`), sampled from
    ``models/textures/sky.png`` by median cut (cached: the cut runs once per map and count).
    Each light emits its share of the preset's luminance (its intensity is divided by its
    colour's luminance); colours are white balanced (:func:`_white_balance`). With shadows on
    they are point lights :data:`SKY_DISTANCE` from the origin (Drake's VTK engine gives point
    lights no shadow maps; with the default attenuation they do not fall off with distance),
    so the sun makes the only shadow; without, directional lights. ``sky_lights`` 0
    (``low``): the sun and fixed white fill lights instead (:func:`_fill_lights`)."""
    from pr2_drake.environment_light import LUMA, ground_light, sky_lights
    from pr2_drake.paths import data_path

    preset = PRESETS[quality]
    if preset.sky_lights == 0:
        return _fill_lights(preset)
    path = data_path("models", "textures", "sky.png")
    sampled = [(light, preset.sky * light.intensity)
               for light in sky_lights(path, preset.sky_lights, SUN_DIRECTION)]
    if preset.bounce > 0:
        sampled.append((ground_light(path), preset.bounce))
    gains = _white_balance(preset, sampled)
    sun = np.asarray(SUN_COLOR) / gains
    lights = [LightParameter(type="directional", frame="world", direction=list(SUN_DIRECTION),
                             intensity=preset.sun * float(np.asarray(SUN_COLOR) @ LUMA)
                             / float(sun / sun.max() @ LUMA),
                             color=Rgba(*(sun / sun.max())))]
    for light, luminance in sampled:
        c = np.asarray(light.color) / gains
        c = c / c.max()
        color, intensity = Rgba(*c), luminance / float(c @ LUMA)
        if preset.shadows:  # point lights: no shadow maps
            position = [-SKY_DISTANCE * v for v in light.direction]
            lights.append(LightParameter(type="point", frame="world", position=position,
                                         intensity=intensity, color=color))
        else:
            lights.append(LightParameter(type="directional", frame="world",
                                         direction=list(light.direction),
                                         intensity=intensity, color=color))
    return lights


def renderer_params(quality: str) -> RenderEngineVtkParams:
    """VTK render settings for a quality level (see :class:`CameraSettings`, :data:`PRESETS`).

    Scenes use glTF PBR materials (:mod:`pr2_drake.materials`), so VTK shades physically
    based. Light: one sun, the only light that casts shadows, and diffuse image-based lighting
    from the generated sky map by median-cut light sampling (:func:`environment_lights`: 4
    sky lights and a ground bounce, colours and directions from the map). This is not
    full image-based lighting: there are no prefiltered specular reflections of the sky on
    metallic surfaces (Drake's ``environment_map``, :class:`RenderPreset`, does that but
    costs minutes of prefiltering under software rendering; off). ``low``: no shadows
    (fastest), four fixed white directional fill lights. ``medium``: sun shadows, the four
    sky lights and the ground bounce. ``high``: as medium, a larger shadow map, ambient
    occlusion and filmic tone mapping.
    """
    preset = PRESETS[quality]
    params = RenderEngineVtkParams()
    params.default_clear_color = [0.62, 0.75, 0.92]
    lights = environment_lights(quality)
    params.lights = lights  # (the property returns a copy: assign, do not append)
    if preset.environment_map:
        from pydrake.geometry import EnvironmentMap, EquirectangularMap

        from pr2_drake.paths import data_path

        sky = data_path("models", "textures", "sky.png")
        params.environment_map = EnvironmentMap(skybox=True,
                                                texture=EquirectangularMap(path=str(sky)))
    params.cast_shadows = preset.shadows
    params.shadow_map_size = preset.shadow_map_size
    if preset.ssao:
        from pydrake.geometry import SsaoParameter

        params.ssao = SsaoParameter(radius=preset.ssao_radius, bias=0.01,
                                    sample_count=preset.ssao_samples, blur=True)
    params.exposure = preset.exposure
    return params


class RgbdSampler(LeafSystem):
    """Samples the sensor's images at ``fps`` (and at initialization) into an
    :class:`RgbdFrame` held between samples: the renderer runs only at the camera's rate, and
    only when a frame is asked for.

    Input ports: ``color_image`` (ImageRgba8U), ``depth_image_32f`` (ImageDepth32F),
    ``capture`` (bool, ``Value[bool]``, optional): capture on demand. Unconnected (or ``capture_always``), every
    sample renders. Connected, a sample at which it reads False renders nothing and the
    previous frame (with its ``time``) is kept; the initialization always renders.
    ``capture_color`` (bool, optional): connected and False at a sample that renders, only
    the depth image renders (the colour render is about 60 % of a frame's cost): the frame's
    ``color`` is then empty (shape (0, 0, 3)). Unconnected (or ``capture_always``), or at the
    initialization, colour renders with every frame.
    Output port: ``rgbd`` (RgbdFrame), no direct feedthrough.

    Attributes:
        capture_always: ignore ``capture`` (set by the head-camera video recorder, which
            writes every sample).
    """

    __slots__ = ()  # see pr2_drake.lifetime: lets the collector free the diagram

    def __init__(self, width: int, height: int, fps: float):
        super().__init__()
        self.capture_always = False
        self._color = self.DeclareAbstractInputPort(
            "color_image", AbstractValue.Make(ImageRgba8U(width, height))
        )
        self._depth = self.DeclareAbstractInputPort(
            "depth_image_32f", AbstractValue.Make(ImageDepth32F(width, height))
        )
        self._capture = self.DeclareAbstractInputPort("capture", AbstractValue.Make(False))
        self._capture_color = self.DeclareAbstractInputPort("capture_color",
                                                            AbstractValue.Make(True))
        blank = RgbdFrame(np.zeros((height, width, 3), np.uint8),
                          np.zeros((height, width), np.float32))
        self._frame = self.DeclareAbstractState(AbstractValue.Make(blank))
        self.DeclareInitializationUnrestrictedUpdateEvent(self._initial)
        self.DeclarePeriodicUnrestrictedUpdateEvent(1.0 / fps, 0.0, self._sample)
        self.DeclareStateOutputPort("rgbd", self._frame)

    def wants_frame(self, context) -> bool:
        """Whether the sample at this context's time renders (see the class docstring)."""
        if self.capture_always or not self._capture.HasValue(context):
            return True
        return bool(self._capture.Eval(context))

    def wants_color(self, context) -> bool:
        """Whether a frame rendered at this context's time has colour (class docstring)."""
        if self.capture_always or not self._capture_color.HasValue(context):
            return True
        return bool(self._capture_color.Eval(context))

    def _initial(self, context, state) -> None:
        self._render(context, state)

    def _sample(self, context, state) -> None:
        if self.wants_frame(context):
            self._render(context, state, self.wants_color(context))
        # else: the state handed to an unrestricted update holds the current frame: kept

    def _render(self, context, state, color: bool = True) -> None:
        rgb = (self._color.Eval(context).data[:, :, :3].copy() if color
               else np.zeros((0, 0, 3), np.uint8))
        frame = RgbdFrame(rgb, self._depth.Eval(context).data[:, :, 0].copy(), context.get_time())
        state.get_mutable_abstract_state(int(self._frame)).set_value(frame)


class CameraScenePoses(LeafSystem):
    """The plant's frame poses, renamed into the camera SceneGraph's frame ids.

    Input port ``plant_geometry_pose`` (FramePoseVector of the plant's geometry source, X_WF);
    output port ``geometry_pose`` (FramePoseVector of the camera SceneGraph's source). The
    output is computed only when evaluated, that is when a camera renders.
    """

    __slots__ = ()  # see pr2_drake.lifetime

    def __init__(self, frame_ids: dict):
        super().__init__()
        self._pairs = tuple(frame_ids.items())  # (plant SceneGraph id, camera SceneGraph id)
        self._in = self.DeclareAbstractInputPort("plant_geometry_pose",
                                                 AbstractValue.Make(FramePoseVector()))
        self.DeclareAbstractOutputPort("geometry_pose",
                                       lambda: AbstractValue.Make(FramePoseVector()),
                                       weak_calc(self._calc))

    def _calc(self, context, output) -> None:
        poses = self._in.Eval(context)
        out = output.get_mutable_value()
        out.clear()
        for plant_id, camera_id in self._pairs:
            out.set_value(camera_id, poses.value(plant_id))


def add_camera_scene_graph(builder: DiagramBuilder, plant, scene_graph: SceneGraph,
                           extra_frames=()) -> tuple[SceneGraph, dict]:
    """Adds a SceneGraph for cameras only: a copy of the perception geometry registered in
    ``scene_graph`` (all of it from ``plant``), posed by :class:`CameraScenePoses` from the
    plant's geometry poses.

    Args:
        extra_frames: plant SceneGraph frame ids to copy even without perception geometry
            (the bodies cameras are mounted on).
    Returns:
        (the camera SceneGraph, {plant SceneGraph frame id: camera SceneGraph frame id}).
    Raises:
        ValueError: a frame with perception geometry that the plant does not pose.
    """
    inspector = scene_graph.model_inspector()
    camera_sg = builder.AddNamedSystem("camera_scene_graph", SceneGraph())
    source = camera_sg.RegisterSource("camera_scene_poses")
    world = inspector.world_frame_id()
    plant_source = plant.get_source_id()
    frame_ids = {}
    for frame_id in inspector.GetAllFrameIds():
        geometries = inspector.GetGeometries(frame_id, Role.kPerception)
        if frame_id != world and not geometries and frame_id not in extra_frames:
            continue
        if frame_id == world:
            target = world
        else:
            if inspector.GetOwningSourceName(frame_id) != inspector.GetName(plant_source):
                raise ValueError(f"frame {inspector.GetName(frame_id)!r} has perception geometry "
                                 "but is not the plant's: the camera cannot pose it")
            target = camera_sg.RegisterFrame(source, GeometryFrame(inspector.GetName(frame_id)))
            frame_ids[frame_id] = target
        for g in geometries:
            instance = GeometryInstance(inspector.GetPoseInFrame(g), inspector.GetShape(g),
                                        inspector.GetName(g))
            instance.set_perception_properties(inspector.GetPerceptionProperties(g))
            if frame_id == world:
                camera_sg.RegisterAnchoredGeometry(source, instance)
            else:
                camera_sg.RegisterGeometry(source, target, instance)
    poses = builder.AddNamedSystem("camera_scene_poses", CameraScenePoses(frame_ids))
    builder.Connect(plant.get_geometry_pose_output_port(), poses.GetInputPort("plant_geometry_pose"))
    builder.Connect(poses.GetOutputPort("geometry_pose"), camera_sg.get_source_pose_port(source))
    return camera_sg, frame_ids


def add_head_camera(
    builder: DiagramBuilder,
    scene_graph: SceneGraph,
    parent_frame_id,
    X_PC: RigidTransform,
    settings: CameraSettings,
) -> RgbdSampler:
    """Adds the renderer to ``scene_graph``, an RgbdSensor on the head frame and its sampler.

    Args:
        scene_graph: the camera SceneGraph (:func:`add_camera_scene_graph`).
        parent_frame_id: its frame id of the body carrying the camera.
        X_PC: camera pose in that body, in Drake's camera convention (+z optical axis).
    Returns:
        the sampler, whose output port ``rgbd`` carries :class:`RgbdFrame`.
    """
    settings.validate()
    if not scene_graph.HasRenderer(RENDERER_NAME):
        scene_graph.AddRenderer(RENDERER_NAME,
                                MakeRenderEngineVtk(renderer_params(settings.quality)))
    core = RenderCameraCore(
        RENDERER_NAME,
        CameraInfo(settings.width, settings.height, np.radians(settings.fov_y_deg)),
        ClippingRange(0.5 * settings.z_near, 2.0 * settings.z_far),
        RigidTransform(),
    )
    color = ColorRenderCamera(core, False)
    depth = DepthRenderCamera(core, DepthRange(settings.z_near, settings.z_far))
    sensor = builder.AddNamedSystem("head_camera", RgbdSensor(parent_frame_id, X_PC, color, depth))
    builder.Connect(scene_graph.get_query_output_port(), sensor.query_object_input_port())
    sampler = builder.AddNamedSystem(
        "head_camera_sampler", RgbdSampler(settings.width, settings.height, settings.fps)
    )
    builder.Connect(sensor.color_image_output_port(), sampler.GetInputPort("color_image"))
    builder.Connect(sensor.depth_image_32F_output_port(), sampler.GetInputPort("depth_image_32f"))
    return sampler

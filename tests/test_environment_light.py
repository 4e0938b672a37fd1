"""Median-cut light sampling of an environment map (pr2_drake/environment_light.py) and the
sky lights the render presets take from it."""

import math

import cv2
import numpy as np
import pytest
from pydrake.geometry import (
    Box,
    ClippingRange,
    ColorRenderCamera,
    LightParameter,
    MakeRenderEngineVtk,
    RenderCameraCore,
    RenderEngineVtkParams,
    Rgba,
)
from pydrake.math import RigidTransform
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.sensors import CameraInfo

from pr2_drake.camera import PRESETS, SUN_DIRECTION, renderer_params
from pr2_drake.environment_light import (
    SUN_DISC_DEG,
    ground_light,
    median_cut,
    pixel_directions,
    sky_lights,
)
from pr2_drake.paths import data_path
from pr2_drake.viz import look_at

SKY = data_path("models", "textures", "sky.png")


def _energy_direction(lights):
    v = sum(light.intensity * -np.asarray(light.direction) for light in lights)
    return v / np.linalg.norm(v)


@pytest.mark.parametrize("count", [1, 2, 4, 8, 16])
def test_bright_spot_draws_the_lights_towards_it(count):
    """A bright 3x3 patch on a dim map: 2^k lights, intensities summing to 1, whose
    energy-weighted direction points at the patch, and one light sits on the patch."""
    rgb = np.full((64, 128, 3), 0.01)
    rgb[20:23, 90:93] = 50.0
    lights = median_cut(rgb, count)
    assert len(lights) == count
    assert sum(light.intensity for light in lights) == pytest.approx(1.0)
    spot = pixel_directions(64, 128)[21, 91]
    assert math.degrees(math.acos(min(1.0, _energy_direction(lights) @ spot))) < 15.0
    nearest = max(-np.asarray(light.direction) @ spot for light in lights)
    assert nearest > math.cos(math.radians(3.0))


def test_uniform_map_gives_equal_lights_spread_over_the_sphere():
    """A uniform grey map: equal energies (within pixel rounding), white lights, whose
    energy-weighted directions cancel (spread over the whole sphere, both hemispheres)."""
    lights = median_cut(np.full((64, 128, 3), 0.5), 16)
    shares = [light.intensity for light in lights]
    assert sum(shares) == pytest.approx(1.0)
    assert max(shares) / min(shares) < 1.1
    assert np.linalg.norm(sum(-np.asarray(light.direction) for light in lights)) < 0.5
    ups = sum(light.direction[2] < 0 for light in lights)
    assert ups == 8  # half the lights above the horizon (they travel down)
    for light in lights:
        assert light.color == pytest.approx((1.0, 1.0, 1.0))


def test_upper_band_alone_covers_the_upper_hemisphere():
    """Cutting only the upper half (as the sky lights do): every light comes from above."""
    rgb = np.full((64, 128, 3), 0.5)
    lights = median_cut(rgb[:32], 8, row0=0, total_rows=64)
    assert all(light.direction[2] < 0 for light in lights)
    azimuths = sorted(math.degrees(math.atan2(-light.direction[1], -light.direction[0])) % 360
                      for light in lights)
    assert max(np.diff(azimuths + [azimuths[0] + 360])) < 120.0  # no wide gap in azimuth


def test_sky_lights_come_from_above_and_not_from_the_sun():
    """The generated sky: the sky lights come from above the horizon, none from the sun disc
    (the sun is the separate shadow-casting light); the ground light comes from below, warm."""
    sun = -np.asarray(SUN_DIRECTION) / np.linalg.norm(SUN_DIRECTION)
    for count in (4, 8, 16):
        lights = sky_lights(SKY, count, SUN_DIRECTION)
        assert len(lights) == count
        assert sum(light.intensity for light in lights) == pytest.approx(1.0)
        for light in lights:
            assert light.direction[2] < 0.0  # travels down: comes from above the horizon
            angle = math.degrees(math.acos(-np.asarray(light.direction) @ sun))
            assert angle > SUN_DISC_DEG
            assert light.color[2] == pytest.approx(1.0)  # sky blue: blue is the largest
    ground = ground_light(SKY)
    assert ground.direction[2] > 0.99  # straight up from below
    assert ground.color[0] == 1.0 and ground.color[2] < 0.9  # warm


def test_extraction_is_cached():
    assert sky_lights(SKY, 8, SUN_DIRECTION) == sky_lights(SKY, 8, SUN_DIRECTION)
    from pr2_drake import environment_light

    before = environment_light._sky_lights.cache_info().hits
    renderer_params("medium")
    assert environment_light._sky_lights.cache_info().hits > before


@pytest.mark.parametrize("quality", ["low", "medium", "high"])
def test_presets_take_their_light_count_from_the_map(quality):
    preset = PRESETS[quality]
    lights = renderer_params(quality).lights
    assert len(lights) == 1 + (preset.sky_lights or 4) + (preset.bounce > 0)
    assert lights[0].direction == pytest.approx(list(SUN_DIRECTION))


def test_bad_input_names_what_was_wrong(tmp_path):
    rgb = np.full((8, 16, 3), 0.5)
    for count in (0, 3, 6, -4, 2.0):
        with pytest.raises(ValueError, match="power of two"):
            median_cut(rgb, count)
    with pytest.raises(ValueError, match="power of two"):
        sky_lights(SKY, 12)
    with pytest.raises(ValueError, match="not found"):
        sky_lights(tmp_path / "missing.png", 4)
    with pytest.raises(ValueError, match="all black"):
        median_cut(np.zeros((8, 16, 3)), 4)
    with pytest.raises(ValueError, match="non-negative"):
        median_cut(-rgb, 4)
    with pytest.raises(ValueError, match="RGB"):
        median_cut(rgb[..., 0], 4)
    with pytest.raises(ValueError, match="only 128 pixels"):
        median_cut(rgb, 256)
    square = tmp_path / "square.png"
    cv2.imwrite(str(square), np.zeros((8, 8, 3), np.uint8))
    with pytest.raises(ValueError, match="equirectangular"):
        sky_lights(square, 4)


def _render_with(light: LightParameter, shadows: bool) -> np.ndarray:
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, 0.0)
    grey = np.array([0.8, 0.8, 0.8, 1.0])
    plant.RegisterVisualGeometry(plant.world_body(), RigidTransform([0, 0, -0.05]),
                                 Box(6, 6, 0.1), "floor", grey)
    plant.RegisterVisualGeometry(plant.world_body(), RigidTransform([0, 0, 0.5]),
                                 Box(0.5, 0.5, 1.0), "post", grey)
    plant.Finalize()
    params = RenderEngineVtkParams()
    params.lights = [light]
    params.cast_shadows = shadows
    params.shadow_map_size = 512
    scene_graph.AddRenderer("test", MakeRenderEngineVtk(params))
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    query = scene_graph.get_query_output_port().Eval(scene_graph.GetMyContextFromRoot(context))
    camera = ColorRenderCamera(RenderCameraCore("test", CameraInfo(64, 64, np.radians(60)),
                                                ClippingRange(0.1, 20.0), RigidTransform()))
    X_WC = look_at(np.array([0.0, 0.0, 5.0]), np.array([1e-3, 0.0, 0.0]))
    return query.RenderColorImage(camera, scene_graph.world_frame_id(), X_WC).data[..., :3]


def test_point_lights_cast_no_shadows_in_vtk():
    """The sky lights rely on it (with shadows on they are far point lights): a point light
    renders the same with shadows on and off, while a directional light's shadow shows."""
    point = LightParameter(type="point", frame="world", position=[30.0, 0.0, 30.0],
                           intensity=1.0, color=Rgba(1, 1, 1))
    np.testing.assert_array_equal(_render_with(point, True), _render_with(point, False))
    sun = LightParameter(type="directional", frame="world", direction=[-1.0, 0.0, -1.0],
                         intensity=1.0, color=Rgba(1, 1, 1))
    shadowed = np.mean(np.abs(_render_with(sun, True).astype(int) - _render_with(sun, False)))
    assert shadowed > 1.0

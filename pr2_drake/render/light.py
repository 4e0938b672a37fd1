"""The light of a path-traced scene: the testbed's sun and sky map, white balanced.

The raster presets light the scene with the sun of :mod:`pr2_drake.camera` (``SUN_DIRECTION``,
``SUN_COLOR``) and lights sampled from ``models/textures/sky.png``; the path tracer uses the
same sun as a lamp of finite size and the whole map as an environment light. Its blue sky
would tint every surface blue; as a camera's white balance does (and as the raster presets
do, :func:`pr2_drake.camera.environment_lights`), both are scaled by RGB gains that make an
upward white surface in sun and sky neutral grey, its luminance unchanged.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pr2_drake.camera import SUN_COLOR, SUN_DIRECTION
from pr2_drake.environment_light import LUMA, load_map, pixel_directions
from pr2_drake.paths import data_path
from pr2_drake.render.settings import PathTracingSettings


@dataclass(frozen=True)
class Lighting:
    """Sun and sky of a path-traced scene.

    Attributes:
        sky: the equirectangular sky map (convention of :mod:`pr2_drake.environment_light`).
        sky_strength: its radiance multiplier; sky_gain: linear RGB white-balance gain on it.
        sun_direction: unit vector the sunlight travels along (world frame).
        sun_color: linear RGB (white balanced, largest channel 1); sun_strength: [W/m^2]
            irradiance facing the sun, of that colour; sun_angle_deg: disc diameter [deg].
    """

    sky: str
    sky_strength: float
    sky_gain: tuple[float, float, float]
    sun_direction: tuple[float, float, float]
    sun_color: tuple[float, float, float]
    sun_strength: float
    sun_angle_deg: float


def testbed_lighting(settings: PathTracingSettings) -> Lighting:
    """The testbed's sun and sky (:mod:`pr2_drake.camera`) at the strengths of ``settings``,
    white balanced (see the module docstring)."""
    sky = str(data_path("models", "textures", "sky.png"))
    sun = np.asarray(SUN_COLOR, float)
    d = np.asarray(SUN_DIRECTION, float) / np.linalg.norm(SUN_DIRECTION)
    e_sun = settings.sun_strength * sun * max(0.0, -d[2])
    e_sky = settings.sky_strength * np.asarray(sky_irradiance(sky))
    total = e_sun + e_sky
    gain = (total @ LUMA) / total  # neutral, same luminance
    sun_wb = sun * gain
    scale = sun_wb.max()
    return Lighting(sky, settings.sky_strength, tuple(float(g) for g in gain),
                    tuple(float(v) for v in d), tuple(float(c) for c in sun_wb / scale),
                    settings.sun_strength * float(scale), settings.sun_angle_deg)


def sky_irradiance(path: str | Path) -> tuple[float, float, float]:
    """Linear RGB irradiance of the map's sky on an upward surface (radiance 1 = map value 1,
    integrated over the upper hemisphere with the cosine). Cached per file."""
    return _sky_irradiance(str(path))


@functools.lru_cache(maxsize=4)
def _sky_irradiance(path: str) -> tuple[float, float, float]:
    rgb = load_map(path)
    h, w = rgb.shape[:2]
    up = np.clip(pixel_directions(h, w)[..., 2], 0.0, None)
    lat = (0.5 - (np.arange(h) + 0.5) / h) * np.pi
    solid_angle = (np.pi / h) * (2 * np.pi / w) * np.cos(lat)[:, None]
    return tuple(float(v) for v in (rgb * (up * solid_angle)[..., None]).sum(axis=(0, 1)))

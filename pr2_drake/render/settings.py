"""The path tracer's light and film settings (``models/textures/path_tracing.yaml``)."""

import functools
from dataclasses import dataclass

from pr2_drake.paths import data_path


@dataclass
class PathTracingSettings:
    """How the path tracer lights and exposes a scene (see the YAML file's comments).

    Attributes:
        sun_strength: sun irradiance [W/m^2]; sun_angle_deg: its disc's diameter [deg].
        sky_strength: multiplier of the sky map's radiance.
        roughness: of flat-coloured surfaces without a material of their own.
        ground_radius: [m] radius of the disc that carries the ground to the horizon.
        exposure: [stops]; view_transform: Blender's (``Khronos PBR Neutral``, ``AgX``,
            ``Standard``).
        max_bounces: light path length; clamp_indirect: brightest indirect sample.
    """

    sun_strength: float = 4.0
    sun_angle_deg: float = 2.0
    sky_strength: float = 1.0
    roughness: float = 0.5
    ground_radius: float = 2000.0
    exposure: float = 0.0
    view_transform: str = "Khronos PBR Neutral"
    max_bounces: int = 6
    clamp_indirect: float = 10.0


@functools.lru_cache(maxsize=1)
def path_tracing_settings() -> PathTracingSettings:
    """The settings of ``models/textures/path_tracing.yaml``."""
    from pydrake.common.yaml import yaml_load_typed

    return yaml_load_typed(schema=PathTracingSettings,
                           filename=str(data_path("models", "textures", "path_tracing.yaml")))

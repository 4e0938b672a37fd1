"""Diffuse image-based lighting from an equirectangular environment map by median-cut light
sampling (Debevec, "A Median Cut Algorithm for Light Probe Sampling", 2005).

The map is cut, recursively, into ``2^k`` regions of equal energy: each cut halves a region's
energy (luminance times the pixel's solid angle, which shrinks as the cosine of the latitude)
across its longer side, the longer side measured on the sphere (the width shrunk by the cosine
of the region's mid latitude). Each region becomes one directional light at its energy
centroid, carrying the region's summed colour.

Map convention (that of :func:`pr2_drake.assets.make_textures.sky`): row 0 is the zenith, the
last row the nadir; column ``u`` of ``W`` looks at azimuth ``(u + 0.5) / W * 360`` deg measured
from world +x towards +y; a pixel at elevation ``e`` and azimuth ``a`` looks along
``(cos e cos a, cos e sin a, sin e)`` in the world frame (z up).

For the generated sky (``models/textures/sky.png``) :func:`sky_lights` cuts the upper half
with the sun disc masked out (the sun is the renderer's one shadow-casting light, of its own
intensity), and :func:`ground_light` takes the lower half, a uniform warm grey ground, as one
light from straight below: the ground's bounce.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

LUMA = np.array([0.2126, 0.7152, 0.0722])  # Rec. 709 luminance of linear RGB
SUN_DISC_DEG = 6.0  # [deg] angular radius of the sun disc (and its sharp glow) masked out


@dataclass(frozen=True)
class EnvironmentLight:
    """One light sampled from an environment map.

    Attributes:
        direction: unit vector the light travels along, world frame (from the region's
            centroid towards the origin).
        color: the region's mean RGB, scaled so its largest channel is 1.
        intensity: the region's share of the map's (or the cut part's) energy; the lights'
            intensities sum to 1.
    """

    direction: tuple[float, float, float]
    color: tuple[float, float, float]
    intensity: float


def pixel_directions(height: int, width: int) -> np.ndarray:
    """(height, width, 3) unit vectors, world frame, each pixel of an equirectangular map of
    that size looks along (see the module's convention)."""
    elev = (0.5 - (np.arange(height) + 0.5) / height) * np.pi
    azim = (np.arange(width) + 0.5) / width * 2 * np.pi
    e, a = np.meshgrid(elev, azim, indexing="ij")
    return np.stack([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)], axis=-1)


def _check_count(count: int) -> int:
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 1 \
            or count & (count - 1):
        raise ValueError(f"light count must be a power of two (1, 2, 4, ...), got {count!r}")
    return int(count)


def median_cut(rgb: np.ndarray, count: int, *, row0: int = 0,
               total_rows: int | None = None) -> list[EnvironmentLight]:
    """Median-cut ``count`` lights (a power of two) from an equirectangular map.

    Args:
        rgb: (rows, width, 3) linear RGB radiance, non-negative; may be a band of rows of a
            larger map (``row0`` its first row in a map of ``total_rows`` rows; the whole
            map by default).
        count: number of lights, a power of two.
    Returns: the lights, whose intensities (energy shares) sum to 1.
    """
    count = _check_count(count)
    rgb = np.asarray(rgb, dtype=float)
    if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.shape[0] < 1 or rgb.shape[1] < 1:
        raise ValueError(f"environment map must be (rows, width, 3) RGB, got {rgb.shape}")
    if not np.all(np.isfinite(rgb)) or np.any(rgb < 0):
        raise ValueError("environment map must be finite and non-negative")
    rows, width = rgb.shape[:2]
    total_rows = rows if total_rows is None else total_rows
    if row0 < 0 or row0 + rows > total_rows:
        raise ValueError(f"rows {row0}..{row0 + rows} lie outside a map of {total_rows} rows")
    if count > rows * width:
        raise ValueError(f"{count} lights from a map of only {rows * width} pixels")
    dirs = pixel_directions(total_rows, width)[row0:row0 + rows]
    lat = (0.5 - (np.arange(row0, row0 + rows) + 0.5) / total_rows) * np.pi
    weight = np.cos(lat)[:, None] * np.ones((1, width))  # solid angle per pixel, up to a factor
    colour = rgb * weight[..., None]
    energy = colour @ LUMA
    total = float(energy.sum())
    if total <= 0.0:
        raise ValueError("environment map has no energy to sample (all black)")

    regions = [(0, rows, 0, width)]  # [r0, r1) x [c0, c1)
    while len(regions) < count:
        regions = [half for region in regions for half in _split(region, energy, lat)]
    lights = []
    for r0, r1, c0, c1 in regions:
        e = energy[r0:r1, c0:c1]
        share = float(e.sum())
        if share > 0:
            centroid = np.tensordot(e, dirs[r0:r1, c0:c1], axes=([0, 1], [0, 1])) / share
        else:  # a region of no energy: its geometric centre, weightless
            centroid = dirs[r0:r1, c0:c1].reshape(-1, 3).mean(axis=0)
        centroid = centroid / max(np.linalg.norm(centroid), 1e-12)
        c = colour[r0:r1, c0:c1].reshape(-1, 3).sum(axis=0)
        c = c / c.max() if c.max() > 0 else np.ones(3)
        lights.append(EnvironmentLight(tuple(float(v) for v in -centroid),
                                       tuple(float(v) for v in c), share / total))
    return lights


def _split(region, energy: np.ndarray, lat: np.ndarray):
    """The two halves of equal energy of a region, cut across its longer side on the sphere."""
    r0, r1, c0, c1 = region
    h, w = r1 - r0, c1 - c0
    if h == 1 and w == 1:
        raise ValueError("environment map too small for that many lights: a region of one "
                         "pixel would have to be cut")
    mid_lat = 0.5 * (lat[r0] + lat[r1 - 1])
    # angular sizes [rad]: a row spans row_step of latitude, a column col_step of azimuth,
    # which is col_step * cos(latitude) of arc
    col_step = 2 * math.pi / energy.shape[1]
    row_step = abs(lat[1] - lat[0]) if len(lat) > 1 else math.pi
    wide = w * col_step * math.cos(mid_lat) >= h * row_step if h > 1 and w > 1 else w > 1
    profile = energy[r0:r1, c0:c1].sum(axis=0 if wide else 1)
    cum = np.cumsum(profile)
    # cut after index k (k = 0 .. n-2): left = cum[k]; choose the most even split
    k = int(np.argmin(np.abs(2 * cum[:-1] - cum[-1])))
    cut = k + 1
    if wide:
        return [(r0, r1, c0, c0 + cut), (r0, r1, c0 + cut, c1)]
    return [(r0, r0 + cut, c0, c1), (r0 + cut, r1, c0, c1)]


def load_map(path: str | Path) -> np.ndarray:
    """An 8-bit equirectangular PNG/JPEG as linear RGB in [0, 1] (sRGB decoded)."""
    import cv2

    path = Path(path)
    if not path.is_file():
        raise ValueError(f"environment map not found: {path}")
    bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if bgr is None:
        raise ValueError(f"environment map could not be read as an image: {path}")
    if bgr.shape[1] != 2 * bgr.shape[0]:
        raise ValueError(f"environment map must be equirectangular (width = 2 x height), "
                         f"got {bgr.shape[1]}x{bgr.shape[0]}: {path}")
    s = bgr[..., ::-1].astype(float) / 255.0
    return np.where(s <= 0.04045, s / 12.92, ((s + 0.055) / 1.055) ** 2.4)


def mask_sun(rgb: np.ndarray, sun_travel_direction, radius_deg: float = SUN_DISC_DEG
             ) -> np.ndarray:
    """A copy of a whole equirectangular map with the pixels within ``radius_deg`` of the sun
    (opposite to ``sun_travel_direction``, the way its light travels) set to black."""
    d = -np.asarray(sun_travel_direction, dtype=float)
    d = d / np.linalg.norm(d)
    dirs = pixel_directions(*rgb.shape[:2])
    out = np.array(rgb, dtype=float)
    out[dirs @ d > math.cos(math.radians(radius_deg))] = 0.0
    return out


def _key(path) -> tuple[str, int, int]:
    p = Path(path)
    if not p.is_file():
        raise ValueError(f"environment map not found: {p}")
    st = p.stat()
    return str(p.resolve()), st.st_mtime_ns, st.st_size


def sky_lights(path: str | Path, count: int, sun_travel_direction=None
               ) -> list[EnvironmentLight]:
    """``count`` lights (a power of two) median-cut from the upper half of the map at ``path``,
    the sun disc (around ``-sun_travel_direction``, if given) masked out. Cached per file
    (path, modification time, size), count and sun."""
    _check_count(count)
    sun = None if sun_travel_direction is None else tuple(float(v) for v in sun_travel_direction)
    return list(_sky_lights(_key(path), count, sun))


@functools.lru_cache(maxsize=32)
def _sky_lights(key, count, sun) -> tuple[EnvironmentLight, ...]:
    rgb = load_map(key[0])
    if sun is not None:
        rgb = mask_sun(rgb, sun)
    half = rgb.shape[0] // 2
    return tuple(median_cut(rgb[:half], count, row0=0, total_rows=rgb.shape[0]))


def ground_light(path: str | Path) -> EnvironmentLight:
    """The lower half of the map at ``path`` as one light (the ground's bounce, travelling
    up), its intensity the lower half's energy relative to the upper half's. Cached."""
    return _ground_light(_key(path))


@functools.lru_cache(maxsize=8)
def _ground_light(key) -> EnvironmentLight:
    rgb = load_map(key[0])
    half = rgb.shape[0] // 2
    (light,) = median_cut(rgb[half:], 1, row0=half, total_rows=rgb.shape[0])
    lat = (0.5 - (np.arange(rgb.shape[0]) + 0.5) / rgb.shape[0]) * np.pi
    energy = (rgb @ LUMA) * np.cos(lat)[:, None]
    ratio = float(energy[half:].sum() / energy[:half].sum())
    return EnvironmentLight(light.direction, light.color, ratio)

"""Generate the scene textures and the sky from procedural noise (deterministic, no downloads).

    PYTHONPATH=. python -m pr2_drake.assets.make_textures [--check]

writes ``models/textures/<name>.png``: greyscale-ish *detail* maps (mean luminance about 0.85)
that the renderer multiplies with each surface's YAML colour, so hues stay what the task files
say (the task-6 detector relies on them), plus ``sky.png``, an equirectangular (2:1) sky with a
sun used as the environment map for image-based lighting. Every map tiles seamlessly (noise is
generated periodic through the FFT). Materials, their maps and tile sizes are in
``models/textures/materials.yaml``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np

from pr2_drake.paths import data_path

SIZE = 256  # [px] texture side: small files, enough for a 640x480 head camera


def periodic_noise(rng: np.random.Generator, n: int, scale: float, aniso=(1.0, 1.0)) -> np.ndarray:
    """Tileable smooth noise in [-1, 1]: white noise low-pass filtered in frequency space.

    ``scale``: feature size in pixels; ``aniso``: (x, y) stretch factors of the features
    (``(10, 1)``: streaks ten times longer along x than across)."""
    f = np.fft.fftfreq(n)
    fx, fy = np.meshgrid(f * aniso[0], f * aniso[1])
    spectrum = np.exp(-(fx ** 2 + fy ** 2) * (scale ** 2) * 2.0)
    field = np.real(np.fft.ifft2(np.fft.fft2(rng.standard_normal((n, n))) * spectrum))
    return field / (np.abs(field).max() + 1e-12)


def fbm(rng, n, base_scale, octaves=4, aniso=(1.0, 1.0)) -> np.ndarray:
    out, amp, total = np.zeros((n, n)), 1.0, 0.0
    for k in range(octaves):
        out += amp * periodic_noise(rng, n, base_scale / 2 ** k, aniso)
        total += amp
        amp *= 0.5
    return out / total


def _grey(lum: np.ndarray, tint=(1.0, 1.0, 1.0)) -> np.ndarray:
    rgb = np.clip(lum[..., None] * np.asarray(tint), 0, 1)
    return (rgb * 255 + 0.5).astype(np.uint8)


def wood(rng, n=SIZE) -> np.ndarray:
    """Wood grain along +u: long, gently warped growth lines (stretched along u), pores."""
    y = np.arange(n)[:, None] * np.ones((1, n))
    warp = 0.35 * fbm(rng, n, 48, octaves=2, aniso=(0.25, 1.0))
    rings = 0.5 + 0.5 * np.sin(2 * np.pi * (y * 24 / n + warp))
    streaks = fbm(rng, n, 6, octaves=2, aniso=(8.0, 1.0))
    pores = periodic_noise(rng, n, 0.7, aniso=(12.0, 1.0))
    return _grey(0.76 + 0.14 * rings ** 3 + 0.08 * streaks + 0.03 * pores, (1.0, 0.97, 0.92))


def parquet(rng, n=SIZE, rows: int = 8) -> np.ndarray:
    """Planks (``rows`` rows, half-length stagger), each a wood strip with its own brightness
    and grain offset, dark seams."""
    grain = wood(rng, n).astype(float) / 255
    out = np.empty_like(grain)
    plank_len = n // 2
    h = n // rows
    for r in range(rows):
        shift = (r * plank_len // 2 + int(rng.integers(0, n // 8))) % n
        src = int(rng.integers(0, n - h))
        band = np.roll(grain[src:src + h], int(rng.integers(0, n)), axis=1).copy()
        for p in range(2):
            x0 = (shift + p * plank_len) % n
            cols = (np.arange(plank_len) + x0) % n
            band[:, cols] *= 0.86 + 0.2 * rng.random()
            band[:, x0] *= 0.6
        band[0] *= 0.6
        out[r * h:(r + 1) * h] = band
    return (np.clip(out, 0, 1) * 255 + 0.5).astype(np.uint8)


def tiles(rng, n=SIZE, count=4) -> np.ndarray:
    """Square ceramic tiles with grout lines and a faint glaze mottle."""
    lum = 0.9 + 0.04 * fbm(rng, n, 12)
    t = n // count
    for i in range(count):
        for j in range(count):
            lum[i * t:(i + 1) * t, j * t:(j + 1) * t] *= 0.95 + 0.08 * rng.random()
    g = np.zeros((n, n), bool)
    for k in range(count):
        g[k * t:k * t + 3, :] = True
        g[:, k * t:k * t + 3] = True
    lum[g] = 0.6
    return _grey(lum)


def plaster(rng, n=SIZE) -> np.ndarray:
    """Painted plaster: soft roller mottle and fine grit."""
    return _grey(0.88 + 0.08 * fbm(rng, n, 24) + 0.03 * periodic_noise(rng, n, 1.0))


def fabric(rng, n=SIZE) -> np.ndarray:
    """Woven fabric: over-under weave of 4-px threads, slub noise."""
    x = np.arange(n)
    u, v = np.meshgrid(x, x)
    warp = 0.5 + 0.5 * np.cos(2 * np.pi * u / 4)
    weft = 0.5 + 0.5 * np.cos(2 * np.pi * v / 4)
    checker = ((u // 4 + v // 4) % 2).astype(float)
    weave = checker * warp + (1 - checker) * weft
    return _grey(0.72 + 0.14 * weave + 0.06 * fbm(rng, n, 10, aniso=(3.0, 1.0))
                 + 0.08 * fbm(rng, n, 40, octaves=2))


def rock(rng, n=SIZE) -> np.ndarray:
    """Stone: multi-octave mottle, dark cracks, grains."""
    base = fbm(rng, n, 30, octaves=5)
    cracks = np.abs(periodic_noise(rng, n, 10))
    lum = 0.78 + 0.16 * base + 0.06 * periodic_noise(rng, n, 0.8)
    lum = np.where(cracks < 0.04, lum * 0.6, lum)
    return _grey(lum)


def brushed_metal(rng, n=SIZE) -> np.ndarray:
    """Brushed metal: fine streaks along +u."""
    return _grey(0.86 + 0.08 * periodic_noise(rng, n, 1.0, aniso=(40.0, 1.0))
                 + 0.03 * fbm(rng, n, 30))


def ground(rng, n=SIZE) -> np.ndarray:
    """Outdoor ground (concrete/compacted earth): blotches, pebbles, grit."""
    lum = 0.82 + 0.09 * fbm(rng, n, 40, octaves=5) + 0.05 * periodic_noise(rng, n, 0.7)
    spots = periodic_noise(rng, n, 2.0) > 0.55
    lum[spots] *= 0.85
    return _grey(lum)


def plastic(rng, n=SIZE) -> np.ndarray:
    """Moulded plastic: faint orange-peel and soft moulding mottle."""
    return _grey(0.9 + 0.025 * periodic_noise(rng, n, 2.0) + 0.05 * fbm(rng, n, 36, octaves=3))


def rubber(rng, n=SIZE) -> np.ndarray:
    """Rubber sole/joint cover: fine grain."""
    return _grey(0.8 + 0.06 * periodic_noise(rng, n, 0.8) + 0.08 * fbm(rng, n, 32, octaves=3))


def sky(rng, width=512) -> np.ndarray:
    """Equirectangular sky (width x width/2), zenith at the top row: blue gradient, haze at the
    horizon, soft clouds, a sun disc with glow at the key light's direction, dim ground below."""
    h = width // 2
    v, u = np.mgrid[0:h, 0:width]
    elev = (0.5 - (v + 0.5) / h) * np.pi  # +pi/2 zenith, -pi/2 nadir
    azim = (u + 0.5) / width * 2 * np.pi
    t = np.clip(elev / (np.pi / 2), 0, 1)
    zenith, horizon = np.array([0.32, 0.52, 0.85]), np.array([0.78, 0.85, 0.92])
    col = horizon + (zenith - horizon) * (t ** 0.5)[..., None]
    clouds = np.clip(fbm(rng, width, 20, octaves=4)[:h] * 1.6, 0, 1) * (t > 0.02) * (1 - t)
    col = col * (1 - 0.6 * clouds[..., None]) + 0.95 * 0.6 * clouds[..., None]
    ground_col = np.array([0.42, 0.40, 0.36])
    below = elev < 0
    col[below] = ground_col * (0.8 + 0.2 * np.exp(elev[below] * 6))[..., None]
    sun_dir = np.array([np.cos(np.radians(50)) * np.cos(np.radians(-146)),
                        np.cos(np.radians(50)) * np.sin(np.radians(-146)), np.sin(np.radians(50))])
    d = np.stack([np.cos(elev) * np.cos(azim), np.cos(elev) * np.sin(azim), np.sin(elev)], -1)
    c = np.clip(d @ sun_dir, -1, 1)
    glow = 0.6 * np.exp((c - 1) * 400) + 0.25 * np.exp((c - 1) * 20)
    col = col + np.array([1.0, 0.95, 0.8]) * glow[..., None]
    return (np.clip(col, 0, 1) * 255 + 0.5).astype(np.uint8)


TEXTURES = {"wood": wood, "parquet": parquet, "tiles": tiles, "plaster": plaster,
            "fabric": fabric, "rock": rock, "brushed_metal": brushed_metal, "ground": ground,
            "plastic": plastic, "rubber": rubber, "sky": sky}


def generate(out_dir: Path) -> dict[str, np.ndarray]:
    """Every texture as an RGB uint8 array, by name (seeded per name: independent, stable)."""
    images = {}
    for k, (name, make) in enumerate(sorted(TEXTURES.items())):
        images[name] = make(np.random.default_rng(1000 + k))
    return images


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--check", action="store_true",
                   help="exit 1 if a committed texture differs from what this script makes")
    a = p.parse_args(argv)
    out_dir = Path(data_path("models")) / "textures"
    out_dir.mkdir(parents=True, exist_ok=True)
    stale = []
    for name, rgb in generate(out_dir).items():
        path = out_dir / f"{name}.png"
        if a.check:
            old = cv2.imread(str(path))
            if old is None or old.shape != rgb.shape or not np.array_equal(old[..., ::-1], rgb):
                stale.append(name)
        else:
            cv2.imwrite(str(path), rgb[..., ::-1], [cv2.IMWRITE_PNG_COMPRESSION, 9])
    if stale:
        print(f"stale textures: {stale}; run python -m pr2_drake.assets.make_textures")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())

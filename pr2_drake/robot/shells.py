"""Visual shell meshes of KUAVO, generated from models/kuavo/params.yaml (visual only: the
collision geometry stays the primitives of the URDF).

Each shell is a closed "super-lathe" surface: rings along the link's z axis, each ring a
superellipse (exponent ``section``: 2 = ellipse, larger = squarer) of half-widths (rx, ry),
the half-widths following a profile that rounds the ends. The trunk is a rounded, chest-wide
block; thighs, shins, upper arms and forearms taper from the joint down, with a muscle bulge;
the foot gets a rounded instep cover over its sole. Written as Wavefront OBJ (positions,
normals, triangles) to ``models/kuavo/meshes``, referenced by the generated URDF.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

SEGMENTS = 24  # around each ring
RINGS = 18  # along the axis


def super_lathe(z: np.ndarray, rx: np.ndarray, ry: np.ndarray, section: float = 2.0,
                x0: np.ndarray | float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (len(z) * SEGMENTS x 3) and triangles of rings at heights ``z`` [m] with
    half-widths ``rx``, ``ry`` [m] (zero at both ends closes the surface), centres offset
    along x by ``x0`` [m]."""
    theta = np.linspace(0.0, 2 * np.pi, SEGMENTS, endpoint=False)
    c, s = np.cos(theta), np.sin(theta)
    ex = np.sign(c) * np.abs(c) ** (2.0 / section)
    ey = np.sign(s) * np.abs(s) ** (2.0 / section)
    x0 = np.broadcast_to(np.asarray(x0, float), z.shape)
    verts = np.stack([x0[:, None] + rx[:, None] * ex[None, :],
                      ry[:, None] * ey[None, :],
                      np.repeat(z[:, None], SEGMENTS, axis=1)], axis=-1).reshape(-1, 3)
    faces = []
    for i in range(len(z) - 1):
        for j in range(SEGMENTS):
            a, b = i * SEGMENTS + j, i * SEGMENTS + (j + 1) % SEGMENTS
            c_, d = a + SEGMENTS, b + SEGMENTS
            faces += [(a, c_, b), (b, c_, d)]  # outward for z decreasing along the rings
    return verts, np.asarray(faces, np.int64)


def _round_ends(t: np.ndarray, power: float) -> np.ndarray:
    """1 in the middle of t in [0, 1], falling to 0 at both ends (superellipse profile)."""
    return np.clip(1.0 - np.abs(2.0 * t - 1.0) ** power, 0.0, 1.0) ** (1.0 / power)


def limb(length: float, radius: float, taper: float = 0.75, bulge: float = 0.12,
         margin: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """A limb shell from z = -margin down to z = -(length - margin) [m]: radius ``radius`` at
    the top narrowing to ``taper * radius``, a bulge in the upper third, slightly flattened
    sideways (y)."""
    t = 0.5 - 0.5 * np.cos(np.linspace(0.0, np.pi, RINGS))  # denser at the ends
    r = radius * (1.0 + (taper - 1.0) * t + bulge * np.sin(np.pi * np.clip(1.5 * t, 0, 1)))
    r = r * _round_ends(t, 5.0)
    z = -margin - t * (length - 2 * margin)
    return super_lathe(z, 1.05 * r, 0.95 * r, section=2.3)


def trunk(size, center) -> tuple[np.ndarray, np.ndarray]:
    """The trunk: a rounded block of ``size`` (x, y, z) [m] at ``center``, widest at the chest,
    narrower at the waist."""
    sx, sy, sz = (float(v) for v in size)
    t = 0.5 - 0.5 * np.cos(np.linspace(0.0, np.pi, RINGS))  # 0 top .. 1 bottom
    waist = 1.0 - 0.18 * t ** 1.5
    ends = _round_ends(t, 6.0)
    z = center[2] + sz / 2 - t * sz
    verts, faces = super_lathe(z, sx / 2 * (1.0 - 0.08 * t) * ends, sy / 2 * waist * ends,
                               section=3.5, x0=center[0])
    verts[:, 1] += center[1]
    return verts, faces


def foot_cover(length: float, width: float, height: float, x_mid: float,
               z_bottom: float) -> tuple[np.ndarray, np.ndarray]:
    """A rounded cover on the sole: ``length`` x ``width`` [m], ``height`` [m] tall at the
    ankle and lower at the toe, standing on z = ``z_bottom``; rings along x."""
    t = 0.5 - 0.5 * np.cos(np.linspace(0.0, np.pi, RINGS))
    ends = _round_ends(t, 4.0)
    x = x_mid + length / 2 - t * length  # toe (t = 0) to heel (t = 1)
    h = height * (0.45 + 0.55 * np.clip(1.6 * t, 0, 1))
    verts, faces = super_lathe(x, h / 2 * ends, width / 2 * ends, section=3.0,
                               x0=z_bottom + h / 2)
    return verts[:, [2, 1, 0]], faces  # ring axis to x, section's first axis to z


def outward(verts: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """``faces`` wound so that the closed surface's normals point out (positive volume)."""
    a, b, c = verts[faces[:, 0]], verts[faces[:, 1]], verts[faces[:, 2]]
    volume = np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0
    return faces if volume > 0 else faces[:, ::-1]


def vertex_normals(verts: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted vertex normals (unit; zero-area fans at the poles fall back to +-axis)."""
    n = np.zeros_like(verts)
    fn = np.cross(verts[faces[:, 1]] - verts[faces[:, 0]], verts[faces[:, 2]] - verts[faces[:, 0]])
    for k in range(3):
        np.add.at(n, faces[:, k], fn)
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return np.where(length > 1e-12, n / np.maximum(length, 1e-12), [0.0, 0.0, 1.0])


def write_obj(path: Path, verts: np.ndarray, faces: np.ndarray, comment: str) -> None:
    """Wavefront OBJ with positions, normals and triangles (1-based indices)."""
    faces = outward(verts, faces)
    normals = vertex_normals(verts, faces)
    lines = [f"# {comment}", "# generated by pr2_drake.robot.shells from models/kuavo/params.yaml"]
    lines += [f"v {x:.5f} {y:.5f} {z:.5f}" for x, y, z in verts]
    lines += [f"vn {x:.4f} {y:.4f} {z:.4f}" for x, y, z in normals]
    lines += [f"f {a + 1}//{a + 1} {b + 1}//{b + 1} {c + 1}//{c + 1}" for a, b, c in faces]
    path.write_text("\n".join(lines) + "\n")


def shell_meshes(p: dict) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Every shell by file stem, in its link's frame, from the raw parameter dictionary."""
    torso, legs, arms = p["torso"], p["legs"], p["arms"]
    foot = legs["foot"]
    th, ca, ua, fa = legs["thigh"], legs["calf"], arms["upper_arm"], arms["forearm"]
    fl, fw, fh, heel = foot["length"], foot["width"], foot["ankle_height"], foot["heel"]
    return {
        "trunk": trunk(torso["trunk_size"], torso["trunk_center"]),
        "thigh": limb(th["length"], 1.25 * th["radius"], taper=0.7, bulge=0.15, margin=0.01),
        "calf": limb(ca["length"], 1.15 * ca["radius"], taper=0.65, bulge=0.18, margin=0.02),
        "upper_arm": limb(ua["length"], 1.2 * ua["radius"], taper=0.8, bulge=0.1, margin=0.01),
        "forearm": limb(fa["length"], 1.15 * fa["radius"], taper=0.75, bulge=0.12,
                        margin=0.01),
        "foot": foot_cover(fl * 0.92, fw * 0.95, fh * 0.9, -heel + fl / 2, -fh + 0.03),
    }

"""Triangle meshes of Drake shapes, in the geometry's own frame G (z up, metres).

Primitives (``Box``, ``Sphere``, ``Cylinder``, ``Capsule``, ``Ellipsoid``) are tessellated
here; ``Mesh`` and ``Convex`` files are read with trimesh, one part per material, with the
material the file declares (glTF PBR, OBJ ``.mtl``). A glTF file is y-up: its coordinates are
turned into Drake's z-up frame as Drake does (glTF ``(x, y, z)`` -> ``(x, -z, y)``).
"""

from __future__ import annotations

import functools
import hashlib
import tempfile
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

SEGMENTS = 48  # around a sphere, cylinder or capsule
RINGS = 24  # pole to pole of a sphere
GLTF_TO_DRAKE = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])  # p_drake = R @ p_gltf


@dataclass(frozen=True)
class SurfaceMaterial:
    """A physically based surface (the metallic-roughness model of glTF).

    Attributes:
        base_color: linear RGBA in [0, 1] (multiplies the texture, as glTF's factor).
        texture: an sRGB image file of the base colour, or None.
        roughness, metallic: in [0, 1].
        source: where it came from: ``"gltf"``, ``"mtl"`` (the mesh file's own material) or
            ``"phong"`` (the geometry's Drake ``phong/diffuse`` colour).
    """

    base_color: tuple[float, float, float, float]
    texture: str | None
    roughness: float
    metallic: float
    source: str


@dataclass
class MeshPart:
    """Triangles in the geometry frame G: ``vertices`` (N, 3) [m], unit ``normals`` (N, 3),
    ``uv`` (N, 2) texture coordinates or None, ``faces`` (M, 3) vertex indices, and the
    material the file gives (None: the geometry's properties decide)."""

    vertices: np.ndarray
    normals: np.ndarray
    uv: np.ndarray | None
    faces: np.ndarray
    material: SurfaceMaterial | None = None


def srgb_to_linear(c) -> np.ndarray:
    """sRGB-encoded values in [0, 1] to linear."""
    c = np.clip(np.asarray(c, float), 0.0, 1.0)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def box(size) -> MeshPart:
    """A box of full ``size`` (x, y, z) [m] centred on G, flat faces."""
    h = np.asarray(size, float) / 2
    verts, normals, faces = [], [], []
    for axis in range(3):
        a, b = (axis + 1) % 3, (axis + 2) % 3
        for sign in (1.0, -1.0):
            base = len(verts)
            for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                v = np.zeros(3)
                v[axis], v[a], v[b] = sign * h[axis], su * h[a], sv * h[b]
                verts.append(v)
                n = np.zeros(3)
                n[axis] = sign
                normals.append(n)
            quad = [[0, 1, 2], [0, 2, 3]] if sign > 0 else [[0, 2, 1], [0, 3, 2]]
            faces += [[base + i for i in tri] for tri in quad]
    return MeshPart(np.array(verts), np.array(normals), None, np.array(faces))


def _grid(rows: np.ndarray, cols: int, closed_rows: bool = False) -> np.ndarray:
    """Triangles of a (len(rows) x cols) vertex grid wrapped around in the column direction."""
    faces = []
    n = len(rows)
    for i in range(n - 1):
        for j in range(cols):
            a, b = i * cols + j, i * cols + (j + 1) % cols
            c, d = a + cols, b + cols
            faces += [[a, c, b], [b, c, d]]
    return np.array(faces)


def ellipsoid(a: float, b: float, c: float) -> MeshPart:
    """An ellipsoid of semi-axes (a, b, c) [m] along G's x, y, z; smooth normals."""
    theta = np.linspace(0, np.pi, RINGS + 1)  # from the +z pole
    phi = np.arange(SEGMENTS) * 2 * np.pi / SEGMENTS
    t, p = np.meshgrid(theta, phi, indexing="ij")
    unit = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1).reshape(-1, 3)
    radii = np.array([a, b, c])
    normals = unit / radii
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    return MeshPart(unit * radii, normals, None, _grid(theta, SEGMENTS))


def sphere(radius: float) -> MeshPart:
    return ellipsoid(radius, radius, radius)


def _disc(radius: float, z: float, up: bool, base: int):
    """A flat disc at height z facing +z (``up``) or -z: vertices, normals, faces."""
    phi = np.arange(SEGMENTS) * 2 * np.pi / SEGMENTS
    ring = np.stack([radius * np.cos(phi), radius * np.sin(phi), np.full(SEGMENTS, z)], -1)
    verts = np.vstack([[0.0, 0.0, z], ring])
    normals = np.tile([0.0, 0.0, 1.0 if up else -1.0], (SEGMENTS + 1, 1))
    faces = [[0, 1 + j, 1 + (j + 1) % SEGMENTS] for j in range(SEGMENTS)]
    faces = np.array(faces) if up else np.array(faces)[:, [0, 2, 1]]
    return verts, normals, faces + base


def cylinder(radius: float, length: float) -> MeshPart:
    """A cylinder along G's z, centred, smooth sides and flat caps."""
    phi = np.arange(SEGMENTS) * 2 * np.pi / SEGMENTS
    ring = np.stack([np.cos(phi), np.sin(phi), np.zeros(SEGMENTS)], -1)
    z = np.array([length / 2, -length / 2])
    side = np.vstack([ring * radius + [0, 0, zz] for zz in z])
    side_n = np.vstack([ring, ring])
    faces = [_grid(z, SEGMENTS)]
    verts, normals = [side], [side_n]
    for zz, up in ((length / 2, True), (-length / 2, False)):
        v, n, f = _disc(radius, zz, up, sum(len(x) for x in verts))
        verts.append(v)
        normals.append(n)
        faces.append(f)
    return MeshPart(np.vstack(verts), np.vstack(normals), None, np.vstack(faces))


def capsule(radius: float, length: float) -> MeshPart:
    """A capsule along G's z: a cylinder of ``length`` between two hemispheres."""
    half = RINGS // 2
    theta = np.concatenate([np.linspace(0, np.pi / 2, half + 1),
                            np.linspace(np.pi / 2, np.pi, half + 1)])
    offset = np.where(np.arange(len(theta)) <= half, length / 2, -length / 2)
    phi = np.arange(SEGMENTS) * 2 * np.pi / SEGMENTS
    t, p = np.meshgrid(theta, phi, indexing="ij")
    unit = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1)
    verts = unit * radius
    verts[..., 2] += offset[:, None]
    return MeshPart(verts.reshape(-1, 3), unit.reshape(-1, 3), None, _grid(theta, SEGMENTS))


def mesh_file_parts(path: str | Path, scale=(1.0, 1.0, 1.0)) -> list[MeshPart]:
    """The parts of a mesh file (one per material) in Drake's frame, scaled per axis."""
    parts = _load_parts(str(Path(path).resolve()), Path(path).stat().st_mtime_ns)
    s = np.asarray(scale, float)
    out = []
    for p in parts:
        n = p.normals / s
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
        faces = p.faces if np.prod(s) > 0 else p.faces[:, [0, 2, 1]]
        out.append(MeshPart(p.vertices * s, n, p.uv, faces, p.material))
    return out


@functools.lru_cache(maxsize=256)
def _load_parts(path: str, _mtime: int) -> tuple[MeshPart, ...]:
    import trimesh

    try:  # textures may lie outside the mesh's folder (pr2_drake.materials' cache)
        resolver = trimesh.resolvers.FilePathResolver(path, allow_anywhere=True)
    except TypeError:  # an older trimesh resolves any relative path
        resolver = trimesh.resolvers.FilePathResolver(path)
    with warnings.catch_warnings():  # trimesh's texture merge warns on untextured OBJ parts
        warnings.simplefilter("ignore", RuntimeWarning)
        loaded = trimesh.load(path, process=False, maintain_order=True, resolver=resolver)
    meshes = loaded.dump() if isinstance(loaded, trimesh.Scene) else [loaded]
    gltf = path.lower().endswith((".gltf", ".glb"))
    parts = []
    for m in meshes:
        if len(m.faces) == 0:
            continue
        v, n = np.asarray(m.vertices, float), np.asarray(m.vertex_normals, float)
        if gltf:
            v, n = v @ GLTF_TO_DRAKE.T, n @ GLTF_TO_DRAKE.T
        uv = getattr(m.visual, "uv", None)
        uv = None if uv is None or len(uv) != len(v) else np.asarray(uv, float)
        # A part of a multi-material file lists every vertex of the file: keep its own.
        used, faces = np.unique(np.asarray(m.faces, np.int64), return_inverse=True)
        parts.append(MeshPart(v[used], n[used], None if uv is None else uv[used],
                              faces.reshape(-1, 3),
                              _file_material(m.visual, "gltf" if gltf else "mtl")))
    if not parts:
        raise ValueError(f"mesh file has no triangles: {path}")
    return tuple(parts)


def _file_material(visual, kind: str) -> SurfaceMaterial | None:
    """The material a mesh file declares (trimesh's), or None if it declares none."""
    import trimesh

    mat = getattr(visual, "material", None)
    if mat is None:
        return None
    if isinstance(mat, trimesh.visual.material.PBRMaterial):
        factor = mat.baseColorFactor
        rgba = (np.ones(4) if factor is None else np.asarray(factor, float) / 255.0)
        # The testbed's colours are display (sRGB) colours wherever they are written, glTF
        # factors included (pr2_drake.materials puts the YAML colour there and VTK shows it
        # as it is): decoded, they look the same after the path tracer's sRGB view transform.
        rgba[:3] = srgb_to_linear(rgba[:3])
        image = mat.baseColorTexture
        return SurfaceMaterial(
            tuple(float(c) for c in rgba), _texture_file(image) if image is not None else None,
            float(1.0 if mat.roughnessFactor is None else mat.roughnessFactor),
            float(1.0 if mat.metallicFactor is None else mat.metallicFactor), kind)
    if isinstance(mat, trimesh.visual.material.SimpleMaterial):
        if getattr(mat, "name", None) in (None, "", "material_0", "default") and \
                mat.image is None and kind != "mtl":
            return None
        diffuse = np.asarray(mat.diffuse, float) / 255.0
        rgb = srgb_to_linear(diffuse[:3])
        image = mat.image
        return SurfaceMaterial((*map(float, rgb), float(diffuse[3])),
                               _texture_file(image) if image is not None else None,
                               _phong_roughness(getattr(mat, "glossiness", None)), 0.0, kind)
    return None


def _phong_roughness(shininess) -> float:
    """An OBJ's Phong exponent ``Ns`` as a roughness (Walter et al.'s conversion,
    alpha = sqrt(2 / (Ns + 2)), roughness = sqrt(alpha)), clamped to [0.2, 1]."""
    if shininess is None:
        return 0.6
    alpha = np.sqrt(2.0 / (float(shininess) + 2.0))
    return float(np.clip(np.sqrt(alpha), 0.2, 1.0))


def _texture_file(image) -> str:
    """A PNG of a PIL image in a content-keyed cache folder (written once)."""
    import io

    buf = io.BytesIO()
    image.save(buf, format="PNG")
    data = buf.getvalue()
    folder = Path(tempfile.gettempdir()) / "pr2_drake_render"
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"tex_{hashlib.sha1(data).hexdigest()[:20]}.png"
    if not path.is_file():
        tmp = path.with_suffix(".tmp")
        tmp.write_bytes(data)
        tmp.replace(path)
    return str(path)

"""Import a USD stage (.usda / .usd / .usdc) as an SDFormat model Drake can load.

Reads every ``UsdGeom.Mesh`` prim of the stage with ``pxr`` (points, face vertex counts and
indices, the prim's world transform, ``primvars:displayColor``), converts units to metres
(``metersPerUnit``) and a Y-up stage to Z-up, triangulates the faces (fans), and writes:

- one OBJ (+ MTL) per mesh prim, in the model frame (the stage's world frame, z up, m);
- one SDFormat model with one link: a visual per mesh (the OBJ, with its displayColor) and a
  collision per mesh, either the mesh's axis-aligned bounding box (``collision="box"``, exact
  for box-like furniture parts) or the mesh declared convex (``collision="convex"``; Drake
  uses its convex hull).

>>> sdf = import_usd("models/house/coffee_table.usda", static=True)
>>> Parser(plant).AddModels(str(sdf))

The output folder defaults to a cache under the system temp folder keyed by a hash of the
stage file and the options, so repeated builds reuse the converted files; the conversion is
deterministic. Nothing is downloaded.
"""

from __future__ import annotations

import hashlib
import re
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pr2_drake.assets.mesh_io import MeshPart, Primitive, write_obj, write_sdf

COLLISION_MODES = ("box", "convex", "none")
DEFAULT_COLOR = (0.7, 0.7, 0.7)


@dataclass
class UsdMesh:
    """A mesh prim in model coordinates: (N, 3) vertices [m], (M, 3) triangles, RGB colour."""

    path: str
    vertices: np.ndarray
    triangles: np.ndarray
    color: tuple[float, float, float]


def _triangulate(counts: np.ndarray, indices: np.ndarray, prim: str) -> np.ndarray:
    tris = []
    k = 0
    for n in counts:
        if n < 3:
            raise ValueError(f"{prim}: face with {n} vertices")
        face = indices[k:k + n]
        tris += [(face[0], face[i], face[i + 1]) for i in range(1, n - 1)]
        k += n
    if k != len(indices):
        raise ValueError(f"{prim}: faceVertexCounts sum {k} != {len(indices)} indices")
    return np.asarray(tris, dtype=int).reshape(-1, 3)


def read_usd_meshes(path: str | Path) -> list[UsdMesh]:
    """All ``UsdGeom.Mesh`` prims of the stage at ``path``, in metres, z up, world frame."""
    from pxr import Usd, UsdGeom

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"USD stage not found: {path}")
    stage = Usd.Stage.Open(str(path))
    if stage is None:
        raise ValueError(f"cannot open USD stage {path}")
    scale = float(UsdGeom.GetStageMetersPerUnit(stage))
    # Row-vector convention in USD: p_world = p_local * M. Convert Y-up to Z-up: (x, y, z) ->
    # (x, -z, y).
    up = np.eye(3)
    if UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y:
        up = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])
    cache = UsdGeom.XformCache(Usd.TimeCode.Default())
    meshes = []
    for prim in stage.Traverse():
        if not prim.IsA(UsdGeom.Mesh):
            continue
        if UsdGeom.Imageable(prim).ComputeVisibility() == UsdGeom.Tokens.invisible:
            continue
        mesh = UsdGeom.Mesh(prim)
        pts = mesh.GetPointsAttr().Get()
        counts = mesh.GetFaceVertexCountsAttr().Get()
        indices = mesh.GetFaceVertexIndicesAttr().Get()
        if pts is None or counts is None or indices is None or len(pts) == 0:
            continue
        M = np.array(cache.GetLocalToWorldTransform(prim), dtype=float)  # 4x4, row vectors
        P = np.asarray(pts, dtype=float)
        world = P @ M[:3, :3] + M[3, :3]
        vertices = (world @ up.T) * scale
        tris = _triangulate(np.asarray(counts, int), np.asarray(indices, int), str(prim.GetPath()))
        if np.linalg.det(M[:3, :3]) < 0:  # mirrored transform: keep faces outward
            tris = tris[:, ::-1]
        if mesh.GetOrientationAttr().Get() == UsdGeom.Tokens.leftHanded:
            tris = tris[:, ::-1]
        color = DEFAULT_COLOR
        colors = mesh.GetDisplayColorAttr().Get()
        if colors is not None and len(colors) > 0:
            color = tuple(float(c) for c in np.mean(np.asarray(colors, float), axis=0))
        meshes.append(UsdMesh(str(prim.GetPath()), vertices, tris, color))
    if not meshes:
        raise ValueError(f"{path}: no UsdGeom.Mesh prims found")
    return meshes


def _safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_]+", "_", name).strip("_") or "mesh"


def default_cache_dir(path: Path, key: str) -> Path:
    digest = hashlib.sha1(Path(path).read_bytes() + key.encode()).hexdigest()[:16]
    return Path(tempfile.gettempdir()) / "pr2_drake_usd" / f"{Path(path).stem}_{digest}"


def import_usd(
    path: str | Path,
    out_dir: str | Path | None = None,
    *,
    name: str | None = None,
    mass: float = 1.0,
    collision: str = "box",
    static: bool = False,
    friction: float = 0.8,
) -> Path:
    """Convert the stage at ``path`` to OBJ meshes + an SDFormat model; returns the .sdf path.

    Args:
        out_dir: where to write (default: a per-content cache under the temp folder).
        name: model and link name (default: the file stem).
        mass: total mass [kg] for a dynamic model, spread uniformly over the meshes' bounding
            boxes (inertia about the combined centre of mass).
        collision: "box" (axis-aligned box per mesh), "convex" (mesh declared convex) or "none".
        static: write ``<static>`` (the model is welded to the world where it is loaded).
    """
    if collision not in COLLISION_MODES:
        raise ValueError(f"collision must be one of {COLLISION_MODES}, got {collision!r}")
    if not mass > 0:
        raise ValueError(f"mass must be positive, got {mass}")
    path = Path(path)
    name = name or _safe(path.stem)
    key = f"{name}|{mass}|{collision}|{static}|{friction}|v2"
    out = Path(out_dir) if out_dir is not None else default_cache_dir(path, key)
    sdf = out / f"{name}.sdf"
    if out_dir is None and sdf.is_file():
        return sdf
    meshes = read_usd_meshes(path)
    out.mkdir(parents=True, exist_ok=True)
    visuals, prims, convex, boxes = [], [], [], []
    for i, m in enumerate(meshes):
        fname = f"{i:02d}_{_safe(m.path)}.obj"
        write_obj(out / fname, [MeshPart(m.vertices, m.triangles, f"mat_{i}", (*m.color, 1.0))])
        visuals.append((fname, None))  # colour from the MTL file
        lo, hi = m.vertices.min(axis=0), m.vertices.max(axis=0)
        boxes.append((lo, hi))
        if collision == "box":
            prims.append(Primitive("box", list(np.maximum(hi - lo, 1e-4)), list((lo + hi) / 2)))
        elif collision == "convex":
            convex.append(fname)
    com, inertia = _box_inertia(boxes, mass)
    write_sdf(sdf, name, visuals, prims, None if static else mass, com, inertia,
              friction=friction, collision_meshes=convex, static=static)
    return sdf


def _box_inertia(boxes: list[tuple[np.ndarray, np.ndarray]], mass: float):
    """Centre of mass and inertia [kg m^2] of solid boxes of uniform density."""
    vols = np.array([np.prod(np.maximum(hi - lo, 1e-4)) for lo, hi in boxes])
    masses = mass * vols / vols.sum()
    centers = np.array([(lo + hi) / 2 for lo, hi in boxes])
    com = masses @ centers / mass
    inertia = np.zeros((3, 3))
    for m, (lo, hi), c in zip(masses, boxes, centers):
        a, b, h = np.maximum(hi - lo, 1e-4)
        inertia += np.diag([m * (b * b + h * h), m * (a * a + h * h), m * (a * a + b * b)]) / 12
        d = c - com
        inertia += m * (d @ d * np.eye(3) - np.outer(d, d))
    return com, inertia

"""PBR materials for scene geometry: textured boxes written as glTF and registered as visuals.

Drake's RenderEngineVtk shades glTF files with their PBR materials (base colour texture x
factor, metallic, roughness) and lights them with the image-based environment map; primitives
(``Box``) can only carry a Phong colour and a texture stretched over each face. So a textured
surface here is a glTF box (or a batch of boxes merged into one file) whose texture coordinates
are in metres divided by the material's tile size: textures repeat at their real-world scale on
every face. Collision geometry stays the plain ``Box``.

Materials live in ``models/textures/materials.yaml``; the textures are made by
:mod:`pr2_drake.assets.make_textures`. The base colour factor is the surface's YAML colour, the
texture a near-grey detail map, so hues are exactly those of the task files. Generated files go
to a content-keyed cache under the temp folder (nothing is downloaded).

The ``low`` render preset draws the same boxes as plain ``Box`` primitives in their YAML colour
(Phong shading, no textures): a glTF file switches Drake's VTK engine to PBR shading for the
whole scene, which costs about half as much again per frame on a software rasteriser. The
testbed picks the style with :func:`visual_style` while it builds the scene.
"""

from __future__ import annotations

import base64
import contextlib
import contextvars
import functools
import hashlib
import json
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np
from pydrake.common.yaml import yaml_load_file
from pydrake.geometry import (Box, GeometryInstance, IllustrationProperties, Mesh,
                              PerceptionProperties)
from pydrake.math import RigidTransform
from pydrake.multibody.plant import CoulombFriction, MultibodyPlant

from pr2_drake.paths import data_path


@dataclass(frozen=True)
class Material:
    """A PBR material: ``texture`` file in models/textures (None: untextured), ``tile`` [m]
    (one texture repeat on the surface), ``roughness`` and ``metallic`` in [0, 1]."""

    texture: str | None = None
    tile: float = 1.0
    roughness: float = 0.8
    metallic: float = 0.0


@functools.lru_cache(maxsize=1)
def materials() -> dict[str, Material]:
    """The materials of ``models/textures/materials.yaml`` by name."""
    raw = yaml_load_file(str(data_path("models", "textures", "materials.yaml")))
    return {name: Material(**cfg) for name, cfg in raw.items()}


def material(name: str) -> Material:
    try:
        return materials()[name]
    except KeyError:
        raise ValueError(f"unknown material {name!r}; known: {sorted(materials())}") from None


STYLES = ("pbr", "phong")
_STYLE: contextvars.ContextVar[str] = contextvars.ContextVar("pr2_drake_visual_style",
                                                            default="pbr")


@contextlib.contextmanager
def visual_style(style: str):
    """Within the block, textured boxes are drawn as ``"pbr"`` (glTF, textured; the default)
    or ``"phong"`` (plain coloured ``Box`` primitives, the fast ``low`` preset)."""
    if style not in STYLES:
        raise ValueError(f"visual style must be one of {STYLES}, got {style!r}")
    token = _STYLE.set(style)
    try:
        yield
    finally:
        _STYLE.reset(token)


def _cache_dir() -> Path:
    d = Path(tempfile.gettempdir()) / "pr2_drake_gltf"
    d.mkdir(parents=True, exist_ok=True)
    return d


# Box faces: (normal axis, sign, u axis, v axis).
_FACES = [(0, 1, 1, 2), (0, -1, 1, 2), (1, 1, 0, 2), (1, -1, 0, 2), (2, 1, 0, 1), (2, -1, 0, 1)]


def box_arrays(size, X: RigidTransform, tile: float):
    """Vertices (24x3, in the frame of X, glTF's y-up axes), normals, texture coordinates
    [m / tile] and triangle indices of a box of full ``size`` [m] posed by ``X``."""
    pos, nrm, uv, idx = _box_faces(size, X, tile)
    # glTF is y-up; Drake turns a glTF file's (x, y, z) into its own (x, -z, y).
    to_gltf = np.array([[1, 0, 0], [0, 0, 1], [0, -1, 0]], float)
    return (np.asarray(pos, np.float32) @ to_gltf.T.astype(np.float32),
            np.asarray(nrm, np.float32) @ to_gltf.T.astype(np.float32),
            np.asarray(uv, np.float32), np.asarray(idx, np.uint32))


def _box_faces(size, X: RigidTransform, tile: float):
    """As :func:`box_arrays`, in the frame of X itself (lists)."""
    h = np.asarray(size, float) / 2
    R, p = X.rotation().matrix(), X.translation()
    pos, nrm, uv, idx = [], [], [], []
    for axis, sign, a, b in _FACES:
        base = len(pos)
        for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
            v = np.zeros(3)
            v[axis], v[a], v[b] = sign * h[axis], su * h[a], sv * h[b]
            pos.append(R @ v + p)
            n = np.zeros(3)
            n[axis] = sign
            nrm.append(R @ n)
            # Texture coordinates in metres / tile (box frame shifted by the box's position:
            # equal to world coordinates for unrotated boxes, so neighbours line up).
            uv.append([(v[a] + p[a]) / tile, (v[b] + p[b]) / tile])
        quad = [0, 1, 2, 0, 2, 3] if sign > 0 else [0, 2, 1, 0, 3, 2]
        if axis == 1:  # (x, z) basis has the opposite handedness
            quad = [0, 2, 1, 0, 3, 2] if sign > 0 else [0, 1, 2, 0, 2, 3]
        idx += [base + q for q in quad]
    return pos, nrm, uv, idx


def write_boxes_obj(boxes: Sequence[tuple[RigidTransform, Sequence[float]]]) -> Path:
    """One OBJ file (positions, flat normals, triangles) holding every (pose, size) box, in
    the frame the poses are given in: one draw call for the renderer instead of one a box."""
    pos, nrm, tri = [], [], []
    for k, (X, size) in enumerate(boxes):
        p, n, _, idx = _box_faces(size, X, 1.0)
        pos += p
        nrm += n
        tri.append(np.asarray(idx).reshape(-1, 3) + 24 * k + 1)  # OBJ counts from 1
    lines = [f"v {a:.6f} {b:.6f} {c:.6f}" for a, b, c in pos]
    lines += [f"vn {a:.6f} {b:.6f} {c:.6f}" for a, b, c in nrm]
    lines += [f"f {a}//{a} {b}//{b} {c}//{c}" for a, b, c in np.concatenate(tri).tolist()]
    text = "\n".join(lines) + "\n"
    path = _cache_dir() / f"boxes_{hashlib.sha1(text.encode()).hexdigest()[:20]}.obj"
    if not path.is_file():
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(text)
        tmp.replace(path)  # atomic: parallel episodes may write the same file
    return path


def write_boxes_gltf(boxes: Sequence[tuple[RigidTransform, Sequence[float]]], rgba,
                     mat: Material) -> Path:
    """One glTF file holding every (pose, size) box, in the frame the poses are given in."""
    parts = [box_arrays(size, X, mat.tile) for X, size in boxes]
    pos = np.concatenate([q[0] for q in parts])
    nrm = np.concatenate([q[1] for q in parts])
    uv = np.concatenate([q[2] for q in parts])
    idx = np.concatenate([q[3] + 24 * k for k, q in enumerate(parts)]).astype(np.uint32)
    color = [float(c) for c in rgba] + ([1.0] if len(rgba) == 3 else [])
    # The texture's absolute path is in the key: the file refers to it by a relative path, so
    # another checkout (or a moved one) must not reuse a file that points into this one.
    texture = data_path("models", "textures", mat.texture) if mat.texture else None
    key = hashlib.sha1(pos.tobytes() + uv.tobytes()
                       + repr((color, mat, str(texture))).encode()).hexdigest()[:20]
    path = _cache_dir() / f"box_{key}.gltf"
    if path.is_file():
        return path
    blob = pos.tobytes() + nrm.tobytes() + uv.tobytes() + idx.tobytes()
    n, offsets = len(pos), np.cumsum([0, pos.nbytes, nrm.nbytes, uv.nbytes])
    pbr = {"baseColorFactor": color, "metallicFactor": mat.metallic,
           "roughnessFactor": mat.roughness}
    doc = {
        "asset": {"version": "2.0", "generator": "pr2_drake.materials"},
        "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2},
                                    "indices": 3, "material": 0}]}],
        "materials": [{"pbrMetallicRoughness": pbr, "doubleSided": False}],
        "buffers": [{"byteLength": len(blob), "uri": "data:application/octet-stream;base64,"
                     + base64.b64encode(blob).decode()}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": int(offsets[0]), "byteLength": pos.nbytes, "target": 34962},
            {"buffer": 0, "byteOffset": int(offsets[1]), "byteLength": nrm.nbytes, "target": 34962},
            {"buffer": 0, "byteOffset": int(offsets[2]), "byteLength": uv.nbytes, "target": 34962},
            {"buffer": 0, "byteOffset": int(offsets[3]), "byteLength": idx.nbytes, "target": 34963},
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": n, "type": "VEC3",
             "min": pos.min(0).tolist(), "max": pos.max(0).tolist()},
            {"bufferView": 1, "componentType": 5126, "count": n, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5126, "count": n, "type": "VEC2"},
            {"bufferView": 3, "componentType": 5125, "count": len(idx), "type": "SCALAR"},
        ],
    }
    if texture is not None:
        doc["images"] = [{"uri": os.path.relpath(texture, path.parent)}]
        doc["samplers"] = [{"magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 10497}]
        doc["textures"] = [{"sampler": 0, "source": 0}]
        pbr["baseColorTexture"] = {"index": 0}
    tmp = path.with_suffix(f".{os.getpid()}.tmp")
    tmp.write_text(json.dumps(doc))
    tmp.replace(path)  # atomic: parallel episodes may write the same file
    return path


def add_textured_boxes(plant: MultibodyPlant, name: str,
                       boxes: Sequence[tuple[RigidTransform, Sequence[float]]], rgba,
                       material_name: str, body=None) -> None:
    """Register the boxes (poses in ``body``, default the world) as one visual-only mesh: a
    textured glTF (``"pbr"`` style), or an OBJ in the flat colour (``"phong"``; one box stays
    a ``Box``)."""
    body = plant.world_body() if body is None else body
    mat = material(material_name)
    if _STYLE.get() == "phong":
        color = np.asarray([float(c) for c in rgba] + ([1.0] if len(rgba) == 3 else []))
        if len(boxes) == 1:
            X, size = boxes[0]
            plant.RegisterVisualGeometry(body, X, Box(*[float(v) for v in size]), name, color)
        else:  # one mesh: VTK draws each geometry separately (488 stones on the rocky road)
            plant.RegisterVisualGeometry(body, RigidTransform(), Mesh(str(write_boxes_obj(boxes))),
                                         name, color)
        return
    path = write_boxes_gltf(boxes, rgba, mat)
    # No Drake material on the instance: the glTF's own PBR material is what renders.
    instance = GeometryInstance(RigidTransform(), Mesh(str(path)), name)
    instance.set_illustration_properties(IllustrationProperties())
    instance.set_perception_properties(PerceptionProperties())
    plant.RegisterVisualGeometry(body, instance)


def add_textured_box(plant: MultibodyPlant, name: str, X: RigidTransform, size, rgba,
                     material_name: str, friction: CoulombFriction | None = None,
                     body=None) -> None:
    """A box whose visual is textured (glTF) and, with ``friction``, whose collision is a
    plain ``Box`` of the same size and pose (in ``body``, default the world)."""
    add_textured_boxes(plant, name, [(X, size)], rgba, material_name, body)
    if friction is not None:
        body = plant.world_body() if body is None else body
        plant.RegisterCollisionGeometry(body, X, Box(*[float(s) for s in size]), name, friction)

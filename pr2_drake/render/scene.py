"""The scene a path tracer draws, read from Drake's SceneGraph: every perception geometry
(what the head camera's VTK renderer draws), its triangles, its material and its pose.

One description feeds every engine: :func:`export_scene` walks the SceneGraph once (shapes
and materials do not move), :func:`geometry_poses` reads the world poses of a given context.
Materials are those the raster renderer uses: a mesh file's own (the glTF PBR materials of
:mod:`pr2_drake.materials`, from ``models/textures/materials.yaml``, or an OBJ's ``.mtl``),
else the geometry's ``phong/diffuse`` colour with the roughness of
``models/textures/path_tracing.yaml``. The sun and sky are those of :mod:`pr2_drake.camera`
(``SUN_DIRECTION``, ``SUN_COLOR``, ``models/textures/sky.png``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from pydrake.geometry import Role

from pr2_drake.render import meshes
from pr2_drake.render.meshes import MeshPart, SurfaceMaterial


@dataclass
class SceneObject:
    """One perception geometry: its ``parts`` (triangles in the geometry frame G, each with
    its material), ``name`` and ``geometry`` (the SceneGraph's GeometryId, as an int)."""

    name: str
    geometry: int
    parts: list[MeshPart]


@dataclass
class SceneExport:
    """Every perception geometry of a SceneGraph, ready for a path tracer.

    Attributes:
        objects: one per geometry, in the inspector's order.
        ground_material: the material of the geometry named ``ground`` (None: no such
            geometry); the engines extend it to the horizon.
        ground_height: z of the top of that ground [m].
        ground_uv_map: (3, 2) texture coordinates of the ground's top as a function of world
            (x, y, 1): ``uv = [x, y, 1] @ ground_uv_map``.
    """

    objects: list[SceneObject] = field(default_factory=list)
    ground_material: SurfaceMaterial | None = None
    ground_height: float = 0.0
    ground_uv_map: np.ndarray = field(default_factory=lambda: np.zeros((3, 2)))


def export_scene(scene_graph, context, settings) -> SceneExport:
    """The perception geometry of ``scene_graph`` (its ``context`` gives the poses of
    anchored geometry), with the default roughness of ``settings``
    (:class:`pr2_drake.render.settings.PathTracingSettings`) for flat colours."""
    query = scene_graph.get_query_output_port().Eval(context)
    inspector = query.inspector()
    out = SceneExport()
    for g in inspector.GetAllGeometryIds(Role.kPerception):
        props = inspector.GetPerceptionProperties(g)
        name = inspector.GetName(g)
        parts = shape_parts(inspector.GetShape(g))
        fallback = phong_material(props, settings)
        parts = [MeshPart(p.vertices, p.normals, p.uv, p.faces, p.material or fallback)
                 for p in parts]
        out.objects.append(SceneObject(name, int(g.get_value()), parts))
        if name == GROUND and inspector.GetFrameId(g) == inspector.world_frame_id():
            _set_ground(out, parts[0], query.GetPoseInWorld(g).GetAsMatrix4())
    return out


GROUND = "ground"  # the name of the scenes' ground geometry (pr2_drake.scene, the tasks)


def _set_ground(out: SceneExport, part: MeshPart, X_WG: np.ndarray) -> None:
    """The ground's material, the height of its top and (when textured) the map from world
    (x, y) to its texture coordinates, fitted on its top face."""
    p_W = part.vertices @ X_WG[:3, :3].T + X_WG[:3, 3]
    n_W = part.normals @ X_WG[:3, :3].T
    top = n_W[:, 2] > 0.99
    out.ground_material = part.material
    out.ground_height = float(p_W[top, 2].max()) if top.any() else float(p_W[:, 2].max())
    if part.uv is not None and top.sum() >= 3:
        A = np.column_stack([p_W[top, :2], np.ones(top.sum())])
        out.ground_uv_map = np.linalg.lstsq(A, part.uv[top], rcond=None)[0]


def phong_material(props, settings) -> SurfaceMaterial:
    """The material of a geometry without a file material: its ``phong/diffuse`` colour
    (sRGB as the raster renderer shows it; Drake's default grey without one) and
    ``phong/diffuse_map`` texture, with ``settings.roughness`` and no metal."""
    rgba = (0.9, 0.9, 0.9, 1.0)  # Drake's default diffuse colour
    if props is not None and props.HasProperty("phong", "diffuse"):
        rgba = tuple(props.GetProperty("phong", "diffuse").rgba)
    texture = None
    if props is not None and props.HasProperty("phong", "diffuse_map"):
        texture = str(props.GetProperty("phong", "diffuse_map"))
    rgb = meshes.srgb_to_linear(rgba[:3])
    return SurfaceMaterial((*map(float, rgb), float(rgba[3])), texture, settings.roughness,
                           0.0, "phong")


def shape_parts(shape) -> list[MeshPart]:
    """Triangles of a Drake shape in its own frame (see :mod:`pr2_drake.render.meshes`)."""
    kind = type(shape).__name__
    if kind == "Box":
        return [meshes.box(shape.size())]
    if kind == "Sphere":
        return [meshes.sphere(shape.radius())]
    if kind == "Ellipsoid":
        return [meshes.ellipsoid(shape.a(), shape.b(), shape.c())]
    if kind == "Cylinder":
        return [meshes.cylinder(shape.radius(), shape.length())]
    if kind == "Capsule":
        return [meshes.capsule(shape.radius(), shape.length())]
    if kind in ("Mesh", "Convex"):
        source = shape.source()
        if not source.is_path():
            raise ValueError(f"the path tracer reads mesh files only; {shape} is in memory")
        return meshes.mesh_file_parts(source.path(), shape.scale3())
    raise ValueError(f"the path tracer cannot draw a {kind} perception geometry")


def geometry_poses(scene_graph, context) -> dict[int, np.ndarray]:
    """{geometry id: X_WG as a 4x4 matrix} of every perception geometry at ``context``
    (the SceneGraph's own context)."""
    query = scene_graph.get_query_output_port().Eval(context)
    inspector = query.inspector()
    return {int(g.get_value()): query.GetPoseInWorld(g).GetAsMatrix4()
            for g in inspector.GetAllGeometryIds(Role.kPerception)}

"""The path tracer: Blender's Cycles on the CPU, through the ``bpy`` wheel (the
``[photoreal]`` extra).

:class:`CyclesRenderer` builds a Blender scene once from a :class:`SceneExport` (one object per
mesh part, with its Principled BSDF material), lights it with the sky map as an environment
(image-based light: diffuse sky and reflections) and the sun as a sun lamp of finite angular
size (soft shadows), carries the ground to the horizon on a large disc, and renders a
:class:`CameraView` after :meth:`CyclesRenderer.set_poses` moved the objects. ``bpy`` holds one
scene per process: one renderer at a time.
"""

from __future__ import annotations

import contextlib
import math
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

from pr2_drake.render import INSTALL_HINT
from pr2_drake.render.light import Lighting
from pr2_drake.render.meshes import SurfaceMaterial
from pr2_drake.render.scene import SceneExport
from pr2_drake.render.settings import PathTracingSettings
from pr2_drake.render.view import CameraView

# Drake's camera frame (+z forward, +y down) to Blender's (-z forward, +y up).
DRAKE_TO_BLENDER_CAMERA = np.diag([1.0, -1.0, -1.0, 1.0])


def import_bpy():
    """``bpy``, or ImportError with the one line that says what to install."""
    try:
        import bpy
    except ImportError as e:
        raise ImportError(f"{INSTALL_HINT} ({e})") from None
    return bpy


class CyclesRenderer:
    """A Blender scene of an exported SceneGraph, rendered by Cycles on the CPU.

    Args:
        scene: the exported geometry and materials (:func:`export_scene`).
        settings: film and light paths (:class:`PathTracingSettings`).
        lighting: sun and sky (:func:`pr2_drake.render.light.testbed_lighting`).
    """

    def __init__(self, scene: SceneExport, settings: PathTracingSettings, lighting: Lighting):
        self.bpy = import_bpy()
        self.settings = settings
        self._materials: dict[SurfaceMaterial, object] = {}
        self._objects: dict[int, list] = {}
        with _quiet():  # (Cycles probes GPU libraries as it starts and says so)
            self._build(scene, lighting)
        self._out = tempfile.TemporaryDirectory(prefix="pr2_drake_cycles_")  # removed with self

    def _build(self, scene: SceneExport, lighting: Lighting) -> None:
        bpy = self.bpy
        bpy.ops.wm.read_factory_settings(use_empty=True)
        self.scene = bpy.context.scene
        for obj in scene.objects:
            self._objects[obj.geometry] = [
                self._add_part(f"{obj.name}.{k}", part) for k, part in enumerate(obj.parts)]
        if scene.ground_material is not None:
            self._add_horizon(scene)
        self._add_sky(lighting)
        self._add_sun(lighting)
        cam = bpy.data.cameras.new("camera")
        cam.sensor_fit = "VERTICAL"
        cam.clip_start, cam.clip_end = 0.01, 2.5 * self.settings.ground_radius
        self.camera = bpy.data.objects.new("camera", cam)
        self.scene.collection.objects.link(self.camera)
        self.scene.camera = self.camera
        self._setup_film()

    # -- scene ----------------------------------------------------------------------------------
    def _add_part(self, name: str, part, matrix=None):
        bpy = self.bpy
        mesh = bpy.data.meshes.new(name)
        mesh.from_pydata(part.vertices.tolist(), [], part.faces.tolist())
        mesh.polygons.foreach_set("use_smooth", np.ones(len(part.faces), bool))
        if part.uv is not None:
            layer = mesh.uv_layers.new(name="UVMap")
            layer.data.foreach_set("uv", part.uv[part.faces.ravel()].astype(np.float32).ravel())
        mesh.normals_split_custom_set_from_vertices(part.normals.tolist())
        mesh.materials.append(self._material(part.material))
        mesh.update()
        obj = bpy.data.objects.new(name, mesh)
        self.scene.collection.objects.link(obj)
        return obj

    def _material(self, m: SurfaceMaterial):
        if m in self._materials:
            return self._materials[m]
        mat = self.bpy.data.materials.new(f"material{len(self._materials)}")
        mat.use_nodes = True
        nodes, links = mat.node_tree.nodes, mat.node_tree.links
        bsdf = nodes["Principled BSDF"]
        bsdf.inputs["Base Color"].default_value = m.base_color
        bsdf.inputs["Roughness"].default_value = m.roughness
        bsdf.inputs["Metallic"].default_value = m.metallic
        bsdf.inputs["Alpha"].default_value = m.base_color[3]  # translucent zones and markers
        if m.texture:
            tex = nodes.new("ShaderNodeTexImage")
            tex.image = self.bpy.data.images.load(str(m.texture), check_existing=True)
            mix = nodes.new("ShaderNodeMix")
            mix.data_type, mix.blend_type = "RGBA", "MULTIPLY"
            mix.inputs["Factor"].default_value = 1.0
            mix.inputs[7].default_value = m.base_color  # B (colour)
            links.new(tex.outputs["Color"], mix.inputs[6])  # A (colour)
            links.new(mix.outputs[2], bsdf.inputs["Base Color"])
        _cull_back_faces(nodes, links, bsdf)
        self._materials[m] = mat
        return mat

    def _add_horizon(self, scene: SceneExport) -> None:
        """A disc of the ground's material out to ``ground_radius``, 5 mm below the ground's
        top (the ground box hides it where they overlap), its texture at the ground's scale."""
        from pr2_drake.render.meshes import MeshPart

        r = np.concatenate([[0.0], np.geomspace(1.0, self.settings.ground_radius, 24)])
        phi = np.arange(64) * 2 * math.pi / 64
        rr, pp = np.meshgrid(r, phi, indexing="ij")
        xy = np.stack([rr * np.cos(pp), rr * np.sin(pp)], -1).reshape(-1, 2)
        verts = np.column_stack([xy, np.full(len(xy), scene.ground_height - 0.005)])
        faces = []
        for i in range(len(r) - 1):
            for j in range(64):
                a, b = i * 64 + j, i * 64 + (j + 1) % 64
                faces += [[a, a + 64, b + 64], [a, b + 64, b]]
        uv = np.column_stack([xy, np.ones(len(xy))]) @ scene.ground_uv_map
        part = MeshPart(verts, np.tile([0.0, 0.0, 1.0], (len(verts), 1)), uv,
                        np.array(faces), scene.ground_material)
        self._add_part("horizon", part)

    def _add_sky(self, light: Lighting) -> None:
        bpy = self.bpy
        world = bpy.data.worlds.new("sky")
        self.scene.world = world
        world.use_nodes = True
        nodes, links = world.node_tree.nodes, world.node_tree.links
        env = nodes.new("ShaderNodeTexEnvironment")
        env.image = bpy.data.images.load(light.sky, check_existing=True)
        coords = nodes.new("ShaderNodeTexCoord")
        mapping = nodes.new("ShaderNodeMapping")
        # The map's column u looks at azimuth u/W * 360 deg from +x towards +y
        # (pr2_drake.environment_light); Blender's runs the other way round from -x.
        mapping.inputs["Scale"].default_value = (1.0, -1.0, 1.0)
        links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
        links.new(mapping.outputs["Vector"], env.inputs["Vector"])
        balance = nodes.new("ShaderNodeMix")  # the white balance: map x gain
        balance.data_type, balance.blend_type = "RGBA", "MULTIPLY"
        balance.inputs["Factor"].default_value = 1.0
        balance.inputs[7].default_value = (*light.sky_gain, 1.0)
        links.new(env.outputs["Color"], balance.inputs[6])
        background = nodes["Background"]
        links.new(balance.outputs[2], background.inputs["Color"])
        background.inputs["Strength"].default_value = light.sky_strength

    def _add_sun(self, light: Lighting) -> None:
        bpy = self.bpy
        sun = bpy.data.lights.new("sun", "SUN")
        sun.energy = light.sun_strength
        sun.angle = math.radians(light.sun_angle_deg)
        sun.color = light.sun_color
        obj = bpy.data.objects.new("sun", sun)
        z = -np.asarray(light.sun_direction, float)
        z /= np.linalg.norm(z)  # the lamp shines along its local -z
        x = np.cross([0.0, 0.0, 1.0], z)
        x = x / np.linalg.norm(x) if np.linalg.norm(x) > 1e-9 else np.array([1.0, 0, 0])
        X = np.eye(4)
        X[:3, :3] = np.column_stack([x, np.cross(z, x), z])
        obj.matrix_world = _matrix(X)
        self.scene.collection.objects.link(obj)

    def _setup_film(self) -> None:
        s, c = self.settings, self.scene.cycles
        self.scene.render.engine = "CYCLES"
        c.device = "CPU"
        c.seed = 0
        c.use_adaptive_sampling = False
        c.max_bounces = s.max_bounces
        c.diffuse_bounces = c.glossy_bounces = min(s.max_bounces, 4)
        c.transmission_bounces = c.volume_bounces = 0
        c.transparent_max_bounces = 8  # camera rays through back faces (_cull_back_faces)
        c.sample_clamp_indirect = s.clamp_indirect
        c.caustics_reflective = c.caustics_refractive = False
        c.denoiser = "OPENIMAGEDENOISE"
        self.scene.render.use_persistent_data = True
        self.scene.render.resolution_percentage = 100
        self.scene.render.image_settings.file_format = "PNG"
        self.scene.render.image_settings.color_mode = "RGB"
        self.scene.render.image_settings.color_depth = "8"
        self.scene.view_settings.view_transform = s.view_transform
        self.scene.view_settings.exposure = s.exposure

    # -- per frame ------------------------------------------------------------------------------
    def set_poses(self, poses: dict[int, np.ndarray]) -> None:
        """Move each geometry's objects to X_WG (4x4, by geometry id)."""
        for geometry, objs in self._objects.items():
            m = _matrix(poses[geometry])
            for obj in objs:
                obj.matrix_world = m

    def render(self, view: CameraView, samples: int, denoise: bool = True,
               threads: int = 0) -> np.ndarray:
        """An (H, W, 3) uint8 sRGB image of the view with ``samples`` per pixel; the
        denoiser (OpenImageDenoise) on or off; ``threads`` 0: every core."""
        scene, cam = self.scene, self.camera.data
        scene.render.resolution_x, scene.render.resolution_y = view.width, view.height
        scene.render.threads_mode = "FIXED" if threads else "AUTO"
        if threads:
            scene.render.threads = threads
        scene.cycles.samples = int(samples)
        scene.cycles.use_denoising = bool(denoise)
        cam.angle_y = math.radians(view.fov_y_deg)
        cam.dof.use_dof = view.focus_distance is not None
        if view.focus_distance is not None:
            cam.dof.focus_distance = float(view.focus_distance)
            cam.dof.aperture_fstop = float(view.f_stop)
        self.camera.matrix_world = _matrix(np.asarray(view.X_WC) @ DRAKE_TO_BLENDER_CAMERA)
        path = Path(self._out.name) / "frame.png"
        scene.render.filepath = str(path)
        with _quiet():
            self.bpy.ops.render.render(write_still=True)
        import cv2

        image = cv2.imread(str(path), cv2.IMREAD_COLOR)
        if image is None:
            raise RuntimeError(f"Cycles wrote no image to {path}")
        return np.ascontiguousarray(image[..., ::-1])


@contextlib.contextmanager
def _quiet():
    """Silence what Blender prints itself (a line per frame and per file written, device
    probes) on the process's stdout and stderr; Python exceptions still carry its errors."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(1), os.dup(2)]
    null = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(null, 1)
        os.dup2(null, 2)
        yield
    finally:
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for fd in (*saved, null):
            os.close(fd)


def _cull_back_faces(nodes, links, bsdf) -> None:
    """Camera rays pass through back faces, as the raster's back-face culling lets them
    (the head camera sits inside the head's mesh); shadows and bounces see both sides."""
    geometry, path = nodes.new("ShaderNodeNewGeometry"), nodes.new("ShaderNodeLightPath")
    both = nodes.new("ShaderNodeMath")
    both.operation = "MULTIPLY"
    links.new(geometry.outputs["Backfacing"], both.inputs[0])
    links.new(path.outputs["Is Camera Ray"], both.inputs[1])
    mix = nodes.new("ShaderNodeMixShader")
    links.new(both.outputs[0], mix.inputs["Fac"])
    links.new(bsdf.outputs["BSDF"], mix.inputs[1])
    links.new(nodes.new("ShaderNodeBsdfTransparent").outputs["BSDF"], mix.inputs[2])
    links.new(mix.outputs["Shader"], nodes["Material Output"].inputs["Surface"])


def _matrix(X: np.ndarray):
    from mathutils import Matrix

    return Matrix([[float(v) for v in row] for row in np.asarray(X)])

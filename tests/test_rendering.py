"""Rendered scenes: textured materials, one shadow-casting sun, no black slabs, repeatable
renders, and the head-camera video."""

import cv2
import numpy as np
import pytest
from pydrake.geometry import (
    ClippingRange,
    ColorRenderCamera,
    MakeRenderEngineVtk,
    RenderCameraCore,
)
from pydrake.geometry import Mesh
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.sensors import CameraInfo

from pr2_drake.camera import PRESETS, CameraSettings, renderer_params
from pr2_drake.materials import (Material, add_textured_box, materials, write_boxes_gltf,
                                 write_boxes_obj)
from pr2_drake.scenario import Scenario
from pr2_drake.testbed import TestbedConfig
from pr2_drake.viz import look_at, render_task_views

SIZE = (96, 72)  # [px] small renders: the checks are about content, not detail


def _luma(rgb: np.ndarray) -> np.ndarray:
    return rgb.astype(float) @ [0.299, 0.587, 0.114]


def test_every_material_shows_texture_variance():
    """A 3 m square of each material, 1.5 m below a 96x96 camera (``medium`` lights), is not
    flat: its detail (luma minus a 6-px blur, which removes shading gradients) varies several
    times more than on an untextured glTF box of the same colour."""
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, 0.0)
    names = sorted(materials())
    grey = (0.7, 0.7, 0.7, 1.0)
    for k, name in enumerate(names):
        add_textured_box(plant, name, RigidTransform([10.0 * k, 0, 0]), (3, 3, 0.1), grey, name)
    untextured = write_boxes_gltf([(RigidTransform([-10.0, 0, 0]), (3, 3, 0.1))], grey,
                                  Material(texture=None))
    plant.RegisterVisualGeometry(plant.world_body(), RigidTransform(), Mesh(str(untextured)),
                                 "untextured", np.array(grey))
    names.append("untextured")
    centre = {name: 10.0 * k for k, name in enumerate(names)}
    centre["untextured"] = -10.0
    plant.Finalize()
    scene_graph.AddRenderer("test", MakeRenderEngineVtk(renderer_params("medium")))
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    query = scene_graph.get_query_output_port().Eval(scene_graph.GetMyContextFromRoot(context))
    camera = ColorRenderCamera(RenderCameraCore("test", CameraInfo(96, 96, np.radians(40)),
                                                ClippingRange(0.1, 10.0), RigidTransform()))
    spread = {}
    for name in names:
        x = centre[name]
        X_WC = look_at(np.array([x, 0.0, 1.5]), np.array([x + 1e-3, 0.0, 0.0]))
        image = query.RenderColorImage(camera, scene_graph.world_frame_id(), X_WC)
        luma = _luma(image.data[:, :, :3])
        detail = luma - cv2.GaussianBlur(luma, (0, 0), 6.0)  # shading gradients removed
        spread[name] = float(np.std(detail[8:-8, 8:-8]))
    reference = spread.pop("untextured")
    flat = [n for n, s in spread.items() if s < max(0.8, 3 * reference)]
    assert not flat, f"flat materials (detail std, untextured {reference:.2f}): {spread}"


@pytest.mark.parametrize("quality", ["medium", "high"])
def test_one_light_casts_shadows(quality):
    """Shadows come from the sun only: one directional light; the sky lights are point lights,
    which cast no shadows in Drake's VTK engine (no duplicated robot shadows)."""
    lights = renderer_params(quality).lights
    assert PRESETS[quality].shadows
    assert [light.type for light in lights].count("directional") == 1
    assert {light.type for light in lights} <= {"directional", "point"}


@pytest.mark.parametrize("task", [1, 2, 3, 4, 5, 6])
def test_high_quality_overview_has_no_black_slabs(task):
    """At ``high`` (sun shadows, ambient occlusion, tone mapping) each task's overview and
    head-camera view are neither crushed to black nor blown to white."""
    cfg = TestbedConfig(task=task, seed=0, camera=CameraSettings(quality="high"))
    overview, head = render_task_views(cfg, size=SIZE)
    for name, image in (("overview", overview), ("head camera", head)):
        near_black = float(np.mean(image.max(axis=2) < 25))
        blown = float(np.mean(image.min(axis=2) > 250))
        assert near_black < 0.02, f"task {task} {name}: {near_black:.1%} near-black pixels"
        assert blown < 0.05, f"task {task} {name}: {blown:.1%} blown-out pixels"
    if task == 1:  # the same frame twice, pixel for pixel
        again, _ = render_task_views(cfg, size=SIZE)
        np.testing.assert_array_equal(overview, again)


def test_head_camera_video_has_a_frame_per_camera_sample(tmp_path):
    """``--record-camera``: one frame per camera sample (0.5 s at 10 fps: 5 frames), at the
    camera's size and rate, colour | depth side by side with ``camera_depth``."""
    from pr2_drake.run import run_episode

    cam = CameraSettings(enabled=True, width=64, height=48, fps=10.0, quality="low")
    for depth, width in ((False, 64), (True, 128)):
        path = tmp_path / f"cam_{depth}.mp4"
        run_episode(Scenario(seconds=0.5, camera=cam), record_camera=str(path),
                    camera_depth=depth)
        video = cv2.VideoCapture(str(path))
        frames = []
        while True:
            ok, frame = video.read()
            if not ok:
                break
            frames.append(frame)
        assert video.get(cv2.CAP_PROP_FPS) == pytest.approx(10.0)
        assert len(frames) == 5
        assert all(f.shape == (48, width, 3) for f in frames)
        assert float(np.std(frames[-1])) > 5.0  # a picture, not a blank frame


def test_a_box_group_is_one_obj_mesh_in_the_low_preset():
    """``write_boxes_obj``: the boxes' exact volume and extent in one file; the low preset
    draws the rocky road's stones through it (one geometry, not one a stone)."""
    import trimesh
    from pydrake.geometry import Role

    from pr2_drake.testbed import Testbed

    boxes = [(RigidTransform([0.0, 0.0, 0.0]), (1.0, 1.0, 1.0)),
             (RigidTransform(RotationMatrix.MakeZRotation(0.3), [3.0, 0.0, 0.5]), (0.5, 0.2, 1.0))]
    mesh = trimesh.load(write_boxes_obj(boxes), force="mesh")
    assert mesh.volume == pytest.approx(1.0 + 0.1, rel=1e-5)  # outward faces: positive volume
    assert mesh.bounds[0] == pytest.approx([-0.5, -0.5, -0.5], abs=1e-6)
    assert mesh.bounds[1][2] == pytest.approx(1.0, abs=1e-6)
    camera = CameraSettings(enabled=True, width=32, height=24, quality="low")
    tb = Testbed(TestbedConfig(task=1, seed=0, camera=camera))
    perception = tb.camera_scene_graph.model_inspector().NumGeometriesWithRole(Role.kPerception)
    assert perception < 60  # 515 when each stone was a Box


def test_a_textured_glTF_points_at_this_checkouts_texture(tmp_path, monkeypatch):
    """The glTF cache (in the temp folder, shared by every checkout) refers to its texture by a
    relative path: a second checkout must get its own file, whose image resolves to its own
    texture, not reuse one pointing into a checkout that may be gone."""
    import json
    import shutil

    import pr2_drake.materials as materials_module
    from pr2_drake.paths import data_path

    boxes = [(RigidTransform([0.0, 0, 0]), (1, 1, 0.1))]
    mat = next(m for m in materials().values() if m.texture)
    here = write_boxes_gltf(boxes, (0.5, 0.5, 0.5, 1.0), mat)
    other = tmp_path / "other_checkout"
    shutil.copytree(data_path("models", "textures"), other / "models" / "textures")
    monkeypatch.setattr(materials_module, "data_path",
                        lambda *parts: other.joinpath(*parts))
    there = write_boxes_gltf(boxes, (0.5, 0.5, 0.5, 1.0), mat)
    assert there != here
    for path, root in ((here, data_path("models", "textures")),
                       (there, other / "models" / "textures")):
        uri = json.loads(path.read_text())["images"][0]["uri"]
        image = (path.parent / uri).resolve()
        assert image == (root / mat.texture).resolve() and image.is_file()

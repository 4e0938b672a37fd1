"""pr2-drake render: re-simulation, the scene export, datasets and the path tracer."""

import json

import cv2
import numpy as np
import pytest
from pydrake.geometry import Role

from pr2_drake.cli import main
from pr2_drake.materials import materials
from pr2_drake.render import command
from pr2_drake.render.meshes import srgb_to_linear
from pr2_drake.render.resim import resimulate
from pr2_drake.render.rig import RenderRig
from pr2_drake.render.scene import export_scene
from pr2_drake.render.settings import path_tracing_settings
from pr2_drake.scenario import Scenario


def _reference_state(scenario: Scenario, t: float) -> np.ndarray:
    """The plant state at ``t`` of the scenario's default (System) agent, advanced as
    ``run`` advances it, with no recorder in the diagram."""
    from pr2_drake.agents import instantiate_agent, load_agent_class
    from pr2_drake.drive import CHECK_EVERY
    from pr2_drake.episode import Episode, wire_system
    from pr2_drake.run import agent_params, agent_spec

    def wire(builder, testbed):
        agent = instantiate_agent(load_agent_class(agent_spec(scenario)),
                                  priors=dict(testbed.scene.priors), task=scenario.task,
                                  seed=scenario.seed, **agent_params(scenario))
        return wire_system(agent)(builder, testbed)

    episode = Episode(scenario, wire)
    episode.initialize()
    while episode.time < t - 1e-9:
        episode.advance_to(min(t, episode.time + CHECK_EVERY))
    return episode.testbed.GetOutputPort("plant_state").Eval(episode.tb_context).copy()


def test_resimulation_is_the_run_episode():
    scenario = Scenario(task=2, seed=3, seconds=1.0)
    report, states = resimulate(scenario, [0.5, 1.0, 7.0])
    assert [s.requested for s in states] == [0.5, 1.0]  # 7 s lies after the episode's end
    assert [s.time for s in states] == pytest.approx([0.5, 1.0], abs=1e-6)
    np.testing.assert_array_equal(states[1].x, _reference_state(scenario, 1.0))
    from pr2_drake.render.resim import run_episode  # the run path the render package uses

    plain = run_episode(scenario)
    for key in ("wall_time", "real_time_factor"):
        report.pop(key), plain.pop(key)
    assert report == plain


def test_scene_export_holds_every_visual_geometry_with_its_material():
    rig = RenderRig(Scenario(task=6, seed=0).testbed_config())
    settings = path_tracing_settings()
    scene = export_scene(rig.scene_graph, rig.sg_context, settings)
    inspector = rig.scene_graph.model_inspector()
    ids = {int(g.get_value()): g for g in inspector.GetAllGeometryIds(Role.kPerception)}
    assert sorted(o.geometry for o in scene.objects) == sorted(ids)
    kinds = set()
    for obj in scene.objects:
        g = ids[obj.geometry]
        assert obj.parts and all(len(p.faces) and p.material is not None for p in obj.parts)
        for p in obj.parts:
            assert p.faces.max() < len(p.vertices)
            np.testing.assert_allclose(np.linalg.norm(p.normals, axis=1), 1.0, atol=1e-6)
            m = p.material
            assert 0 <= m.roughness <= 1 and 0 <= m.metallic <= 1
            assert all(0 <= c <= 1 for c in m.base_color)
            kinds.add(m.source)
        shape, props = inspector.GetShape(g), inspector.GetPerceptionProperties(g)
        if type(shape).__name__ == "Box":  # its triangles span exactly the box
            extent = np.ptp(obj.parts[0].vertices, axis=0)
            np.testing.assert_allclose(extent, shape.size(), atol=1e-12)
        if props.HasProperty("phong", "diffuse") and obj.parts[0].material.source == "phong":
            rgb = props.GetProperty("phong", "diffuse").rgba[:3]
            np.testing.assert_allclose(obj.parts[0].material.base_color[:3],
                                       srgb_to_linear(rgb), atol=1e-9)
    assert kinds == {"phong", "gltf", "mtl"}  # primitives, textured scenery, the objects
    # The textured ground: the glTF material of materials.yaml, texture and all.
    ground = materials()["ground"]
    assert scene.ground_material.roughness == pytest.approx(ground.roughness)
    assert scene.ground_material.texture is not None
    assert cv2.imread(scene.ground_material.texture) is not None
    # The cup's two OBJ materials (body and inside), from its .mtl (Kd, read as 8 bits)
    cup = next(o for o in scene.objects if o.name.startswith("cup::"))
    colours = np.array([p.material.base_color[:3] for p in cup.parts])
    assert len(colours) == 2 and all(p.material.source == "mtl" for p in cup.parts)
    for kd in ([0.2, 0.45, 0.85], [0.95, 0.95, 0.95]):
        assert np.abs(colours - srgb_to_linear(kd)).max(axis=1).min() < 0.005


def test_render_without_the_extra_says_what_to_install(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(command, "path_tracer_available", lambda: False)
    code = main(["render", "--task", "2", "--times", "1", "--out", str(tmp_path)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and err[0].startswith("pr2-drake: error:")
    assert "pip install 'pr2-drake[photoreal]'" in err[0]
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize("argv, message", [
    (["--times", "1", "--size", "64"], "--size"),
    (["--times", "-1"], "--times"),
    (["--times", "1", "--samples", "0"], "samples"),
    (["--every", "0"], "--every"),
    (["--times", "1"], "--out"),
])
def test_render_rejects_bad_input(argv, message, tmp_path, capsys):
    out = [] if message == "--out" else ["--out", str(tmp_path)]
    code = main(["render", "--task", "2", "--engine", "vtk", *argv, *out])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and message in err[0], err


def test_head_dataset_has_exact_depth_and_object_masks(tmp_path):
    out = tmp_path / "dataset"
    code = main(["render", "--task", "6", "--seconds", "0.5", "--view", "head", "--every", "0.5",
                 "--engine", "vtk", "--quality", "low", "--size", "96x72", "--out", str(out),
                 "--quiet"])
    assert code == 0
    meta = json.loads((out / "frames.json").read_text())
    assert [f["time"] for f in meta["frames"]] == pytest.approx([0.0, 0.5])
    assert set(meta["objects"].values()) == {"cup", "bottle", "bowl", "apple", "teddy_bear",
                                             "toy_car", "cube", "book", "pencil_box"}
    K = np.array(meta["intrinsics"]["K"])
    assert K[0, 0] == pytest.approx(36 / np.tan(np.radians(30)))  # 72 px, 60 deg
    seen = set()
    for f in meta["frames"]:
        color = cv2.imread(str(out / f["color"]))
        depth = np.load(out / f["depth"])
        mask = cv2.imread(str(out / f["mask"]), cv2.IMREAD_UNCHANGED)
        assert color.shape == (72, 96, 3) and depth.shape == mask.shape == (72, 96)
        assert depth.dtype == np.float32 and np.isfinite(depth).mean() > 0.9
        on = mask > 0
        seen |= set(np.unique(mask[on]).tolist())
        assert np.all(np.isfinite(depth[on])) and np.all(depth[on] < 10.0)
    assert seen and seen <= set(range(1, 10))


def test_video_has_a_frame_per_step_of_the_episode(tmp_path):
    video = tmp_path / "walk.mp4"
    code = main(["render", "--task", "2", "--seconds", "1", "--video", str(video), "--fps", "4",
                 "--engine", "vtk", "--quality", "low", "--size", "64x48", "--quiet"])
    assert code == 0
    capture = cv2.VideoCapture(str(video))
    frames = []
    while True:
        ok, frame = capture.read()
        if not ok:
            break
        frames.append(frame)
    assert len(frames) == 5 and frames[0].shape == (48, 64, 3)  # t = 0, 0.25, ..., 1 s
    assert np.abs(frames[-1].astype(float) - frames[0]).mean() > 0.5  # the robot moved


def test_path_traced_still_of_task_2(tmp_path):
    pytest.importorskip("bpy", reason="the [photoreal] extra (bpy, Python 3.11) is not "
                                      "installed: pip install 'pr2-drake[photoreal]'")
    frames = {}
    for engine in ("cycles", "vtk"):
        code = main(["render", "--task", "2", "--times", "1", "--size", "64x48", "--samples",
                     "16", "--engine", engine, "--out", str(tmp_path / engine), "--quiet"])
        assert code == 0
        frames[engine] = cv2.imread(str(tmp_path / engine / "color_00000.png")).astype(float)
    traced, raster = frames["cycles"], frames["vtk"]
    assert traced.shape == (48, 64, 3)
    assert traced.mean() > 40  # not black
    assert traced.std() > 8  # not flat
    assert np.abs(traced - raster).mean() > 3  # not the raster's frame
    # ... but the same frame: the red valve wheel and the blue start pad sit at the same
    # pixels in both
    for colour in (lambda r, g, b: (r > g + 50) & (r > b + 50),
                   lambda r, g, b: (b > r + 50) & (b > g + 20)):
        where = [np.argwhere(colour(*np.moveaxis(x[..., ::-1], 2, 0))) for x in (traced, raster)]
        assert all(len(w) >= 5 for w in where)
        assert np.linalg.norm(where[0].mean(axis=0) - where[1].mean(axis=0)) < 2.5  # pixels

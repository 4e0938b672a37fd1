"""USD -> OBJ + SDFormat import: geometry, units, up axis, colours, physics, errors, cache."""

import numpy as np
import pytest
from pxr import Gf, Usd, UsdGeom, Vt
from pydrake.geometry import Box as DrakeBox
from pydrake.math import RigidTransform
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph, CoulombFriction
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from pr2_drake.paths import data_path
from pr2_drake.usd_import import import_usd, read_usd_meshes

# A 10-unit cube as six quads, centred on its local origin.
CUBE_POINTS = [(x, y, z) for x in (-5, 5) for y in (-5, 5) for z in (-5, 5)]
CUBE_QUADS = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]


def write_stage(path, up="Y", meters_per_unit=0.01):
    """A stage in centimetres, Y up: a red cube under a translated Xform and a blue
    triangle-pair plate rotated 90 deg about x."""
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y if up == "Y" else UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, meters_per_unit)
    root = UsdGeom.Xform.Define(stage, "/Thing")
    UsdGeom.XformCommonAPI(root).SetTranslate(Gf.Vec3d(100.0, 20.0, 0.0))  # 1 m, 0.2 m
    cube = UsdGeom.Mesh.Define(stage, "/Thing/Cube")
    cube.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*p) for p in CUBE_POINTS]))
    cube.CreateFaceVertexCountsAttr(Vt.IntArray([4] * 6))
    cube.CreateFaceVertexIndicesAttr(Vt.IntArray([i for q in CUBE_QUADS for i in q]))
    cube.CreateDisplayColorAttr(Vt.Vec3fArray([Gf.Vec3f(0.9, 0.1, 0.1)]))
    plate = UsdGeom.Mesh.Define(stage, "/Thing/Plate")
    plate.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*p) for p in
                                          [(-20, -10, 0), (20, -10, 0), (20, 10, 0), (-20, 10, 0)]]))
    plate.CreateFaceVertexCountsAttr(Vt.IntArray([3, 3]))
    plate.CreateFaceVertexIndicesAttr(Vt.IntArray([0, 1, 2, 0, 2, 3]))
    plate.CreateDisplayColorAttr(Vt.Vec3fArray([Gf.Vec3f(0.1, 0.2, 0.9)]))
    UsdGeom.XformCommonAPI(plate).SetTranslate(Gf.Vec3d(0.0, 30.0, 0.0))
    UsdGeom.XformCommonAPI(plate).SetRotate(Gf.Vec3f(90.0, 0.0, 0.0))
    stage.SetDefaultPrim(root.GetPrim())
    stage.GetRootLayer().Save()
    return path


def test_meshes_units_up_axis_and_transforms(tmp_path):
    meshes = {m.path: m for m in read_usd_meshes(write_stage(tmp_path / "thing.usda"))}
    assert set(meshes) == {"/Thing/Cube", "/Thing/Plate"}
    cube = meshes["/Thing/Cube"]
    assert cube.triangles.shape == (12, 3)  # six quads as triangle fans
    # cm -> m; Y-up (x, y, z) -> Z-up (x, -z, y); translated by (100, 20, 0) cm.
    assert np.allclose(cube.vertices.min(axis=0), [0.95, -0.05, 0.15])
    assert np.allclose(cube.vertices.max(axis=0), [1.05, 0.05, 0.25])
    assert np.allclose(cube.color, [0.9, 0.1, 0.1])
    plate = meshes["/Thing/Plate"]
    # Rotated 90 deg about x, the plate lies flat (horizontal) in the Y-up stage, 30 cm above
    # the Thing's origin, which is 20 cm up: at z = 0.5 m once converted to Z-up.
    assert np.allclose(plate.vertices[:, 2], 0.5, atol=1e-6)
    assert np.allclose(np.ptp(plate.vertices, axis=0), [0.4, 0.2, 0.0], atol=1e-6)
    # Outward normals of the cube: the mesh encloses a positive volume.
    v, f = cube.vertices, cube.triangles
    vol = np.einsum("ij,ij->i", v[f[:, 0]], np.cross(v[f[:, 1]], v[f[:, 2]])).sum() / 6
    assert vol == pytest.approx(0.001, rel=1e-6)


def test_sdf_loads_in_drake_and_the_box_collision_rests_on_the_ground(tmp_path):
    stage = write_stage(tmp_path / "thing.usda")
    sdf = import_usd(stage, tmp_path / "out", name="thing", mass=2.0, collision="box")
    assert sdf.is_file() and len(list((tmp_path / "out").glob("*.obj"))) == 2
    mtl = sorted((tmp_path / "out").glob("*Cube.mtl"))[0].read_text()
    assert "Kd 0.9000 0.1000 0.1000" in mtl
    builder = DiagramBuilder()
    plant, _ = AddMultibodyPlantSceneGraph(builder, 0.001)
    plant.RegisterCollisionGeometry(plant.world_body(), RigidTransform([0, 0, -0.5]),
                                    DrakeBox(10, 10, 1), "ground", CoulombFriction(1.0, 1.0))
    (model,) = Parser(plant).AddModels(str(sdf))
    body = plant.GetBodyByName("thing", model)
    plant.Finalize()
    assert body.default_mass() == pytest.approx(2.0)
    sim = Simulator(builder.Build())
    ctx = plant.GetMyMutableContextFromRoot(sim.get_mutable_context())
    # The cube (z in [0.15, 0.25] m in the model frame) carries the plate above it; drop the
    # model from 0.5 m: it lands on the cube's collision box.
    plant.SetFreeBodyPose(ctx, body, RigidTransform([0, 0, 0.5]))
    lowest = min(m.vertices[:, 2].min() for m in read_usd_meshes(stage))
    for t in (0.8, 1.2):  # landed and stays there (box-on-box point contact may rock a little)
        sim.AdvanceTo(t)
        z = plant.EvalBodyPoseInWorld(ctx, body).translation()[2]
        assert z + lowest == pytest.approx(0.0, abs=0.005)  # lowest collision box on the ground


def test_convex_and_static_modes(tmp_path):
    stage = write_stage(tmp_path / "thing.usda")
    sdf = import_usd(stage, tmp_path / "convex", collision="convex", static=True)
    text = sdf.read_text()
    assert "<drake:declare_convex/>" in text and "<static>true</static>" in text
    assert "<inertial>" not in text
    builder = DiagramBuilder()
    plant, _ = AddMultibodyPlantSceneGraph(builder, 0.001)
    Parser(plant).AddModels(str(sdf))
    plant.Finalize()
    assert plant.num_positions() == 0  # static: welded to the world


def test_conversion_is_deterministic_and_cached(tmp_path):
    stage = write_stage(tmp_path / "thing.usda")
    a = import_usd(stage, tmp_path / "a")
    b = import_usd(stage, tmp_path / "b")
    for fa in sorted(a.parent.iterdir()):
        assert (b.parent / fa.name).read_bytes() == fa.read_bytes()
    c1, c2 = import_usd(stage), import_usd(stage)  # default cache folder
    assert c1 == c2 and c1.is_file()
    assert import_usd(stage, collision="convex") != c1  # options are part of the key


def test_errors(tmp_path):
    with pytest.raises(FileNotFoundError):
        import_usd(tmp_path / "missing.usda")
    empty = Usd.Stage.CreateNew(str(tmp_path / "empty.usda"))
    UsdGeom.Xform.Define(empty, "/Nothing")
    empty.GetRootLayer().Save()
    with pytest.raises(ValueError, match="no UsdGeom.Mesh"):
        import_usd(tmp_path / "empty.usda", tmp_path / "o")
    with pytest.raises(ValueError, match="collision"):
        import_usd(write_stage(tmp_path / "t.usda"), tmp_path / "o", collision="mesh")


def test_committed_coffee_table_comes_through_the_importer(tmp_path):
    meshes = read_usd_meshes(data_path("models", "house", "coffee_table.usda"))
    assert len(meshes) == 5  # top + four legs
    top = max(m.vertices[:, 2].max() for m in meshes)
    assert top == pytest.approx(0.45, abs=1e-6)  # matches tasks/6_object_search.yaml
    sdf = import_usd(data_path("models", "house", "coffee_table.usda"), tmp_path, static=True)
    assert sdf.read_text().count("<collision") == 5

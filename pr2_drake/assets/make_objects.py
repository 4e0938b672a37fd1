"""Generate the task-6 object models and the house's USD furniture from primitives.

    PYTHONPATH=. python -m pr2_drake.assets.make_objects

writes, deterministically (no randomness, nothing downloaded):

- ``models/objects/<name>/<name>.obj`` + ``.mtl`` (visual mesh, several colours) and
  ``<name>.sdf`` (one link: mass, inertia of the solid convex hull, convex collision
  primitives, plus small "feet" spheres under the base so the object rests on a table without
  rocking under point contact), for the nine objects of task 6;
- ``models/house/coffee_table.usda``: the living-room coffee table as a USD stage of
  ``UsdGeom.Mesh`` prims with ``displayColor``; the scene imports it at build time through
  :mod:`pr2_drake.usd_import`.

Every object's frame is the centre of its bounding box (the point the 0.20 m pick distance of
task 6 is measured to); z up; the base of the object lies at z = -height/2.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import trimesh
from trimesh import creation

from pr2_drake.assets.mesh_io import MeshPart, Primitive, write_obj, write_sdf
from pr2_drake.paths import data_path

FOOT_RADIUS = 0.004  # [m] feet spheres under each object
FOOT_DROP = 0.001  # [m] how far the feet reach below the other collision shapes


@dataclass
class ObjectModel:
    """An object under construction: parts in a frame whose z = 0 is the object's base."""

    name: str
    mass: float
    parts: list[MeshPart] = field(default_factory=list)
    collisions: list[Primitive] = field(default_factory=list)
    feet: list[tuple[float, float]] = field(default_factory=list)  # (x, y) of feet spheres
    friction: float = 0.9

    def add(self, mesh: trimesh.Trimesh, material: str, color, smooth: bool = False) -> None:
        self.parts.append(MeshPart(np.asarray(mesh.vertices), np.asarray(mesh.faces), material,
                                   tuple(color), smooth))


def _at(mesh: trimesh.Trimesh, xyz=(0, 0, 0), rpy=(0, 0, 0)) -> trimesh.Trimesh:
    T = trimesh.transformations.euler_matrix(*rpy, axes="sxyz")
    T[:3, 3] = xyz
    mesh = mesh.copy()
    mesh.apply_transform(T)
    return mesh


def _cyl(r, h, xyz=(0, 0, 0), rpy=(0, 0, 0), sections=32):
    return _at(creation.cylinder(radius=r, height=h, sections=sections), xyz, rpy)


def _box(size, xyz=(0, 0, 0), rpy=(0, 0, 0)):
    return _at(creation.box(extents=size), xyz, rpy)


def _sphere(r, xyz=(0, 0, 0), scale=(1, 1, 1), subdivisions=2):
    m = creation.icosphere(subdivisions=subdivisions, radius=r)
    m.apply_scale(scale)
    return _at(m, xyz)


def _square_feet(hx: float, hy: float) -> list[tuple[float, float]]:
    return [(sx * hx, sy * hy) for sx in (-1, 1) for sy in (-1, 1)]


def _tripod(r: float) -> list[tuple[float, float]]:
    return [(r * np.cos(a), r * np.sin(a)) for a in np.radians([90, 210, 330])]


# -- the nine objects -------------------------------------------------------------------------
def cup() -> ObjectModel:
    o = ObjectModel("cup", 0.15)
    r, h, wall = 0.04, 0.09, 0.006
    blue, white = (0.20, 0.45, 0.85, 1), (0.95, 0.95, 0.95, 1)
    o.add(_at(creation.annulus(r_min=r - wall, r_max=r, height=h, sections=40), (0, 0, h / 2)),
          "cup_body", blue, smooth=True)
    o.add(_cyl(r - wall, 0.008, (0, 0, 0.004), sections=40), "cup_inside", white)
    handle = creation.torus(major_radius=0.025, minor_radius=0.006, major_sections=24,
                            minor_sections=12)
    o.add(_at(handle, (r + 0.005, 0, h / 2), (np.pi / 2, 0, 0)), "cup_body", blue, smooth=True)
    o.collisions = [Primitive("cylinder", [r, h], [0, 0, h / 2]),
                    Primitive("box", [0.03, 0.012, 0.05], [r + 0.015, 0, h / 2])]
    o.feet = _tripod(r - 0.008)
    return o


def teddy_bear() -> ObjectModel:
    o = ObjectModel("teddy_bear", 0.25)
    brown, light, black = (0.55, 0.35, 0.17, 1), (0.80, 0.62, 0.40, 1), (0.05, 0.05, 0.05, 1)
    body_c, head_c = (0, 0, 0.075), (0, 0, 0.175)
    o.add(_sphere(0.065, body_c, (1.0, 1.0, 1.15)), "fur", brown, smooth=True)
    o.add(_sphere(0.05, head_c), "fur", brown, smooth=True)
    o.add(_sphere(0.045, (0.03, 0, 0.07), (0.6, 1.0, 1.1)), "belly", light, smooth=True)
    for s in (-1, 1):
        o.add(_sphere(0.018, (0, s * 0.035, 0.215)), "fur", brown, smooth=True)  # ears
        o.add(_sphere(0.022, (0.02, s * 0.065, 0.10), (1.0, 1.0, 1.5)), "fur", brown, True)
        o.add(_sphere(0.028, (0.045, s * 0.04, 0.028), (1.3, 1.0, 1.0)), "fur", brown, True)
        o.add(_sphere(0.007, (0.045, s * 0.018, 0.188)), "eyes", black, smooth=True)
    o.add(_sphere(0.02, (0.045, 0, 0.168), (1.0, 1.2, 0.9)), "belly", light, smooth=True)
    o.add(_sphere(0.007, (0.064, 0, 0.172)), "eyes", black, smooth=True)
    o.collisions = [Primitive("sphere", [0.065], list(body_c)),
                    Primitive("sphere", [0.05], list(head_c))]
    o.feet = [(0.06, 0.04), (0.06, -0.04), (-0.04, 0.0)]
    return o


def cube() -> ObjectModel:
    o = ObjectModel("cube", 0.12)
    a = 0.06
    o.add(_box([a, a, a], (0, 0, a / 2)), "cube", (0.85, 0.12, 0.10, 1))
    o.collisions = [Primitive("box", [a, a, a], [0, 0, a / 2])]
    o.feet = _square_feet(a / 2 - 0.006, a / 2 - 0.006)
    return o


def bottle() -> ObjectModel:
    o = ObjectModel("bottle", 0.30)
    green, white = (0.15, 0.60, 0.30, 1), (0.95, 0.95, 0.95, 1)
    o.add(_cyl(0.033, 0.15, (0, 0, 0.075)), "bottle", green, smooth=True)
    o.add(_at(creation.cone(radius=0.033, height=0.05, sections=32), (0, 0, 0.15)), "bottle",
          green, smooth=True)
    o.add(_cyl(0.013, 0.04, (0, 0, 0.19)), "bottle", green, smooth=True)
    o.add(_cyl(0.015, 0.02, (0, 0, 0.215)), "cap", white, smooth=True)
    o.add(_cyl(0.0335, 0.06, (0, 0, 0.08)), "label", white, smooth=True)
    o.collisions = [Primitive("cylinder", [0.033, 0.16], [0, 0, 0.08]),
                    Primitive("cylinder", [0.015, 0.065], [0, 0, 0.1925])]
    o.feet = _tripod(0.025)
    return o


def bowl() -> ObjectModel:
    o = ObjectModel("bowl", 0.20)
    orange = (0.95, 0.55, 0.10, 1)
    # A hemispherical shell: revolve a thick arc profile about z.
    t = np.linspace(np.radians(-90), np.radians(0), 16)
    outer = np.stack([0.075 * np.cos(t), 0.055 + 0.055 * np.sin(t)], axis=1)
    inner = np.stack([0.068 * np.cos(t[::-1]), 0.055 + 0.048 * np.sin(t[::-1])], axis=1)
    profile = np.vstack([[[0.0, 0.0]], outer[1:], inner[:-1], [[0.0, 0.007]]])
    o.add(creation.revolve(profile, sections=40), "bowl", orange, smooth=True)
    o.collisions = [Primitive("cylinder", [0.07, 0.05], [0, 0, 0.03])]
    o.feet = _tripod(0.03)
    return o


def book() -> ObjectModel:
    o = ObjectModel("book", 0.35)
    sx, sy, sz = 0.15, 0.21, 0.03
    o.add(_box([sx, sy, 0.004], (0, 0, 0.002)), "cover", (0.15, 0.25, 0.60, 1))
    o.add(_box([sx, sy, 0.004], (0, 0, sz - 0.002)), "cover", (0.15, 0.25, 0.60, 1))
    o.add(_box([0.004, sy, sz], (-sx / 2 + 0.002, 0, sz / 2)), "cover", (0.15, 0.25, 0.60, 1))
    o.add(_box([sx - 0.01, sy - 0.01, sz - 0.008], (0.003, 0, sz / 2)), "pages",
          (0.96, 0.94, 0.86, 1))
    o.collisions = [Primitive("box", [sx, sy, sz], [0, 0, sz / 2])]
    o.feet = _square_feet(sx / 2 - 0.01, sy / 2 - 0.01)
    return o


def apple() -> ObjectModel:
    o = ObjectModel("apple", 0.18)
    o.add(_sphere(0.04, (0, 0, 0.037), (1.0, 1.0, 0.92)), "apple", (0.80, 0.08, 0.08, 1), True)
    o.add(_cyl(0.003, 0.02, (0, 0, 0.078)), "stem", (0.35, 0.22, 0.08, 1))
    o.add(_sphere(0.012, (0.01, 0, 0.08), (1.0, 0.5, 0.2)), "leaf", (0.20, 0.60, 0.15, 1), True)
    o.collisions = [Primitive("sphere", [0.037], [0, 0, 0.037])]
    o.feet = _tripod(0.018)
    return o


def toy_car() -> ObjectModel:
    o = ObjectModel("toy_car", 0.20)
    yellow, black, glass = (0.98, 0.80, 0.10, 1), (0.08, 0.08, 0.08, 1), (0.55, 0.75, 0.90, 1)
    o.add(_box([0.16, 0.07, 0.035], (0, 0, 0.035)), "car_body", yellow)
    o.add(_box([0.08, 0.064, 0.03], (-0.01, 0, 0.067)), "car_window", glass)
    for x in (-0.05, 0.05):
        for y in (-0.038, 0.038):
            o.add(_cyl(0.018, 0.012, (x, y, 0.018), (np.pi / 2, 0, 0), sections=20), "tyre",
                  black, smooth=True)
    o.collisions = [Primitive("box", [0.16, 0.07, 0.035], [0, 0, 0.035]),
                    Primitive("box", [0.08, 0.064, 0.03], [-0.01, 0, 0.067])]
    o.feet = [(x, y) for x in (-0.05, 0.05) for y in (-0.038, 0.038)]
    return o


def pencil_box() -> ObjectModel:
    o = ObjectModel("pencil_box", 0.15)
    sx, sy, sz = 0.20, 0.06, 0.035
    o.add(_box([sx, sy, sz - 0.006], (0, 0, (sz - 0.006) / 2)), "pencil_box", (0.55, 0.25, 0.70, 1))
    o.add(_box([sx, sy, 0.006], (0, 0, sz - 0.003)), "lid", (0.95, 0.75, 0.85, 1))
    o.add(_cyl(0.004, 0.12, (0.0, 0.0, sz + 0.004), (0, np.pi / 2, 0), sections=6), "pencil",
          (0.98, 0.75, 0.10, 1))
    o.collisions = [Primitive("box", [sx, sy, sz], [0, 0, sz / 2])]
    o.feet = _square_feet(sx / 2 - 0.01, sy / 2 - 0.008)
    return o


OBJECTS = (cup, teddy_bear, cube, bottle, bowl, book, apple, toy_car, pencil_box)


def write_object(o: ObjectModel, root: Path) -> Path:
    """Centre the object on its bounding box and write its OBJ/MTL/SDF under root/<name>/."""
    folder = root / o.name
    folder.mkdir(parents=True, exist_ok=True)
    allv = np.vstack([p.vertices for p in o.parts])
    lo, hi = allv.min(axis=0), allv.max(axis=0)
    c = (lo + hi) / 2
    for p in o.parts:
        p.vertices = p.vertices - c
    write_obj(folder / f"{o.name}.obj", o.parts)
    prims = [Primitive(p.kind, p.dims, list(np.asarray(p.xyz) - c), p.rpy) for p in o.collisions]
    z_foot = -(hi[2] - lo[2]) / 2 + FOOT_RADIUS - FOOT_DROP
    prims += [Primitive("sphere", [FOOT_RADIUS], [x - c[0], y - c[1], z_foot]) for x, y in o.feet]
    hull = trimesh.Trimesh(np.vstack([p.vertices for p in o.parts])).convex_hull
    hull.density = o.mass / hull.volume
    write_sdf(folder / f"{o.name}.sdf", o.name, [(f"{o.name}.obj", None)], prims, o.mass,
              np.round(hull.center_mass, 6), np.round(hull.moment_inertia, 9),
              friction=o.friction)
    return folder / f"{o.name}.sdf"


# -- USD furniture -----------------------------------------------------------------------------
def _usd_box_mesh(stage, path: str, size, center, color) -> None:
    from pxr import Gf, UsdGeom, Vt

    m = creation.box(extents=size)
    mesh = UsdGeom.Mesh.Define(stage, path)
    mesh.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*map(float, v)) for v in m.vertices]))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray([3] * len(m.faces)))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray([int(i) for i in m.faces.ravel()]))
    mesh.CreateDisplayColorAttr(Vt.Vec3fArray([Gf.Vec3f(*map(float, color))]))
    UsdGeom.XformCommonAPI(mesh).SetTranslate(Gf.Vec3d(*map(float, center)))


def write_coffee_table_usda(path: Path, top=(1.0, 0.6, 0.04), height=0.45, leg=0.05) -> Path:
    """A coffee table (top + four legs) as Mesh prims; origin at the floor centre, z up, m."""
    from pxr import Usd, UsdGeom

    path = Path(path)
    if path.exists():
        path.unlink()
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    root = UsdGeom.Xform.Define(stage, "/CoffeeTable")
    stage.SetDefaultPrim(root.GetPrim())
    wood, dark = (0.62, 0.40, 0.22), (0.35, 0.22, 0.12)
    _usd_box_mesh(stage, "/CoffeeTable/Top", top, (0, 0, height - top[2] / 2), wood)
    lx, ly = top[0] / 2 - leg, top[1] / 2 - leg
    leg_h = height - top[2]
    for i, (sx, sy) in enumerate([(1, 1), (1, -1), (-1, 1), (-1, -1)]):
        _usd_box_mesh(stage, f"/CoffeeTable/Leg_{i}", (leg, leg, leg_h),
                      (sx * lx, sy * ly, leg_h / 2), dark)
    stage.GetRootLayer().Save()
    return path


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=None, help="models/ folder (default: the data root's)")
    args = parser.parse_args(argv)
    models = Path(args.out) if args.out else data_path("models")
    for make in OBJECTS:
        print(write_object(make(), models / "objects"))
    (models / "house").mkdir(parents=True, exist_ok=True)
    print(write_coffee_table_usda(models / "house" / "coffee_table.usda"))


if __name__ == "__main__":
    main()

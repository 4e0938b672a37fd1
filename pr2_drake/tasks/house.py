"""The task-6 house: floor with per-room colours, walls with doorways, tables and decor.

Everything is read from the ``scene`` block of ``tasks/6_object_search.yaml``. Walls, tables and
decor are boxes welded to the world (visual + collision); room floors are visual-only tiles on
the collision ground; the coffee table comes from a USD stage through
:func:`pr2_drake.usd_import.import_usd` (converted at build time into a cache folder).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import CoulombFriction, MultibodyPlant

from pr2_drake.materials import add_textured_box
from pr2_drake.paths import resolve_user_path
from pr2_drake.scene import add_flat_ground
from pr2_drake.tasks.regions import Rect, region_from_yaml, rgba
from pr2_drake.usd_import import import_usd

FURNITURE_FRICTION = CoulombFriction(0.8, 0.7)
WALL_FRICTION = CoulombFriction(0.5, 0.4)
FLOOR_TILE = 0.001  # [m] thickness of the visual floor tiles


@dataclass(frozen=True)
class Table:
    """A table's top in world: centre (x, y), size (x, y) [m] and top height z [m]."""

    name: str
    label: str
    room: str
    center: tuple[float, float]
    size: tuple[float, float]
    height: float

    @property
    def footprint(self) -> Rect:
        return Rect(self.center, self.size)

    def grown(self, margin: float) -> Rect:
        return Rect(self.center, (self.size[0] + 2 * margin, self.size[1] + 2 * margin))


def add_box(plant: MultibodyPlant, name: str, center, size, color, collision: bool = True,
            friction: CoulombFriction = FURNITURE_FRICTION, material: str = "plastic") -> None:
    """A world-welded box with its centre at ``center`` (x, y, z) [m], textured with
    ``material`` (:mod:`pr2_drake.materials`)."""
    X = RigidTransform(np.asarray(center, float))
    add_textured_box(plant, name, X, size, rgba(color), material,
                     friction if collision else None)


def add_walls(plant: MultibodyPlant, walls: dict) -> None:
    """Axis-aligned wall segments, each a box ``thickness`` wide and ``height`` tall."""
    t, h = float(walls["thickness"]), float(walls["height"])
    for i, (p0, p1) in enumerate(walls["segments"]):
        p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
        d = np.abs(p1 - p0)
        if d[0] > 1e-9 and d[1] > 1e-9:
            raise ValueError(f"wall segment {i} is not axis-aligned: {p0.tolist()} {p1.tolist()}")
        size = [d[0] + t, t, h] if d[0] > d[1] else [t, d[1] + t, h]
        add_box(plant, f"wall_{i}", [*(p0 + p1) / 2, h / 2], size, walls["color"],
                friction=WALL_FRICTION, material=walls.get("material", "plaster"))


def add_table(plant: MultibodyPlant, name: str, cfg: dict, top_thickness: float,
              leg: float) -> None:
    """A table from boxes: a top whose upper face is at cfg["height"], on four legs."""
    (cx, cy), (sx, sy), h = cfg["center"], cfg["size"], float(cfg["height"])
    add_box(plant, f"{name}_top", [cx, cy, h - top_thickness / 2], [sx, sy, top_thickness],
            cfg["color"], material=cfg.get("material", "wood"))
    leg_h = h - top_thickness
    for k, (ux, uy) in enumerate([(1, 1), (1, -1), (-1, 1), (-1, -1)]):
        add_box(plant, f"{name}_leg_{k}",
                [cx + ux * (sx / 2 - leg), cy + uy * (sy / 2 - leg), leg_h / 2],
                [leg, leg, leg_h], cfg["leg_color"], material=cfg.get("leg_material", "wood"))


def add_usd_furniture(plant: MultibodyPlant, name: str, cfg: dict) -> None:
    """Import cfg["usd"] (origin at its floor centre, z up) and weld it at cfg["center"],
    turned by cfg["yaw_deg"] (default 0; its ``size`` is then the turned footprint's)."""
    sdf = import_usd(resolve_user_path(cfg["usd"], f"{name} USD stage"), name=name, mass=10.0,
                     collision="box")
    parser = Parser(plant, name)
    (instance,) = parser.AddModels(str(sdf))
    body = plant.GetBodyByName(name, instance)
    cx, cy = cfg["center"]
    yaw = np.radians(float(cfg.get("yaw_deg", 0.0)))
    plant.WeldFrames(plant.world_frame(), body.body_frame(),
                     RigidTransform(RotationMatrix.MakeZRotation(yaw), [cx, cy, 0.0]))


def add_house(plant: MultibodyPlant, scene: dict) -> dict[str, Table]:
    """Build the house from the task YAML's ``scene`` block; returns the tables by name."""
    add_flat_ground(plant, color=tuple(scene["ground_color"]))
    for name, room in scene["rooms"].items():
        r = region_from_yaml(room["rect"])
        X = RigidTransform([r.center[0], r.center[1], FLOOR_TILE / 2])
        add_textured_box(plant, f"floor_{name}", X, (*r.size, FLOOR_TILE),
                         rgba(room["floor_color"]), room.get("floor_material", "parquet"))
    add_walls(plant, scene["walls"])
    tables = {}
    for name, cfg in scene["furniture"].items():
        if "usd" in cfg:
            add_usd_furniture(plant, name, cfg)
        else:
            add_table(plant, name, cfg, float(scene["table_top_thickness"]),
                      float(scene["table_leg_width"]))
        tables[name] = Table(name, cfg["label"], cfg["room"], tuple(cfg["center"]),
                             tuple(cfg["size"]), float(cfg["height"]))
    for d in scene.get("decor", []):
        sx, sy, sz = d["size"]
        add_box(plant, d["name"], [d["center"][0], d["center"][1], sz / 2], [sx, sy, sz],
                d["color"], material=d.get("material", "plastic"))
    return tables

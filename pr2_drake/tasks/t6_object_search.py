"""Task 6 - indoor object search and transport (25 points, 4 min).

Scene (``tasks/6_object_search.yaml``, built by :mod:`pr2_drake.tasks.house`): an 8 m x 8 m house
with a living room (coffee table, imported from USD), a kitchen (cup, bottle, bowl and apple on
the kitchen table), a playroom (teddy bear and toy car on a table) and a study (cube, book and
pencil box on the desk): nine free objects, models under ``models/objects/``.

From the episode seed, in this order: the target among ``candidates``; every object's position
and yaw inside its table top (shrunk by ``placement_margin``, objects at least
``object_clearance`` apart); the sentence among ``instructions``; the robot's start inside the
target room's start rectangle, heading = the room's heading +- ``heading_noise_deg``.

``pick`` with a hand welds the object whose centre is nearest the hand sphere centre, if within
``pick_distance`` (0.20 m, Euclidean); ``release`` drops it. Any object can be picked; only the
target scores.

Rubric (our definitions of the regions, numbers in the YAML):
- pick_region +5: the base within ``pick_region_radius`` (horizontal) of the target object;
- pick_target +10: the target attached to a hand;
- table_region +5: the base inside the coffee table footprint grown by
  ``table_region_margin``, while holding the target (``table_region_requires_target_held``);
- place_on_table +5: the target not attached, its centre above the coffee table top (by at
  most ``place.max_height_above_top``) and inside its footprint, slower than
  ``place.max_speed``, all for ``place.settle_time`` without interruption.

Priors: the nine object models (paths), the coffee table centre (top centre), the sentence
(also ``instruction()``). Feedback: the pick state; the head RGB-D camera is on (``camera``).

Scene variation (``scene.variation``): a house generated from the seed
(:mod:`pr2_drake.tasks.house_gen`: rooms, doorways, furniture, decor, which table holds each
object); the episode's draws above then run on it, and the priors and the sentence describe it
as they describe the task's own house.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant

from pr2_drake.grasp import Graspable
from pr2_drake.paths import resolve_user_path
from pr2_drake.scene import Scene, StartPose
from pr2_drake.tasks.base import EpisodeStatus, Referee, TaskDefinition
from pr2_drake.tasks.house import Table, add_house
from pr2_drake.tasks.regions import held_for

SPAWN_GAP = 0.002  # [m] objects start this far above their table top and settle onto it


@lru_cache(maxsize=None)
def model_extent(sdf: str) -> tuple[float, float]:
    """(half height, footprint radius) [m] of an object model, from its OBJ next to the SDF."""
    obj = Path(sdf).with_suffix(".obj")
    v = np.array([[float(t) for t in line.split()[1:4]]
                  for line in obj.read_text().splitlines() if line.startswith("v ")])
    return float(-v[:, 2].min()), float(np.max(np.hypot(v[:, 0], v[:, 1])))


def sample_layout(scene: dict, tables: dict[str, Table], rng: np.random.Generator):
    """Draw target, object poses X_WO, sentence and start from ``rng`` (in that order)."""
    objects = scene["objects"]
    candidates = list(scene["candidates"])
    unknown = [c for c in candidates if c not in objects]
    if unknown:
        raise ValueError(f"task 6: candidates {unknown} are not in scene.objects")
    target = candidates[int(rng.integers(len(candidates)))]
    poses: dict[str, RigidTransform] = {}
    placed: dict[str, list[tuple[np.ndarray, float]]] = {}
    margin, clearance = float(scene["placement_margin"]), float(scene["object_clearance"])
    for name, o in objects.items():
        table = tables[o["table"]]
        half_h, radius = model_extent(str(resolve_user_path(o["model"], f"{name} model")))
        lo = np.asarray(table.center) - np.asarray(table.size) / 2 + margin
        hi = np.asarray(table.center) + np.asarray(table.size) / 2 - margin
        others = placed.setdefault(o["table"], [])
        for _ in range(500):
            p = rng.uniform(lo, hi)
            if all(np.linalg.norm(p - q) >= radius + r + clearance for q, r in others):
                break
        else:
            raise ValueError(f"task 6: cannot place {name} on {o['on']} without overlaps")
        others.append((p, radius))
        yaw = rng.uniform(-np.pi, np.pi)
        poses[name] = RigidTransform(RollPitchYaw(0, 0, yaw),
                                     [p[0], p[1], table.height + half_h + SPAWN_GAP])
    table = tables[objects[target]["table"]]
    room_cfg = scene["rooms"][table.room]
    template = scene["instructions"][int(rng.integers(len(scene["instructions"])))]
    sentence = template.format(object=objects[target]["label"], furniture=table.label,
                               room=room_cfg["label"])
    return target, poses, sentence, room_cfg


def sample_room_start(room_cfg: dict, noise_deg: float, rng: np.random.Generator) -> StartPose:
    s = room_cfg["start"]
    (cx, cy), (dx, dy) = s["center"], s["size"]
    x = cx + rng.uniform(-dx / 2, dx / 2)
    y = cy + rng.uniform(-dy / 2, dy / 2)
    yaw = np.radians(s["heading_deg"] + rng.uniform(-noise_deg, noise_deg))
    return StartPose(float(x), float(y), float(yaw))


class ObjectSearchReferee(Referee):
    """Scores task 6 from the base, the target object and the pick state."""

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    def __init__(self, spec, plant, robot, scene: Scene):
        super().__init__(spec, plant, robot, scene)
        s = spec.scene
        self.target: str = scene.data["target"]
        self._target_index = scene.data["bodies"][self.target]
        self._table: Table = scene.data["tables"][s["table"]]
        self._table_region = self._table.grown(float(s["table_region_margin"]))
        self._requires_held = bool(s.get("table_region_requires_target_held", True))
        self._pick_radius = float(s["pick_region_radius"])
        self._place = s["place"]
        self._sentence: str = scene.data["instruction"]

    # Multibody elements (bodies, joints, frames) are kept as indices: a stored element holds its
    # plant through a reference the garbage collector cannot see (pr2_drake.lifetime).
    @property
    def _target_body(self):
        return self.plant.get_body(self._target_index)

    def holding_target(self, context) -> bool:
        p = self.pick_state(context)
        return p.attached and p.object == self.target

    def target_on_table(self) -> bool:
        """Target centre over the coffee table's top and slow (self.ctx holds the state)."""
        p = self.plant.EvalBodyPoseInWorld(self.ctx, self._target_body).translation()
        v = self.plant.EvalBodySpatialVelocityInWorld(self.ctx, self._target_body)
        dz = p[2] - self._table.height
        return bool(self._table.footprint.contains(p)
                    and 0.0 < dz <= float(self._place["max_height_above_top"])
                    and np.linalg.norm(v.translational()) < float(self._place["max_speed"]))

    def judge(self, context, status: EpisodeStatus) -> None:
        t = context.get_time()
        p_base = self.X_WB().translation()
        p_obj = self.plant.EvalBodyPoseInWorld(self.ctx, self._target_body).translation()
        if np.hypot(*(p_base[:2] - p_obj[:2])) <= self._pick_radius:
            self.award(status, "pick_region", t)
        held = self.holding_target(context)
        if held:
            self.award(status, "pick_target", t)
        if self._table_region.contains(p_base) and (held or not self._requires_held):
            self.award(status, "table_region", t)
        resting = (not held) and self.target_on_table()
        if held_for(status.memo, "place", resting, t) >= float(self._place["settle_time"]) - 1e-9:
            self.award(status, "place_on_table", t)

    def feedback(self, context) -> dict[str, Any]:
        p = self.pick_state(context)
        return {"pick_state": {"attached": p.attached, "hand": p.hand, "object": p.object}}

    def instruction(self) -> str:
        return self._sentence


class Task(TaskDefinition):
    def build_scene(self, plant: MultibodyPlant, rng: np.random.Generator) -> Scene:
        s = self.spec.scene
        tables = add_house(plant, s)
        target, poses, sentence, start = self.draw_episode(tables, rng)
        pick_distance = float(s["pick_distance"])
        bodies, graspables, models = {}, [], {}
        for name, o in s["objects"].items():
            sdf = resolve_user_path(o["model"], f"{name} model")
            (instance,) = Parser(plant, name).AddModels(str(sdf))
            body = plant.GetBodyByName(name, instance)
            plant.SetDefaultFloatingBaseBodyPose(body, poses[name])
            bodies[name] = body.index()
            models[name] = {"sdf": str(sdf), "mesh": str(sdf.with_suffix(".obj")),
                            "label": o["label"]}
            graspables.append(Graspable(
                name=name, body=body.index(), mode="weld",
                can_pick=lambda p_WH, X_WO: bool(
                    np.linalg.norm(p_WH - X_WO.translation()) <= pick_distance)))
        table = tables[s["table"]]
        priors = {
            "object_models": models,
            "coffee_table_center": [*table.center, table.height],
            "coffee_table_size": list(table.size),
            "instruction": sentence,
        }
        return Scene(
            name="object_search",
            start=start,
            graspables=graspables,
            priors=priors,
            data={"target": target, "bodies": bodies, "tables": tables,
                  "instruction": sentence, "target_room": table_room(tables, s, target),
                  "initial_poses": poses},
        )

    def draw_episode(self, tables: dict[str, Table], rng: np.random.Generator):
        """(target, object poses X_WO, sentence, start pose), all drawn from ``rng``."""
        target, poses, sentence, room_cfg = sample_layout(self.spec.scene, tables, rng)
        start = sample_room_start(room_cfg, self.spec.heading_noise_deg, rng)
        return target, poses, sentence, start

    def vary_scene(self, scene: dict, rng: np.random.Generator) -> dict:
        """A generated house (:func:`pr2_drake.tasks.house_gen.generate_house`)."""
        from pr2_drake.tasks.house_gen import generate_house

        return generate_house(scene, rng)

    def make_referee(self, plant, robot, scene) -> ObjectSearchReferee:
        return ObjectSearchReferee(self.spec, plant, robot, scene)


def table_room(tables: dict[str, Table], scene: dict, obj: str) -> str:
    """The room an object starts in (the room of the table it stands on)."""
    return tables[scene["objects"][obj]["table"]].room

"""Regions, markers and contact queries shared by the locomotion tasks (1, 3, 4, 5).

Regions are horizontal shapes in the world frame W (z ignored): a :class:`Rect` (axis-aligned,
``{"center": [x, y], "size": [dx, dy]}`` in the task YAML) or a :class:`Circle`
(``{"center": [x, y], "radius": r}``). Markers drawn for them are visual-only (illustration and
perception roles, no collision), so the head camera sees them and the robot does not feel them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterable, Union

import numpy as np
from pydrake.geometry import Box, Cylinder
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.plant import ContactResults, MultibodyPlant
from pydrake.multibody.tree import BodyIndex, ModelInstanceIndex

#: Arm bodies of KUAVO, per side: contact with any of these counts as "with the arm".
ARM_BODY_NAMES = tuple(
    f"{s}_{n}"
    for s in ("l", "r")
    for n in ("shoulder_pitch_link", "shoulder_roll_link", "upper_arm", "forearm", "arm_sphere")
)
FOOT_BODY_NAMES = ("l_foot", "r_foot")
SOLE_FRAME_NAMES = ("l_sole", "r_sole")

MARKER_THICKNESS = 0.002  # [m] thickness of the flat visual markers


@dataclass(frozen=True)
class Rect:
    """Axis-aligned rectangle: centre (x, y) [m] and full size (dx, dy) [m]."""

    center: tuple[float, float]
    size: tuple[float, float]

    def contains(self, p) -> bool:
        return (abs(p[0] - self.center[0]) <= self.size[0] / 2
                and abs(p[1] - self.center[1]) <= self.size[1] / 2)

    @property
    def min(self) -> np.ndarray:
        return np.asarray(self.center) - np.asarray(self.size) / 2

    @property
    def max(self) -> np.ndarray:
        return np.asarray(self.center) + np.asarray(self.size) / 2


@dataclass(frozen=True)
class Circle:
    """Disc: centre (x, y) [m] and radius [m]. ``contains`` uses the horizontal distance."""

    center: tuple[float, float]
    radius: float

    def contains(self, p) -> bool:
        return float(np.hypot(p[0] - self.center[0], p[1] - self.center[1])) <= self.radius


Region = Union[Rect, Circle]


def region_from_yaml(d: dict) -> Region:
    """A region from its YAML form; raises ValueError naming the bad keys."""
    if "radius" in d:
        return Circle(tuple(float(v) for v in d["center"][:2]), float(d["radius"]))
    if "size" in d:
        return Rect(tuple(float(v) for v in d["center"][:2]), tuple(float(v) for v in d["size"]))
    raise ValueError(f"a region needs 'center' and 'size' or 'radius', got keys {sorted(d)}")


def rgba(c: Iterable[float]) -> np.ndarray:
    c = [float(v) for v in c]
    return np.asarray(c if len(c) == 4 else c + [1.0])


def add_marker(plant: MultibodyPlant, name: str, region: Region, z: float, color,
               yaw: float = 0.0) -> None:
    """Draw ``region`` as a thin visual-only patch whose top is at height ``z`` [m]."""
    X = RigidTransform(RollPitchYaw(0, 0, yaw),
                       [region.center[0], region.center[1], z - MARKER_THICKNESS / 2])
    if isinstance(region, Circle):
        shape = Cylinder(region.radius, MARKER_THICKNESS)
    else:
        shape = Box(region.size[0], region.size[1], MARKER_THICKNESS)
    plant.RegisterVisualGeometry(plant.world_body(), X, shape, name, rgba(color))


def add_line_marker(plant: MultibodyPlant, name: str, p0, p1, z: float, color,
                    width: float = 0.03) -> None:
    """A thin visual-only strip from (x0, y0) to (x1, y1) at height ``z`` [m]."""
    p0, p1 = np.asarray(p0[:2], float), np.asarray(p1[:2], float)
    d = p1 - p0
    X = RigidTransform(RollPitchYaw(0, 0, float(np.arctan2(d[1], d[0]))),
                       [*(p0 + p1) / 2, z - MARKER_THICKNESS / 2])
    plant.RegisterVisualGeometry(plant.world_body(), X,
                                 Box(float(np.linalg.norm(d)), width, MARKER_THICKNESS), name,
                                 rgba(color))


def body_indices(plant: MultibodyPlant, robot: ModelInstanceIndex,
                 names: Iterable[str]) -> frozenset[BodyIndex]:
    return frozenset(plant.GetBodyByName(n, robot).index() for n in names)


def contact_pairs(contacts: ContactResults) -> list[tuple[BodyIndex, BodyIndex]]:
    """The (bodyA, bodyB) of every point-pair contact."""
    return [
        (contacts.point_pair_contact_info(i).bodyA_index(),
         contacts.point_pair_contact_info(i).bodyB_index())
        for i in range(contacts.num_point_pair_contacts())
    ]


def touching(pairs, group_a: frozenset, group_b: frozenset) -> bool:
    """Whether some contact pair has one body in ``group_a`` and the other in ``group_b``."""
    return any((a in group_a and b in group_b) or (b in group_a and a in group_b)
               for a, b in pairs)


def bodies_touching(pairs, group: frozenset, others: frozenset | None = None,
                    exclude: frozenset = frozenset()) -> set:
    """Bodies of ``group`` in contact with a body of ``others`` (None: any body outside
    ``group`` and ``exclude``)."""
    out = set()
    for a, b in pairs:
        for mine, other in ((a, b), (b, a)):
            if mine in group and other not in group and other not in exclude and (
                    others is None or other in others):
                out.add(mine)
    return out


def held_for(memo: dict, key: str, condition: bool, t: float) -> float:
    """Time [s] ``condition`` has held without interruption, sampled at the referee's ticks.

    ``memo`` is the referee's per-episode memory (``EpisodeStatus.memo``); the start time is kept
    under ``key``. The first tick at which the condition holds counts as its start, so a
    condition seen at ticks t0, t0 + h, ..., t1 has held for t1 - t0.
    """
    if not condition:
        memo[key] = None
        return 0.0
    if memo.get(key) is None:
        memo[key] = t
    return t - memo[key]

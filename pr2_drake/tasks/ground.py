"""The ground of the locomotion tasks' scenes: a rocky road of tilted boxes, a slope, a staircase.

Scene geometry: what the world is (bodies in the plant, and the heights the referee judges
falls and regions by). What a controller believes about the ground is its terrain model,
:mod:`pr2_drake.controllers.planning.terrain`, built from the priors alone. Each piece is built from convex boxes registered on the world body (point contact convexifies
meshes, so rough ground is made of many boxes), and knows its own terrain height
``height(x, y)`` [m] in the world frame W (``None`` off the piece). Dimensions come from the
task YAML (the ``scene`` section), given as keyword arguments of the dataclasses below.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from pydrake.geometry import Box
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix
from pydrake.multibody.plant import MultibodyPlant

from pr2_drake.materials import add_textured_box, add_textured_boxes
from pr2_drake.scene import GROUND_FRICTION
from pr2_drake.tasks.regions import Rect, rgba


def _add_box(plant: MultibodyPlant, name: str, X_WB: RigidTransform, size, color,
             collision: bool = True, material: str = "concrete") -> None:
    """A world-welded box: plain Box collision, textured glTF visual (pr2_drake.materials)."""
    add_textured_box(plant, name, X_WB, size, rgba(color), material,
                     GROUND_FRICTION if collision else None)


@dataclass
class RockyRoad:
    """A road of ``cells[0] x cells[1]`` stones (boxes) along +x, generated from ``seed``.

    Every stone's top face is a plane: its centre is ``height_range`` above z = 0, tilted about x
    and y by up to ``tilt_max_deg``. Stones reach ``depth`` below z = 0 (they sit in the ground
    box) and are separated by ``gap``. The road's layout depends only on its parameters, never
    on the episode seed.

    Attributes:
        seed: the road seed (fixed per release, in the task YAML).
        start_x, center_y: where the road begins (x) and its centre line (y) [m].
        length, width: road extent along x and y [m].
        cells: number of stones along x and across y.
        height_range: [min, max] height of a stone's top-face centre above z = 0 [m].
        tilt_max_deg: maximum roll and pitch of a stone [deg].
        gap: gap between neighbouring stones [m].
        depth: how far stones reach below z = 0 [m].
        colors: stone colours (RGB or RGBA), picked at random per stone.
    """

    seed: int
    start_x: float
    length: float
    width: float
    cells: list[int]
    height_range: list[float]
    tilt_max_deg: float
    center_y: float = 0.0
    gap: float = 0.002
    depth: float = 0.05
    colors: list[list[float]] = field(default_factory=lambda: [[0.45, 0.40, 0.35]])

    def __post_init__(self):
        rng = np.random.default_rng(self.seed)
        nx, ny = self.cells
        self.dx, self.dy = self.length / nx, self.width / ny
        self.top = rng.uniform(*self.height_range, size=(nx, ny))
        tilt = np.radians(self.tilt_max_deg)
        self.roll = rng.uniform(-tilt, tilt, size=(nx, ny))
        self.pitch = rng.uniform(-tilt, tilt, size=(nx, ny))
        self.color_index = rng.integers(len(self.colors), size=(nx, ny))
        # Top-face normal of each stone (world frame), for height queries.
        self.normal = np.zeros((nx, ny, 3))
        for i in range(nx):
            for j in range(ny):
                R = RotationMatrix(RollPitchYaw(self.roll[i, j], self.pitch[i, j], 0.0))
                self.normal[i, j] = R.matrix()[:, 2]

    @property
    def footprint(self) -> Rect:
        return Rect((self.start_x + self.length / 2, self.center_y), (self.length, self.width))

    def cell_center(self, i: int, j: int) -> np.ndarray:
        """Centre (x, y) of stone (i, j) [m]."""
        return np.array([self.start_x + (i + 0.5) * self.dx,
                         self.center_y - self.width / 2 + (j + 0.5) * self.dy])

    def stone_pose(self, i: int, j: int) -> tuple[RigidTransform, np.ndarray]:
        """X_WS of stone (i, j) (box centre) and its size [m]."""
        c = self.cell_center(i, j)
        thickness = self.top[i, j] + self.depth
        R = RotationMatrix(RollPitchYaw(self.roll[i, j], self.pitch[i, j], 0.0))
        p_top = np.array([c[0], c[1], self.top[i, j]])
        p_center = p_top - R.matrix() @ np.array([0.0, 0.0, thickness / 2])
        size = (self.dx - self.gap, self.dy - self.gap, thickness)
        return RigidTransform(R, p_center), np.array(size)

    @property
    def num_stones(self) -> int:
        return int(self.cells[0] * self.cells[1])

    def add_to(self, plant: MultibodyPlant, prefix: str = "rock") -> None:
        nx, ny = self.cells
        by_color: dict[int, list] = {}
        for i in range(nx):
            for j in range(ny):
                X, size = self.stone_pose(i, j)
                plant.RegisterCollisionGeometry(plant.world_body(), X, Box(*size),
                                                f"{prefix}_{i}_{j}", GROUND_FRICTION)
                by_color.setdefault(int(self.color_index[i, j]), []).append((X, size))
        # One visual mesh per stone colour: a few glTF files instead of one per stone.
        for c, boxes in sorted(by_color.items()):
            add_textured_boxes(plant, f"{prefix}_visual_{c}", boxes, rgba(self.colors[c]), "rock")

    def height(self, x: float, y: float) -> float | None:
        """Top-face height of the stone under (x, y) [m], or None off the road."""
        i = int(np.floor((x - self.start_x) / self.dx))
        j = int(np.floor((y - (self.center_y - self.width / 2)) / self.dy))
        if not (0 <= i < self.cells[0] and 0 <= j < self.cells[1]):
            return None
        c = self.cell_center(i, j)
        n = self.normal[i, j]
        return float(self.top[i, j] - (n[0] * (x - c[0]) + n[1] * (y - c[1])) / n[2])


@dataclass
class Slope:
    """Level ground, a ramp of ``angle_deg`` rising along +x, then a level plateau.

    Attributes:
        start_x: where the ramp leaves the ground (x) [m].
        run: horizontal length of the ramp [m]; it rises ``run * tan(angle)``.
        angle_deg: incline [deg].
        width: extent across the ramp (y), centred on ``center_y`` [m].
        plateau_length: length of the level top after the ramp [m].
        thickness: thickness of the ramp slab [m] (below its surface).
        colors: {"ramp": rgb, "plateau": rgb}.
    """

    start_x: float
    run: float
    angle_deg: float
    width: float
    plateau_length: float
    center_y: float = 0.0
    thickness: float = 0.3
    colors: dict[str, list[float]] = field(default_factory=dict)

    @property
    def rise(self) -> float:
        return self.run * float(np.tan(np.radians(self.angle_deg)))

    @property
    def end_x(self) -> float:
        """Where the ramp meets the plateau (x) [m]."""
        return self.start_x + self.run

    @property
    def ramp_footprint(self) -> Rect:
        return Rect((self.start_x + self.run / 2, self.center_y), (self.run, self.width))

    @property
    def plateau_footprint(self) -> Rect:
        return Rect((self.end_x + self.plateau_length / 2, self.center_y),
                    (self.plateau_length, self.width))

    def add_to(self, plant: MultibodyPlant) -> None:
        a = np.radians(self.angle_deg)
        along = self.run / np.cos(a)
        R = RotationMatrix(RollPitchYaw(0.0, -a, 0.0))  # +x of the slab points up the ramp
        p_top_mid = np.array([self.start_x + self.run / 2, self.center_y, self.rise / 2])
        p = p_top_mid - R.matrix() @ np.array([0.0, 0.0, self.thickness / 2])
        _add_box(plant, "ramp", RigidTransform(R, p), (along, self.width, self.thickness),
                 self.colors.get("ramp", [0.55, 0.45, 0.35]))
        _add_box(plant, "plateau",
                 RigidTransform([self.end_x + self.plateau_length / 2, self.center_y,
                                 self.rise / 2]),
                 (self.plateau_length, self.width, self.rise),
                 self.colors.get("plateau", [0.5, 0.5, 0.45]))

    def height(self, x: float, y: float) -> float | None:
        """Surface height at (x, y) [m] over the ramp or plateau, None elsewhere."""
        if abs(y - self.center_y) > self.width / 2:
            return None
        if self.start_x <= x <= self.end_x:
            return (x - self.start_x) * float(np.tan(np.radians(self.angle_deg)))
        if self.end_x < x <= self.end_x + self.plateau_length:
            return self.rise
        return None


@dataclass
class Staircase:
    """``count`` steps up along +x, each ``height`` high and ``depth`` deep, then a level floor.

    Attributes:
        start_x: front edge of the first step (x) [m].
        count, height, depth, width: number of steps, riser height, tread depth, width (y) [m].
        floor_length: length of the level floor at the top, after the last step [m].
        colors: {"steps": [rgb, ...] (cycled), "floor": rgb}.
    """

    start_x: float
    count: int
    height: float
    depth: float
    width: float
    floor_length: float
    center_y: float = 0.0
    colors: dict[str, list] = field(default_factory=dict)

    @property
    def floor_start_x(self) -> float:
        return self.start_x + self.count * self.depth

    @property
    def floor_end_x(self) -> float:
        return self.floor_start_x + self.floor_length

    @property
    def top(self) -> float:
        return self.count * self.height

    def tread(self, k: int) -> Rect:
        """Footprint of step k (1-based); k = count + 1 is the floor."""
        x0 = self.start_x + (k - 1) * self.depth
        length = self.depth if k <= self.count else self.floor_length
        return Rect((x0 + length / 2, self.center_y), (length, self.width))

    def add_to(self, plant: MultibodyPlant) -> None:
        step_colors = self.colors.get("steps", [[0.35, 0.5, 0.75], [0.3, 0.65, 0.7]])
        for k in range(1, self.count + 1):
            r = self.tread(k)
            h = k * self.height
            _add_box(plant, f"step_{k}", RigidTransform([r.center[0], r.center[1], h / 2]),
                     (r.size[0], r.size[1], h), step_colors[(k - 1) % len(step_colors)])
        r = self.tread(self.count + 1)
        _add_box(plant, "step_floor", RigidTransform([r.center[0], r.center[1], self.top / 2]),
                 (r.size[0], r.size[1], self.top), self.colors.get("floor", [0.6, 0.6, 0.55]))

    def level(self, x: float, y: float) -> int:
        """Which level is under (x, y): 0 = ground, k = step k, count + 1 = the floor."""
        if abs(y - self.center_y) > self.width / 2 or x < self.start_x or x > self.floor_end_x:
            return 0
        return min(int((x - self.start_x) // self.depth) + 1, self.count + 1)

    def height_at(self, x: float, y: float) -> float:
        """Surface height at (x, y) [m] (0 off the staircase)."""
        return min(self.level(x, y), self.count) * self.height

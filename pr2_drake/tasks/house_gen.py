"""Generated houses for task 6 (``scene.variation``): a new layout of the same house from a seed.

:func:`generate_house` rewrites a copy of the ``scene`` block of ``tasks/6_object_search.yaml``
(the schema :mod:`pr2_drake.tasks.house` builds from), with the rules and figures of its
``scene.variation`` block:

1. rooms: within the footprint (the outer walls), a wall across the house at an offset drawn
   from ``split``, and each half cut across at its own offset: four rectangular rooms;
2. doorways (``door_width``, at least ``door_margin`` from corners and junctions): one in each
   inner wall between the two rooms of a half, one across the long wall where two rooms face
   each other over a long enough stretch (a second one with chance ``second_door``): every room
   reaches every other;
3. the four room names are dealt to the four rooms at random;
4. each room's furniture (its ``furniture`` entries, sizes and heights kept) is turned by 0 or
   90 deg and placed with ``table_clearance`` of free floor before both long sides and
   ``table_end_clearance`` at its ends, clear of every doorway by ``door_clearance``;
5. the room's decor groups (``variation.decor``) stand against its walls, off the doorways and
   the tables' free floor (a group that finds no place is left out);
6. checked on a grid: a robot of ``robot_radius`` passes from every doorway to every other and
   to both long sides of every table; a house that fails is drawn again;
7. a start rectangle (``start_size``) in every room that can hold the target, ``start_clearance``
   from walls and furniture, facing the room's centre;
8. which table holds each object: uniformly among the tables other than the destination, at
   most ``max_objects_per_table`` on one.

The episode then draws the target, the objects' poses on their tables, the sentence and the
start from the episode seed exactly as in the task's own house (:mod:`t6_object_search`).
Positions in m in the world frame W; a rectangle is (x0, y0, x1, y1).
"""

from __future__ import annotations

import math
from typing import Any

import cv2
import numpy as np

Rect4 = tuple  # (x0, y0, x1, y1) [m]
GRID = 0.05  # [m] cell of the reachability check
TRIES = 60  # houses drawn before giving up


class HouseError(RuntimeError):
    """No valid house from these figures within :data:`TRIES` draws."""


def _overlap(a: Rect4, b: Rect4, gap: float = 0.0) -> bool:
    return a[0] < b[2] + gap and b[0] < a[2] + gap and a[1] < b[3] + gap and b[1] < a[3] + gap


def _inside(a: Rect4, b: Rect4) -> bool:
    return a[0] >= b[0] - 1e-9 and a[1] >= b[1] - 1e-9 and a[2] <= b[2] + 1e-9 \
        and a[3] <= b[3] + 1e-9


def _rect(center, size) -> Rect4:
    return (center[0] - size[0] / 2, center[1] - size[1] / 2, center[0] + size[0] / 2,
            center[1] + size[1] / 2)


def _grow(r: Rect4, gx: float, gy: float) -> Rect4:
    return (r[0] - gx, r[1] - gy, r[2] + gx, r[3] + gy)


def footprint(scene: dict) -> Rect4:
    """The bounding box of the house's wall segments (its outer walls)."""
    pts = np.array([p for seg in scene["walls"]["segments"] for p in seg], float)
    return (*pts.min(0), *pts.max(0))


# -- 1-3: rooms, doorways, walls -----------------------------------------------------------------
def _layout(v: dict, box: Rect4, rng: np.random.Generator):
    """(rooms, doors, segments) in W: four room rectangles; doorways as (room a, room b,
    centre (x, y), wall axis 0: along x / 1: along y); wall segments [[x, y], [x, y]].
    Drawn in a frame where the long wall is x = c, then transposed half the time."""
    transpose = bool(rng.integers(2))
    if transpose:
        box = (box[1], box[0], box[3], box[2])
    x0, y0, x1, y1 = box
    mx, my = (x0 + x1) / 2, (y0 + y1) / 2
    c, c1, c2 = (float(rng.uniform(*v["split"])) for _ in range(3))
    c, c1, c2 = mx + c, my + c1, my + c2
    rooms = [(x0, y0, c, c1), (x0, c1, c, y1), (c, y0, x1, c2), (c, c2, x1, y1)]
    w, m = float(v["door_width"]), float(v["door_margin"])

    def door_at(lo: float, hi: float) -> float:
        return float(rng.uniform(lo + m + w / 2, hi - m - w / 2))

    doors = [(0, 1, (door_at(x0, c), c1), 0), (2, 3, (door_at(c, x1), c2), 0)]
    spans = [(0, 2, y0, min(c1, c2)), (1, 3, max(c1, c2), y1)]
    spans.append((0, 3, c2, c1) if c1 > c2 else (1, 2, c1, c2))
    usable = [s for s in spans if s[3] - s[2] >= w + 2 * m]
    order = rng.permutation(len(usable))
    count = 1 + int(len(usable) > 1 and rng.uniform() < float(v["second_door"]))
    for k in order[:count]:
        a, b, lo, hi = usable[k]
        doors.append((a, b, (c, door_at(lo, hi)), 1))
    segments = [[[x0, y0], [x1, y0]], [[x1, y0], [x1, y1]], [[x1, y1], [x0, y1]],
                [[x0, y1], [x0, y0]]]
    walls = [((x0, c1), (c, c1), 0), ((c, c2), (x1, c2), 0), ((c, y0), (c, y1), 1)]
    for p0, p1, axis in walls:
        cuts = sorted(d[2][axis] for d in doors if d[3] == axis and d[2][1 - axis] == p0[1 - axis]
                      and p0[axis] < d[2][axis] < p1[axis])
        a = p0[axis]
        for cut in cuts + [None]:
            b = p1[axis] if cut is None else cut - w / 2
            if b - a > 1e-6:
                q0, q1 = list(p0), list(p0)
                q0[axis], q1[axis] = a, b
                segments.append([q0, q1])
            if cut is not None:
                a = cut + w / 2
    if transpose:
        def t(p):
            return [p[1], p[0]]

        rooms = [(r[1], r[0], r[3], r[2]) for r in rooms]
        doors = [(a, b, (p[1], p[0]), 1 - axis) for a, b, p, axis in doors]
        segments = [[t(p), t(q)] for p, q in segments]
    return rooms, doors, segments


def _door_zones(doors, v: dict, thickness: float) -> list[Rect4]:
    """Where no furniture stands: each doorway's gap (plus the walls' thickness) by
    ``door_clearance`` on either side."""
    w, dc = float(v["door_width"]), float(v["door_clearance"])
    out = []
    for _, _, (x, y), axis in doors:
        half = (w + thickness) / 2
        out.append((x - half, y - dc, x + half, y + dc) if axis == 0
                   else (x - dc, y - half, x + dc, y + half))
    return out


# -- 4-5: furniture ------------------------------------------------------------------------------
def _place_table(cfg: dict, interior: Rect4, zones, v: dict, rng) -> tuple[dict, Rect4] | None:
    """A table of this room: (its furniture entry, the rectangle of it and its free floor)."""
    long_gap, end_gap = float(v["table_clearance"]), float(v["table_end_clearance"])
    for _ in range(200):
        yaw = 90.0 * int(rng.integers(2))
        sx, sy = cfg["size"] if yaw == 0.0 else cfg["size"][::-1]
        gx, gy = (end_gap, long_gap) if sx >= sy else (long_gap, end_gap)
        lo = (interior[0] + sx / 2 + gx, interior[1] + sy / 2 + gy)
        hi = (interior[2] - sx / 2 - gx, interior[3] - sy / 2 - gy)
        if lo[0] > hi[0] or lo[1] > hi[1]:
            continue
        center = (float(rng.uniform(lo[0], hi[0])), float(rng.uniform(lo[1], hi[1])))
        zone = _grow(_rect(center, (sx, sy)), gx, gy)
        if not any(_overlap(zone, z) for z in zones):
            return {**cfg, "center": list(center), "size": [sx, sy], "yaw_deg": yaw}, zone
    return None


def _place_decor(group: list, interior: Rect4, blocked: list, v: dict, rng) -> list | None:
    """The parts of a decor group against one of the room's walls: [(part, rect, size3)]."""
    gap = float(v["decor_gap"])
    reach = max(abs(p["along"]) + p["size"][0] / 2 for p in group)
    for _ in range(60):
        side = int(rng.integers(4))  # the wall at x0, x1, y0, y1 of the interior
        along_y = side < 2
        lo, hi = (interior[1], interior[3]) if along_y else (interior[0], interior[2])
        if hi - lo < 2 * reach:
            continue
        s = float(rng.uniform(lo + reach, hi - reach))
        face = interior[side % 2 * 2 + (0 if along_y else 1)]
        inward = 1.0 if side % 2 == 0 else -1.0
        parts = []
        for p in group:
            a, o = s + p["along"], face + inward * p["out"]
            length, depth, height = p["size"]
            center, size = ((o, a), (depth, length)) if along_y else ((a, o), (length, depth))
            parts.append((p, _rect(center, size), [*size, height]))
        if all(_inside(r, interior) and not any(_overlap(r, b, gap) for b in blocked)
               for _, r, _ in parts):
            return parts
    return None


# -- 6-7: checks on a grid -----------------------------------------------------------------------
class _Grid:
    """Occupied cells of walls and furniture over the footprint, and the free space of a robot
    of radius r (cells farther than r from any occupied one)."""

    def __init__(self, box: Rect4, boxes: list[Rect4]):
        self.box = box
        cols = int(round((box[2] - box[0]) / GRID))
        rows = int(round((box[3] - box[1]) / GRID))
        x = box[0] + (np.arange(cols) + 0.5) * GRID
        y = box[1] + (np.arange(rows) + 0.5) * GRID
        X, Y = np.meshgrid(x, y)
        occ = np.zeros((rows, cols), bool)
        occ[[0, -1], :] = True
        occ[:, [0, -1]] = True
        for r in boxes:
            occ |= (X >= r[0]) & (X <= r[2]) & (Y >= r[1]) & (Y <= r[3])
        self.distance = cv2.distanceTransform((~occ).astype(np.uint8), cv2.DIST_L2, 5) * GRID

    def cell(self, p) -> tuple[int, int]:
        return (int((p[1] - self.box[1]) // GRID), int((p[0] - self.box[0]) // GRID))

    def components(self, radius: float) -> np.ndarray:
        return cv2.connectedComponents((self.distance > radius).astype(np.uint8), 4)[1]


def _wall_boxes(segments, thickness: float) -> list[Rect4]:
    out = []
    for p, q in segments:
        x0, x1 = sorted((p[0], q[0]))
        y0, y1 = sorted((p[1], q[1]))
        out.append((x0 - thickness / 2, y0 - thickness / 2, x1 + thickness / 2,
                    y1 + thickness / 2))
    return out


def access_points(table: dict, standoff: float) -> list[tuple[float, float]]:
    """Where a robot stands ``standoff`` [m] before the middle of each long side of a table."""
    (cx, cy), (sx, sy) = table["center"], table["size"]
    if sx >= sy:
        return [(cx, cy - sy / 2 - standoff), (cx, cy + sy / 2 + standoff)]
    return [(cx - sx / 2 - standoff, cy), (cx + sx / 2 + standoff, cy)]


def _start(room: Rect4, grid: _Grid, main: np.ndarray, label: int, v: dict, rng):
    """A free start rectangle in ``room``, facing its centre, or None."""
    w, h = v["start_size"]
    clear, radius = float(v["start_clearance"]), float(v["robot_radius"])
    for _ in range(200):
        c = (float(rng.uniform(room[0] + w / 2 + clear, room[2] - w / 2 - clear)),
             float(rng.uniform(room[1] + h / 2 + clear, room[3] - h / 2 - clear)))
        corners = [(c[0] + sx * w / 2, c[1] + sy * h / 2) for sx in (-1, 1) for sy in (-1, 1)]
        cells = [grid.cell(p) for p in corners + [c]]
        if all(grid.distance[k] > max(clear, radius) and main[k] == label for k in cells):
            mid = ((room[0] + room[2]) / 2, (room[1] + room[3]) / 2)
            heading = math.degrees(math.atan2(mid[1] - c[1], mid[0] - c[0]))
            return {"center": list(c), "size": [w, h], "heading_deg": heading}
    return None


# -- the house -----------------------------------------------------------------------------------
def generate_house(scene: dict, rng: np.random.Generator) -> dict[str, Any]:
    """Rewrite ``scene`` (a copy of the task's ``scene`` block) as a house drawn from ``rng``
    (module docstring); returns a summary (rooms, tables, which table holds each object).
    Raises :class:`HouseError` when no draw of :data:`TRIES` is valid."""
    v = scene["variation"]
    for _ in range(TRIES):
        house = _draw(scene, v, rng)
        if house is not None:
            break
    else:
        raise HouseError(f"task 6: no valid house in {TRIES} draws; check scene.variation")
    rooms, segments, furniture, decor, starts = house
    scene["walls"]["segments"] = segments
    for name, r in rooms.items():
        room = scene["rooms"][name]
        room["rect"] = {"center": [(r[0] + r[2]) / 2, (r[1] + r[3]) / 2],
                        "size": [r[2] - r[0], r[3] - r[1]]}
        room.pop("start", None)
        if name in starts:
            room["start"] = starts[name]
    scene["furniture"] = furniture
    scene["decor"] = decor
    tables = [k for k in furniture if k != scene["table"]]
    count = dict.fromkeys(tables, 0)
    for obj in scene["objects"].values():
        free = [k for k in tables if count[k] < int(v["max_objects_per_table"])]
        obj["table"] = free[int(rng.integers(len(free)))]
        count[obj["table"]] += 1
    return {"rooms": {k: [round(float(x), 3) for x in r] for k, r in rooms.items()},
            "tables": {k: [round(float(f["center"][0]), 3), round(float(f["center"][1]), 3), f["yaw_deg"]]
                       for k, f in furniture.items()},
            "objects": {k: o["table"] for k, o in scene["objects"].items()}}


def _draw(scene: dict, v: dict, rng):
    """One draw of rooms, walls, furniture, decor and starts; None when a check fails."""
    box = footprint(scene)
    t = float(scene["walls"]["thickness"])
    rects, doors, segments = _layout(v, box, rng)
    names = [list(scene["rooms"])[k] for k in rng.permutation(len(scene["rooms"]))]
    rooms = dict(zip(names, rects))
    zones = _door_zones(doors, v, t)
    decor_by_name = {d["name"]: d for d in scene.get("decor", [])}
    furniture, decor, blocked = {}, [], []
    for name, r in rooms.items():
        interior = _grow(r, -t / 2, -t / 2)
        room_blocked = list(zones)
        for key, cfg in scene["furniture"].items():
            if cfg["room"] != name:
                continue
            placed = _place_table(cfg, interior, room_blocked, v, rng)
            if placed is None:
                return None
            furniture[key], zone = placed
            room_blocked.append(zone)
            blocked.append(_rect(placed[0]["center"], placed[0]["size"]))
        for group in v["decor"].get(name, []):
            parts = _place_decor(group, interior, room_blocked, v, rng)
            for part, rect, size in parts or []:
                room_blocked.append(rect)
                blocked.append(rect)
                base = decor_by_name[part["name"]]
                decor.append({**base, "center": [(rect[0] + rect[2]) / 2,
                                                 (rect[1] + rect[3]) / 2], "size": size})
    grid = _Grid(box, _wall_boxes(segments, t) + blocked)
    labels = grid.components(float(v["robot_radius"]))
    must = [d[2] for d in doors] + [p for f in furniture.values()
                                    for p in access_points(f, float(v["robot_radius"]) + 0.1)]
    reached = {int(labels[grid.cell(p)]) for p in must}
    if len(reached) != 1 or 0 in reached:
        return None
    main = reached.pop()
    starts = {}
    # In furniture order (a set's order would follow the process's string hash seed).
    holders = list(dict.fromkeys(f["room"] for k, f in furniture.items() if k != scene["table"]))
    for name in holders:
        start = _start(rooms[name], grid, labels, main, v, rng)
        if start is None:
            return None
        starts[name] = start
    return rooms, segments, furniture, decor, starts

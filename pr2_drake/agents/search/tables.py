"""The tops the task-6 search agent stands at (from its map, or the coffee table of the priors):
the side to stand at, the order to search them in, and poses relative to a table or the robot's
heading.

Positions in m, world frame W; a pose is (x, y, yaw) [m, m, rad]; a side of a table is its
outward unit normal (x, y).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import numpy as np

from pr2_drake.agents.search.navigation import OccupancyGrid


@dataclass(frozen=True)
class Table:
    """A flat top (a table's, from the map or the priors): centre (x, y), size (x, y) [m] (axis
    aligned), top height [m]."""

    name: str
    center: np.ndarray
    size: np.ndarray
    height: float

    def side_frame(self, normal: np.ndarray):
        """(half depth along ``normal``, unit tangent, half length along the tangent)."""
        n = np.asarray(normal, float)
        t = np.array([-n[1], n[0]])
        return (float(abs(n) @ self.size) / 2, t, float(abs(t) @ self.size) / 2)

    def contains(self, p, margin: float = 0.0) -> bool:
        return bool(np.all(np.abs(np.asarray(p)[:2] - self.center) <= self.size / 2 + margin))


def best_side(grid: OccupancyGrid, table: Table, standoff: float, radius: float) -> np.ndarray:
    """Outward unit normal (x, y) of the table side to stand at: the long sides first, the one
    with the most free floor in front (ray on the grid inflated by ``radius``)."""
    return sides_by_preference(grid, table, standoff, radius)[0]


def sides_by_preference(grid: OccupancyGrid, table: Table, standoff: float,
                        radius: float) -> list[np.ndarray]:
    """The four outward unit normals (x, y) of ``table``'s sides, best first (as
    :func:`best_side` ranks them; ties in the order +x, -x, +y, -y)."""
    g = grid.inflated(radius)
    ranked = []
    for n in (np.array([1.0, 0.0]), np.array([-1.0, 0.0]), np.array([0.0, 1.0]),
              np.array([0.0, -1.0])):
        half, _, half_len = table.side_frame(n)
        free = 0.0
        for d in np.arange(standoff, 2.0, 0.05):
            if not g.free(table.center + n * (half + d)):
                break
            free = d
        ranked.append(((free >= standoff + 0.2, half_len >= half, free), n))
    # sorted() is stable with reverse=True too: equal keys keep the order above.
    return [n for _, n in sorted(ranked, key=lambda kn: kn[0], reverse=True)]


#: [m] a point seen up to this high above a top is on it (the tallest object is shorter).
ON_TOP_HEIGHT = 0.35


def seen_on(top: Table, p_W, margin: float) -> bool:
    """Whether a point p_W (x, y, z) [m] seen by the camera lies on ``top``: within its
    outline grown by ``margin`` and above it by less than :data:`ON_TOP_HEIGHT`."""
    return top.contains(p_W, margin) and 0.0 < p_W[2] - top.height < ON_TOP_HEIGHT


def surface_order(tops: list[Table], hints: list, expected_height: Optional[float], p0,
                  params) -> list[Table]:
    """The tops to search, most likely first: those the target was seen on (a hint within
    ``search_margin`` of the top, at most 0.35 m above it), then those of the height of the
    furniture the sentence names (within ``height_tolerance``), then the nearest to p0."""

    def key(s: Table):
        hinted = any(seen_on(s, h, params.search_margin) for h in hints)
        fits = expected_height is not None and abs(s.height - expected_height) <= \
            params.height_tolerance
        return (not hinted, not fits, float(np.linalg.norm(s.center - np.asarray(p0)[:2])))

    return sorted(tops, key=key)


def pose_at(tab: Table, n: np.ndarray, along: float, standoff: float) -> np.ndarray:
    """The pose ``standoff`` [m] out from ``tab``'s side ``n``, ``along`` [m] along that side
    (within 0.1 m of its ends), facing the table."""
    half, t, half_len = tab.side_frame(n)
    along = float(np.clip(along, -half_len - 0.1, half_len + 0.1))
    xy = tab.center + n * (half + standoff) + t * along
    return np.array([xy[0], xy[1], math.atan2(-n[1], -n[0])])


def heading_frame(yaw: float, err_W) -> tuple[float, float]:
    """A horizontal vector of W in the heading frame (x ahead, y left) of heading ``yaw``."""
    cy, sy = math.cos(yaw), math.sin(yaw)
    return cy * err_W[0] + sy * err_W[1], -sy * err_W[0] + cy * err_W[1]


def in_heading(p_WB, yaw: float, p_W) -> np.ndarray:
    """p_W relative to the base in its heading frame (x ahead, y left, z up) [m]."""
    d = np.asarray(p_W, float) - np.asarray(p_WB, float)
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1], d[2]])


def out_from_under(p_WH, heading, tab: Table, margin: float):
    """Where the hand goes first when it hangs below ``tab``'s top within ``margin`` of its
    footprint: straight back along ``heading`` (unit, x-y) at its height until it is that far
    outside (at most 0.2 m back); None when it hangs clear."""
    if p_WH[2] >= tab.height or not tab.contains(p_WH, margin):
        return None
    back = np.array(p_WH, float)
    for _ in range(10):
        back[:2] -= 0.02 * heading
        if not tab.contains(back, margin):
            break
    return back

"""Generated houses of task 6 (``scene.variation``): valid from the seed (walls closed, doorways
passable for the robot's footprint between every two rooms, every object on a table the robot
can reach, start poses free), the same seed the same house, another seed another; the priors
and the sentence describe the house built."""

import numpy as np
import pytest

from pr2_drake.agents.search.navigation import OccupancyGrid, house_obstacles, plan_path
from pr2_drake.tasks import get_task
from pr2_drake.tasks.house import Table
from pr2_drake.tasks.house_gen import access_points
from pr2_drake.tasks.t6_object_search import sample_layout

TASK = get_task(6)
SEEDS = range(24)
ROBOT_RADIUS = 0.32  # the search agent's (params/agents/search_navigation.yaml)


def house(seed: int) -> dict:
    return TASK.varied(seed).spec.scene


def tables(scene: dict) -> dict[str, Table]:
    return {k: Table(k, f["label"], f["room"], tuple(f["center"]), tuple(f["size"]),
                     float(f["height"])) for k, f in scene["furniture"].items()}


def wall_lines(scene: dict) -> dict:
    """Collinear wall segments grouped by their line: (axis, offset) -> [(lo, hi), ...]."""
    lines: dict = {}
    for p, q in scene["walls"]["segments"]:
        axis = 0 if abs(p[1] - q[1]) < 1e-9 else 1  # 0: along x
        key = (axis, round(p[1 - axis], 9))
        lines.setdefault(key, []).append(tuple(sorted((p[axis], q[axis]))))
    return lines


def test_the_same_seed_gives_the_same_house_and_another_seed_another():
    assert house(3) == house(3) and TASK.varied(3).variation == TASK.varied(3).variation
    layouts = {str(house(s)["walls"]["segments"]) for s in SEEDS}
    assert len(layouts) == len(SEEDS)
    assert TASK.spec.scene != house(0) and TASK.variation is None  # the task's own is kept


@pytest.mark.parametrize("seed", SEEDS)
def test_walls_are_closed_with_doorways_the_only_openings(seed):
    scene = house(seed)
    v = scene["variation"]
    lines = wall_lines(scene)
    for (axis, offset), spans in lines.items():
        spans.sort()
        if abs(offset) == 4.0:  # an outer wall: whole
            assert spans == [(-4.0, 4.0)], spans
            continue
        gaps = [b[0] - a[1] for a, b in zip(spans, spans[1:])]
        assert all(g == pytest.approx(v["door_width"]) for g in gaps)  # only doorways
        assert spans[0][0] >= -4.0 and spans[-1][1] <= 4.0
    # Four rooms tiling the footprint, each with a table or its decor inside.
    area = sum(r["rect"]["size"][0] * r["rect"]["size"][1] for r in scene["rooms"].values())
    assert area == pytest.approx(64.0)
    for f in scene["furniture"].values():  # every table inside its own room
        r = scene["rooms"][f["room"]]["rect"]
        assert np.all(np.abs(np.subtract(f["center"], r["center"])) + np.array(f["size"]) / 2
                      <= np.array(r["size"]) / 2)


@pytest.mark.parametrize("seed", SEEDS[::2])
def test_a_robot_passes_between_every_two_rooms_and_reaches_every_table(seed):
    scene = house(seed)
    grid = OccupancyGrid.from_scene(scene)
    free = grid.inflated(ROBOT_RADIUS)
    places = []
    for name, room in scene["rooms"].items():
        if "start" in room:
            places.append(room["start"]["center"])
    for f in scene["furniture"].values():  # both long sides of every table, free floor
        for p in access_points(f, 0.55):
            assert free.free(p), (f, p)
            places.append(p)
    rooms_seen = set()
    for p in places:
        path = plan_path(grid, places[0], p, ROBOT_RADIUS)  # NoPathError if none
        assert np.linalg.norm(path[-1] - p) < 0.05 and np.linalg.norm(path[0] - places[0]) < 0.05
        rooms_seen |= {k for k, r in scene["rooms"].items()
                       if np.all(np.abs(np.subtract(p, r["rect"]["center"]))
                                 <= np.array(r["rect"]["size"]) / 2)}
    assert rooms_seen == set(scene["rooms"])  # every room, from one start


@pytest.mark.parametrize("seed", SEEDS)
def test_objects_stand_within_reach_and_starts_are_free(seed):
    scene = house(seed)
    t = tables(scene)
    target, poses, sentence, room = sample_layout(scene, t, np.random.default_rng(seed))
    per_table: dict = {}
    for name, X in poses.items():
        table = t[scene["objects"][name]["table"]]
        assert table.name != scene["table"]  # never on the destination
        per_table[table.name] = per_table.get(table.name, 0) + 1
        p = X.translation()
        inner = table.grown(-scene["placement_margin"])  # on the top, off its edges
        assert inner.contains(p) and p[2] > table.height
    assert max(per_table.values()) <= scene["variation"]["max_objects_per_table"]
    # The sentence names the target's table and room of this house; the start is in that room.
    home = t[scene["objects"][target]["table"]]
    assert scene["objects"][target]["label"] in sentence
    assert home.label in sentence or scene["rooms"][home.room]["label"] in sentence
    assert room is scene["rooms"][home.room]
    start = TASK.varied(seed).draw_episode(t, np.random.default_rng(seed))[3]
    r = room["rect"]
    assert np.all(np.abs(np.subtract([start.x, start.y], r["center"])) <= np.array(r["size"]) / 2)
    for box in house_obstacles(scene):  # the footprint clear of walls and furniture
        assert box.distance(np.array([start.x, start.y])) > 0.3, box.name


def test_a_generated_house_builds_and_its_priors_describe_it():
    from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
    from pydrake.systems.framework import DiagramBuilder

    from pr2_drake.robot.model import add_kuavo

    task = TASK.varied(5)
    plant, _ = AddMultibodyPlantSceneGraph(DiagramBuilder(), 0.002)
    add_kuavo(plant)
    scene = task.build_scene(plant, np.random.default_rng(5))
    plant.Finalize()
    coffee = task.spec.scene["furniture"]["coffee_table"]
    assert scene.priors["coffee_table_center"] == [*coffee["center"], coffee["height"]]
    assert scene.priors["coffee_table_size"] == coffee["size"]
    assert scene.priors["instruction"] == scene.data["instruction"]
    assert set(scene.priors) == {"object_models", "coffee_table_center", "coffee_table_size",
                                 "instruction"}  # as in the task's own house
    assert task.variation["objects"] == {k: o["table"]
                                         for k, o in task.spec.scene["objects"].items()}


def test_the_house_does_not_depend_on_the_string_hash_seed():
    # Same seed, two processes with different PYTHONHASHSEED: the same house (a set's order
    # once decided the order of the draws for the start poses and the objects' tables).
    import os
    import subprocess
    import sys

    code = ("import copy, numpy as np\nfrom pr2_drake.tasks import get_task\n"
            "from pr2_drake.tasks.house_gen import generate_house\n"
            "s = copy.deepcopy(get_task(6).spec.scene)\n"
            "print(generate_house(s, np.random.default_rng(16)))\n")
    out = [subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                          env={**os.environ, "PYTHONHASHSEED": h}).stdout for h in ("1", "2", "3")]
    assert out[0] and out[0] == out[1] == out[2]

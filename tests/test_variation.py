"""Scene variation (``scene.variation``) of tasks 1, 2, 4 and 5: drawn from the seed within the
YAML's ranges, the priors describe the scene built, and off it changes nothing."""

import numpy as np
import pytest
from pydrake.systems.framework import DiagramBuilder
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph

from pr2_drake.robot.model import add_kuavo
from pr2_drake.scenario import Scenario, load_scenario
from pr2_drake.tasks import get_task
from tests._locomotion_sim import min_distance_to_terrain

SEEDS = range(12)


def varied_geometry(task: int, seed: int):
    """(varied task, scene, plant, scene_graph, diagram, context) of a varied scene."""
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, 0.001)
    add_kuavo(plant)
    task_def = get_task(task).varied(seed)
    scene = task_def.build_scene(plant, np.random.default_rng(seed))
    plant.Finalize()
    diagram = builder.Build()
    return task_def, scene, plant, scene_graph, diagram, diagram.CreateDefaultContext()


@pytest.mark.parametrize("task", [1, 2, 4, 5])
def test_variation_is_drawn_from_the_seed_within_the_yaml_ranges(task):
    base = get_task(task)
    drawn = [base.varied(s).variation for s in SEEDS]
    assert base.varied(3).variation == drawn[3]  # the same seed, the same scene
    assert len({tuple(sorted(d.items())) for d in drawn}) == len(SEEDS)  # all different
    ranges = base.spec.scene["variation"]
    for d in drawn:
        if task == 4:
            assert ranges["angle_deg"][0] <= d["slope_angle_deg"] <= ranges["angle_deg"][1]
        elif task == 5:
            assert ranges["height"][0] <= d["step_height"] <= ranges["height"][1]
            assert ranges["depth"][0] <= d["step_depth"] <= ranges["depth"][1]
        elif task == 2:
            assert ranges["height"][0] <= d["valve_height"] <= ranges["height"][1]
            assert ranges["diameter"][0] <= d["valve_diameter"] <= ranges["diameter"][1]
        else:
            assert 0 <= d["road_seed"] < ranges["road_seed_max"]
    # The task's own definition is untouched; a task without variation is itself.
    assert base.variation is None and base.spec.scene == get_task(task).spec.scene
    assert get_task(3).varied(0) is get_task(3)


def test_slope_prior_matches_the_built_incline():
    for seed in (0, 5):
        task, scene, plant, sg, diagram, ctx = varied_geometry(4, seed)
        angle = scene.priors["slope_angle_deg"]
        assert angle == task.variation["slope_angle_deg"] != 7.0
        s = task.spec.scene["slope"]
        x0, run = s["start_x"], s["run"]
        for x in (x0 + 0.4, x0 + run / 2, x0 + run - 0.4):
            z = np.tan(np.radians(angle)) * (x - x0)  # the surface the prior describes
            assert abs(min_distance_to_terrain(plant, sg, diagram, ctx, [x, 0.3, z])) < 1e-6
        goal = scene.priors["goal_center"]
        assert goal[2] == pytest.approx(run * np.tan(np.radians(angle)))
        assert abs(min_distance_to_terrain(plant, sg, diagram, ctx, goal)) < 1e-6


def test_step_priors_match_the_built_staircase():
    task, scene, plant, sg, diagram, ctx = varied_geometry(5, 2)
    p = scene.priors
    h, d, x0 = p["step_height"], p["step_depth"], p["step_start_x"]
    assert (h, d) == (task.variation["step_height"], task.variation["step_depth"])
    for k in range(1, p["step_count"] + 1):  # each tread's top at k h, from x0 + (k-1) d
        for x in (x0 + (k - 1) * d + 0.02, x0 + k * d - 0.02):
            assert abs(min_distance_to_terrain(plant, sg, diagram, ctx, [x, 0.2, k * h])) < 1e-6
    button = p["button_center"]
    floor = p["step_count"] * h
    assert button[2] == pytest.approx(floor + task.spec.scene["button"]["height"])
    assert abs(min_distance_to_terrain(plant, sg, diagram, ctx, [3.5, 0.0, floor])) < 1e-6


def test_valve_priors_match_the_built_wheel():
    task, scene, plant, sg, diagram, ctx = varied_geometry(2, 4)
    center = np.asarray(scene.priors["valve_center"])
    diameter = scene.priors["valve_dimensions"]["diameter"]
    assert center[2] == task.variation["valve_height"] and diameter == task.variation[
        "valve_diameter"]
    wheel = plant.GetBodyByName("valve_wheel")
    plant_ctx = plant.GetMyContextFromRoot(ctx)
    assert plant.EvalBodyPoseInWorld(plant_ctx, wheel).translation() == pytest.approx(center)
    # The rim's outer edge is where the diameter says, at the centre's height.
    for a in (0.3, 2.0, 4.0):
        outer = center + 0.5 * diameter * np.array([np.cos(a), np.sin(a), 0.0])
        assert abs(min_distance_to_terrain(plant, sg, diagram, ctx, outer, wheel)) < 2e-3
    # The pick volume keeps its margin beyond the rim.
    volume = scene.priors["valve_dimensions"]["pick_volume"]
    standard = get_task(2).spec.scene
    assert volume["radius"] - diameter / 2 == pytest.approx(
        standard["pick_volume"]["radius"] - standard["valve"]["diameter"] / 2)


def test_rock_fields_differ_by_seed_and_ground_height_matches_them():
    fields = []
    for seed in (0, 1):
        task, scene, plant, sg, diagram, ctx = varied_geometry(1, seed)
        xs = np.linspace(0.8, 5.4, 12)
        heights = [scene.ground_height(x, 0.1) for x in xs]
        for x, z in zip(xs[::4], heights[::4]):
            assert abs(min_distance_to_terrain(plant, sg, diagram, ctx, [x, 0.1, z])) < 1e-6
        fields.append(heights)
    standard = get_task(1).build_scene(
        AddMultibodyPlantSceneGraph(DiagramBuilder(), 0.001)[0], np.random.default_rng(0))
    assert fields[0] != fields[1]
    assert fields[0] != [standard.ground_height(x, 0.1) for x in np.linspace(0.8, 5.4, 12)]


def test_the_switch_reaches_the_testbed_and_the_report_only_when_on():
    from pr2_drake.agents.standing import StandingAgent  # noqa: F401 (importable agent)
    from pr2_drake.run import run_episode

    on = load_scenario(None, ["task=4", "seed=1", "seconds=0.05", "scene.variation=true",
                              "agent=pr2_drake.agents.standing:StandingAgent"])
    assert on.scene.variation is True and on.testbed_config().variation is True
    report = run_episode(on)
    assert report["variation"] == get_task(4).varied(1).variation
    off = run_episode(Scenario(task=4, seed=1, seconds=0.05,
                               agent="pr2_drake.agents.standing:StandingAgent"))
    assert "variation" not in off


@pytest.mark.parametrize("task", [1, 2, 4, 5])
def test_a_varied_scene_is_never_reused_for_another_seed(task):
    """The learning envs' fast reset moves a built episode to another seed only where the seed
    draws the start pose alone: a varied scene is one seed's, so it is built anew."""
    assert get_task(task).start_of(7) is not None
    assert get_task(task).varied(3).start_of(7) is None

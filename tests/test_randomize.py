"""Domain randomisation (pr2_drake.randomize): drawn from the seed, each kind reaches the
physics, and off means the testbed of before."""

import hashlib

import numpy as np
import pytest
from pydrake.geometry import Sphere
from pydrake.math import RigidTransform
from pydrake.multibody.math import SpatialVelocity
from pydrake.multibody.plant import CoulombFriction
from pydrake.multibody.tree import SpatialInertia

from pr2_drake.camera import CameraSettings
from pr2_drake.controllers.standing import StandingController
from pr2_drake.env import Env
from pr2_drake.episode import Episode, wire_system
from pr2_drake.ports import EFFORT_LEGS, V_WB
from pr2_drake.randomize import RandomizeSettings, draw_physics, kind_rng, terrain_and_feet
from pr2_drake.scenario import PlantSettings, Scenario, ScenarioError, load_scenario
from pr2_drake.scene import add_flat_ground, Scene
from pr2_drake.testbed import DEFAULT_TIME_STEP

KINDS = ("friction", "mass", "motor", "joints", "objects", "latency", "noise", "pushes")


def only(*kinds: str, **changes) -> RandomizeSettings:
    """Randomisation with only ``kinds`` on; ``changes``: {"kind.field": value}."""
    s = RandomizeSettings(enabled=True)
    for kind in KINDS:
        getattr(s, kind).enabled = kind in kinds
    for key, value in changes.items():
        kind, name = key.split(".")
        setattr(getattr(s, kind), name, value)
    return s


def standing(seed: int = 3, seconds: float = 0.3, randomize=None, task=None) -> Episode:
    scenario = Scenario(task=task, seed=seed, seconds=seconds,
                        randomize=randomize or RandomizeSettings())
    episode = Episode(scenario, wire_system(StandingController()))
    episode.initialize()
    episode.advance_to(seconds)
    return episode


def state_hash(episode: Episode) -> str:
    x = np.asarray(episode.testbed.GetOutputPort("plant_state").Eval(episode.tb_context), float)
    return hashlib.sha256(x.tobytes()).hexdigest()


def test_same_seed_same_physics_and_trajectory_other_seed_other_values():
    on = RandomizeSettings(enabled=True)
    a, b, c = standing(3, randomize=on), standing(3, randomize=on), standing(4, randomize=on)
    ra, rb, rc = a.report(), b.report(), c.report()
    assert ra["physics"] == rb["physics"] and state_hash(a) == state_hash(b)
    assert set(ra["physics"]) >= {"friction", "mass_scale", "motor_strength", "joint_damping",
                                  "armature", "latency", "noise", "pushes"}
    for key in ("friction", "mass_scale", "base_com_offset", "motor_strength", "joint_damping",
                "armature"):
        assert ra["physics"][key] != rc["physics"][key], key
    assert state_hash(a) != state_hash(c)
    assert ra["physics"]["pushes"] == []  # the first comes after 4 s
    minute = [draw_physics(on, seed, a.testbed, 60.0).pushes for seed in (3, 3, 4)]
    assert minute[0] == minute[1] != minute[2] and 7 <= len(minute[0]) <= 15


def test_a_built_diagram_takes_another_seeds_physics():
    """The reuse path: redraw for seed 4 on seed 3's diagram, reset the context, initialize:
    the same physics and trajectory as a diagram built for seed 4 (flat ground: the scene
    does not depend on the seed)."""
    on = RandomizeSettings(enabled=True)
    reused = standing(3, randomize=on)
    reused.redraw_physics(4)
    reused.context.SetTimeStateAndParametersFrom(reused.diagram.CreateDefaultContext())
    reused.initialize()
    reused.advance_to(0.3)
    fresh = standing(4, randomize=on)
    assert reused.physics == fresh.physics and state_hash(reused) == state_hash(fresh)


def test_turning_one_kind_off_leaves_the_others_values():
    full = standing(5, seconds=0.01, randomize=RandomizeSettings(enabled=True)).physics
    part = standing(5, seconds=0.01, randomize=only("friction", "motor")).physics
    assert part.friction == full.friction and part.motor_strength == full.motor_strength
    assert part.mass_scale is None and part.pushes is None


def test_off_builds_nothing_and_draws_nothing():
    """With ``enabled: false`` (whatever the kinds say) the diagram, the report and the
    trajectory are those of a scenario without a randomize section."""
    off = RandomizeSettings(enabled=False)
    off.friction.range = [0.1, 0.2]
    a, b = standing(2), standing(2, randomize=off)
    names = {s.get_name() for s in b.testbed.GetSystems()}
    assert not names & {"command_delay", "peak_torque", "joint_state_noise", "base_pushes"}
    assert "physics" not in a.report() and a.physics is None
    assert state_hash(a) == state_hash(b)


def _sliding_plate_scene(plant, rng) -> Scene:
    """Flat ground and a plate on four small spheres (mu 1.0) at x = 3 m."""
    add_flat_ground(plant)
    plate = plant.AddRigidBody("plate", plant.AddModelInstance("plate"),
                               SpatialInertia.SolidBoxWithMass(2.0, 0.4, 0.4, 0.05))
    for i, (x, y) in enumerate([(0.2, 0.2), (0.2, -0.2), (-0.2, 0.2), (-0.2, -0.2)]):
        plant.RegisterCollisionGeometry(plate, RigidTransform([x, y, -0.02]), Sphere(0.01),
                                        f"foot_{i}", CoulombFriction(1.0, 1.0))
    plant.SetDefaultFreeBodyPose(plate, RigidTransform([3.0, 0.0, 0.03]))
    return Scene(name="sliding plate")


@pytest.mark.parametrize("mu", [0.5, 1.2])
def test_friction_reaches_the_contact(mu):
    """A plate sliding on the ground slows at mu_eff g, mu_eff = 2 mu 1 / (mu + 1) (Drake's
    combination of the ground's drawn mu with the plate's 1.0); the feet get mu too. With the
    "lagged" approximation, whose friction is mu times the last step's normal force: the
    default "similar" one, convex, lets a plate sliding at 3 m/s glide (about 0.7 mu_eff at
    1 and 2 ms; README, "Physics")."""
    scenario = Scenario(seed=0, seconds=0.5, plant=PlantSettings(contact_approximation="lagged"),
                        randomize=only("friction", **{"friction.range": [mu, mu]}))
    episode = Episode(scenario, scene_builder=_sliding_plate_scene)
    episode.initialize()
    plant, ctx = episode.testbed.plant, episode.plant_context
    plate = plant.GetBodyByName("plate")
    episode.advance_to(0.05)  # settled on the ground
    plant.SetFreeBodySpatialVelocity(ctx, plate, SpatialVelocity(np.zeros(3), [3.0, 0.0, 0.0]))
    t0 = episode.time
    episode.advance_to(t0 + 0.2)
    vx = plant.EvalBodySpatialVelocityInWorld(ctx, plate).translational()[0]
    mu_eff = (3.0 - vx) / (9.81 * (episode.time - t0))
    assert mu_eff == pytest.approx(2 * mu / (mu + 1), rel=0.01)
    inspector = episode.testbed.scene_graph.GetMyContextFromRoot(episode.context)
    inspector = episode.testbed.scene_graph.get_query_output_port().Eval(inspector).inspector()
    feet = terrain_and_feet(episode.testbed)
    assert len(feet) >= 5  # the floor and four foot spheres
    for gid in feet:
        f = inspector.GetProximityProperties(gid).GetProperty("material", "coulomb_friction")
        assert (f.static_friction(), f.dynamic_friction()) == (mu, mu)


def test_mass_reaches_the_plant():
    episode = standing(7, seconds=0.01, randomize=only("mass"))
    plant, ctx, p = episode.testbed.plant, episode.plant_context, episode.physics
    nominal = plant.CalcTotalMass(plant.CreateDefaultContext())
    expected = sum(plant.GetBodyByName(n).default_mass() * s for n, s in p.mass_scale.items())
    assert plant.CalcTotalMass(ctx) == pytest.approx(expected, rel=1e-12)
    assert abs(plant.CalcTotalMass(ctx) - nominal) > 1e-3
    base = plant.GetBodyByName("base_link")
    shift = base.CalcCenterOfMassInBodyFrame(ctx) - base.default_com()
    assert np.allclose(shift, p.base_com_offset, atol=1e-12)


def test_joint_damping_armature_and_motor_strength_reach_the_plant():
    env = Env(seed=7, scenario=Scenario(randomize=only("joints", "motor")), time_limit=1.0)
    episode = env.episode
    tb, ctx, p = episode.testbed, episode.plant_context, episode.physics
    knee = tb.plant.GetJointByName("l_knee")
    assert knee.GetDamping(ctx) == pytest.approx(knee.default_damping() * p.joint_damping["l_knee"])
    act = tb.plant.GetJointActuatorByName("l_knee")
    assert act.rotor_inertia(ctx) == pytest.approx(
        act.default_rotor_inertia() * p.armature["l_knee"])
    # A full-effort command on the knee is clamped at the drawn peak torque.
    big = np.zeros(10)
    big[3] = 1000.0
    _, _, obs = env.step({"legs": {"ctrl_mode": "effort", "joint_values": big}})
    applied = obs["agent"]["joint_state"]["legs_applied_effort"][3]
    assert applied == pytest.approx(110.0 * p.motor_strength["l_knee"], rel=1e-12)


def test_a_push_changes_the_base_velocity():
    """A 40 N push for 0.1 s adds about F dt / m = 0.12 m/s to the base, along the push, by
    its end (the standing robot's feet hold little of it that soon)."""
    pushes = only("pushes", **{"pushes.interval": [0.1, 0.1], "pushes.duration": [0.1, 0.1],
                               "pushes.force": [40.0, 40.0]})
    pushed, still = standing(1, seconds=0.2, randomize=pushes), standing(1, seconds=0.2)
    t, duration, fx, fy = pushed.physics.pushes[0]
    assert (t, duration) == (pytest.approx(0.1), pytest.approx(0.1))
    v = [e.testbed.GetOutputPort("body_state").Eval(e.tb_context)[V_WB] for e in (pushed, still)]
    dv = (v[0] - v[1])[:2]
    along = np.array([fx, fy]) / 40.0
    mass = pushed.testbed.plant.CalcTotalMass(pushed.plant_context)
    assert dv @ along == pytest.approx(40.0 * 0.1 / mass, rel=0.25)
    assert abs(dv @ [-along[1], along[0]]) < 0.02


def _first_step_applied(latency: float) -> int:
    randomize = only("latency", **{"latency.range": [latency, latency]})
    env = Env(seed=0, scenario=Scenario(randomize=randomize), time_limit=1.0)
    effort = np.full(10, 3.0)
    for step in range(1, 20):
        _, _, obs = env.step({"legs": {"ctrl_mode": "effort", "joint_values": effort}})
        if np.allclose(obs["agent"]["joint_state"]["legs_applied_effort"], effort):
            return step
    raise AssertionError("the command never took effect")


def test_latency_delays_the_commands_effect():
    assert _first_step_applied(0.0) == 1
    # Five physics steps later (Env steps one physics step).
    assert _first_step_applied(5 * DEFAULT_TIME_STEP) == 6


def test_noise_changes_the_observation_but_not_the_state():
    noisy = Env(seed=0, scenario=Scenario(randomize=only("noise")), time_limit=1.0)
    clean = Env(seed=0, time_limit=1.0)
    hold = {"legs": {"ctrl_mode": "position", "joint_values": np.zeros(10)}}
    errors = []
    for _ in range(40):
        noisy.step(hold)
        clean.step(hold)
        a = noisy.observation_values()["joint_state"]
        b = clean.observation_values()["joint_state"]
        assert np.array_equal(a, noisy.observation_values()["joint_state"])  # same read again
        errors.append((a - b)[:18])
    assert state_hash(noisy.episode) == state_hash(clean.episode)
    assert np.std(errors) == pytest.approx(0.001, rel=0.25)
    assert not np.allclose(errors[0], errors[1])  # fresh at each step
    body = noisy.observation_values()["body_state"]
    assert np.linalg.norm(body[3:7]) == pytest.approx(1.0)


def test_valve_dynamics_are_randomised():
    episode = standing(0, seconds=0.01, task=2, randomize=only("objects"))
    tb, p = episode.testbed, episode.physics
    joint = tb.plant.GetJointByName("valve_joint")
    assert joint.GetDamping(episode.plant_context) == pytest.approx(
        joint.default_damping() * p.valve["damping"])
    friction = tb.GetSubsystemByName("valve_friction")
    tau = friction.GetMyContextFromRoot(episode.context).get_numeric_parameter(0)[0]
    assert tau == pytest.approx(friction.nominal_torque * p.valve["friction_torque"])
    assert p.valve["damping"] != 1.0 and p.object_mass is None


def test_object_mass_and_friction_and_sleeping_objects_hold_still():
    """Task 6: each object's drawn mass is in the plant (and in the weight the grasp system
    cancels for sleeping objects: they hold exactly still), its friction in the SceneGraph."""
    scenario = Scenario(task=6, seed=0, seconds=2.0, camera=CameraSettings(enabled=False),
                        randomize=only("objects"))
    episode = Episode(scenario, wire_system(StandingController()))
    episode.initialize()
    tb, p = episode.testbed, episode.physics
    plant, ctx = tb.plant, episode.plant_context
    bodies = [plant.get_body(g.body) for g in tb.scene.graspables]
    assert sorted(p.object_mass) == sorted(b.name() for b in bodies)
    for b in bodies:
        assert b.get_mass(ctx) == pytest.approx(b.default_mass() * p.object_mass[b.name()])
    episode.advance_to(1.2)
    grasp = tb.grasp
    assert len(grasp.sleeping(grasp.GetMyContextFromRoot(episode.context))) == len(bodies)
    before = [plant.EvalBodyPoseInWorld(ctx, b).translation().copy() for b in bodies]
    episode.advance_to(2.0)
    after = [plant.EvalBodyPoseInWorld(ctx, b).translation() for b in bodies]
    assert np.array_equal(before, after)
    query = tb.scene_graph.get_query_output_port().Eval(
        tb.scene_graph.GetMyContextFromRoot(episode.context))
    gid = plant.GetCollisionGeometriesForBody(bodies[0])[0]
    nominal = tb.scene_graph.model_inspector().GetProximityProperties(gid).GetProperty(
        "material", "coulomb_friction").static_friction()
    drawn = query.inspector().GetProximityProperties(gid).GetProperty(
        "material", "coulomb_friction").static_friction()
    assert drawn == pytest.approx(nominal * p.object_friction[bodies[0].name()])


def test_a_sandboxed_agent_gets_noisy_ports_and_never_the_physics(monkeypatch):
    """compete: the report has the physics of the seed (as ``run`` draws it); what crosses
    to the agent's process is the noisy observation and nothing of the draw."""
    from pr2_drake.compete import proxy
    from pr2_drake.compete.sandbox import SandboxLimits

    sent = []
    original = proxy.AgentProcess.request

    def request(self, message, *args, **kwargs):
        sent.append(message)
        return original(self, message, *args, **kwargs)

    monkeypatch.setattr(proxy.AgentProcess, "request", request)
    scenario = Scenario(task=1, seed=2, seconds=0.05, control_dt=0.01,
                        agent="pr2_drake.agents.standing:StandingAgent",
                        randomize=RandomizeSettings(enabled=True))
    report = proxy.run_sandboxed_episode(scenario, limits=SandboxLimits(startup_seconds=60.0))
    episode = Episode(scenario)
    assert report["physics"] == episode.report()["physics"]
    assert "physics" not in repr(sent) and repr(episode.physics.friction) not in repr(sent)
    first = next(m["ports"]["joint_state"] for m in sent if m.get("op") == "reset")
    episode.initialize()
    in_process = episode.testbed.GetOutputPort("joint_state").Eval(episode.tb_context)
    assert np.array_equal(first, in_process)  # the same noise: the same key and step
    clean = np.asarray(episode.testbed.plant.GetPositions(episode.plant_context))
    assert not np.isin(first[:18], clean).all()


def test_env_exposes_the_physics_of_its_seed():
    env = Env(task=None, seed=9, scenario=Scenario(randomize=RandomizeSettings(enabled=True)),
              time_limit=0.1)
    assert env.physics == env.report()["physics"]
    assert env.physics["friction"] == pytest.approx(
        kind_rng(9, "friction").uniform(0.5, 1.25))


@pytest.mark.parametrize("override, field", [
    ("randomize.friction.range=[-0.1, 1.0]", "randomize.friction.range"),
    ("randomize.latency.range=[0.02, 0.01]", "randomize.latency.range"),
    ("randomize.latency.range=[0.0, 2.0]", "randomize.latency.range"),
    ("randomize.pushes.force=[30]", "randomize.pushes.force"),
    ("randomize.noise.joint_velocity=-1", "randomize.noise.joint_velocity"),
    ("randomize.mass.enabled=3", "randomize.mass.enabled"),
])
def test_bad_ranges_name_the_field(override, field):
    """A type the YAML loader refuses, or a value validation refuses: both name the field."""
    with pytest.raises(ScenarioError, match=field.replace(".", r"\.")):
        load_scenario(None, overrides=["randomize.enabled=true", override]).validate()


def test_unknown_fields_are_named():
    with pytest.raises(ScenarioError, match="frcition"):
        load_scenario(None, overrides=["randomize.frcition.range=[0.5, 1.0]"])


def test_a_randomised_testbed_is_collected():
    """The randomisation's blocks close no invisible cycle (pr2_drake.lifetime)."""
    import gc
    import weakref

    episode = standing(0, seconds=0.01, task=2, randomize=RandomizeSettings(enabled=True))
    ref = weakref.ref(episode.testbed)
    del episode
    gc.collect()
    assert ref() is None

"""Domain randomisation: the scenario's ``randomize`` section, drawn from the episode seed.

Off by default. ``--set randomize.enabled=true`` turns every kind on with the default ranges;
each kind has its own ``enabled`` and ranges (``--set randomize.pushes.enabled=false``,
``--set randomize.friction.range=[0.4,1.0]``):

=============  =====================================================  ======================
kind           what is drawn (per episode, from the seed)             default
=============  =====================================================  ======================
friction       one Coulomb coefficient (static = dynamic) of the      0.5 - 1.25
               terrain (world geometry with the scenes' ground
               friction: floor, rocks, slope, steps) and the feet;
               their contact gets exactly this coefficient
mass           every robot link's mass and inertia (x scale);         x 0.9 - 1.1, +-2 cm
               the base's centre of mass (+- per axis, base frame)
motor          each joint's peak torque (x scale)                     x 0.9 - 1.1
joints         each joint's viscous damping and reflected rotor       x 0.5 - 1.5,
               inertia (armature) (x scale)                           x 0.8 - 1.2
objects        task 2: the valve's Coulomb torque and damping;        x 0.7 - 1.3 each
               task 6: each free object's mass and friction
latency        a delay of the arm and leg commands [s], whole         0 - 10 ms
               physics steps
noise          white Gaussian noise on ``joint_state`` and            sigmas below
               ``body_state`` (fresh at each physics step)
pushes         horizontal forces on the base: magnitude, duration,    30-40 N, 0.1-0.2 s,
               direction (uniform), the gap between two starts        every 4-8 s
=============  =====================================================  ======================

Why these defaults. Friction, mass/CoM, motor strength, valve and latency: the ranges of the
learning issue (28). Joint damping is a viscous coefficient that real gearboxes change by tens
of percent with temperature and lubricant, and identification rarely pins it better than a
factor of 2: x 0.5-1.5. The armature is the rotor inertia times the squared gear ratio, from the
motor's datasheet: +-20 % covers datasheet tolerance and the unmodelled gear stages, and keeps
the actuation's stable-gain caps (I/dt, I/dt^2 from the nominal joint inertia I) stable: at
0.8 I (links 0.9) the capped damper's d dt / I is at most 1.25, under the explicit scheme's 2. Object mass and friction: the valve's +-30 %. Noise (standard deviations): encoders
0.001 rad (a few counts of a 13-bit absolute encoder plus backlash) and 0.05 rad/s (encoder
differences at 1 kHz, filtered); IMU attitude 0.005 rad (0.3 deg, a MEMS AHRS's roll/pitch
accuracy), gyro 0.01 rad/s; the base's estimated position 0.002 m and velocity 0.02 m/s (a
leg-odometry + IMU estimator's jitter, not its drift). Applied efforts are not noised.

Determinism: each kind draws from its own stream, ``SeedSequence(seed, spawn_key=(0xD12,
kind))``: the same seed gives the same values bit for bit, turning one kind off leaves the
others' values as they were, and nothing else that uses the seed (start pose, scene) sees a
draw. With ``enabled: false`` nothing is built and nothing drawn: episodes are those of a
testbed without this module.

The API (the reuse path of a built diagram)::

    from pr2_drake.randomize import draw_physics, apply_physics
    sample = draw_physics(settings, seed, testbed, horizon)   # a PhysicsSample
    apply_physics(testbed, root_context, sample)              # one call, context only
    sample.report()                                           # the report's ``physics``

:class:`pr2_drake.episode.Episode` draws at construction (``episode.physics``), applies at every
``initialize()`` (after a reset to default parameters too) and reports ``physics``;
``Episode.redraw_physics(seed)`` draws another seed's values for the same diagram. Everything
is a Context value (plant parameters, SceneGraph proximity properties, the parameters of the
systems in :mod:`pr2_drake.randomize_systems`), except, set at build time: which kinds are on,
the noise sigmas, the latency buffer's capacity (from the range's upper end), the pushes'
capacity (from the horizon), the actuation's stable-gain caps (from the nominal model) and the
grasp system's weight cancellation of sleeping objects (set from the sample by
:func:`apply_physics`, a system attribute).
"""


import math
import typing
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

# Streams of the kinds (spawn keys): fixed forever, so a seed's values never move.
_STREAM = 0xD12
_KINDS = ("friction", "mass", "motor", "joints", "objects", "latency", "noise", "pushes")
MAX_LATENCY = 0.5  # [s] longest command delay (the delay buffer holds that many steps)
PUSH_HORIZON = 600.0  # [s] pushes are drawn up to this time when an episode has no limit
FOOT_BODIES = ("l_foot", "r_foot")


def _span(low: float, high: float):
    return field(default_factory=lambda: [low, high])


@dataclass
class FrictionRandomization:
    """Attributes: range: [low, high] Coulomb coefficient of terrain and feet."""

    enabled: bool = True
    range: typing.List[float] = _span(0.5, 1.25)


@dataclass
class MassRandomization:
    """Attributes: scale: [low, high] of each robot link's mass (and inertia);
    base_com: half-width [m] of the uniform offset of the base's centre of mass, per axis."""

    enabled: bool = True
    scale: typing.List[float] = _span(0.9, 1.1)
    base_com: float = 0.02


@dataclass
class MotorRandomization:
    """Attributes: strength: [low, high] scale of each joint's peak torque."""

    enabled: bool = True
    strength: typing.List[float] = _span(0.9, 1.1)


@dataclass
class JointRandomization:
    """Attributes: damping, armature: [low, high] scales of each joint's viscous damping and
    reflected rotor inertia."""

    enabled: bool = True
    damping: typing.List[float] = _span(0.5, 1.5)
    armature: typing.List[float] = _span(0.8, 1.2)


@dataclass
class ObjectRandomization:
    """Attributes: valve_friction, valve_damping: [low, high] scales of the valve's Coulomb
    torque and viscous damping (task 2); mass, friction: of each free object (task 6)."""

    enabled: bool = True
    valve_friction: typing.List[float] = _span(0.7, 1.3)
    valve_damping: typing.List[float] = _span(0.7, 1.3)
    mass: typing.List[float] = _span(0.7, 1.3)
    friction: typing.List[float] = _span(0.7, 1.3)


@dataclass
class LatencyRandomization:
    """Attributes: range: [low, high] delay of the arm and leg commands [s] (rounded to whole
    physics steps)."""

    enabled: bool = True
    range: typing.List[float] = _span(0.0, 0.010)


@dataclass
class NoiseRandomization:
    """Standard deviations of the observation noise (see the module docstring).

    Attributes:
        joint_position [rad], joint_velocity [rad/s]: on ``joint_state``'s q and v.
        base_position [m], base_orientation [rad] (a rotation about a random axis),
        base_linear_velocity [m/s], base_angular_velocity [rad/s]: on ``body_state``.
    """

    enabled: bool = True
    joint_position: float = 0.001
    joint_velocity: float = 0.05
    base_position: float = 0.002
    base_orientation: float = 0.005
    base_linear_velocity: float = 0.02
    base_angular_velocity: float = 0.01


@dataclass
class PushRandomization:
    """Attributes: force [N], duration [s], interval [s] (between two starts; the first at one
    interval): [low, high] each; the direction is uniform in the horizontal plane."""

    enabled: bool = True
    force: typing.List[float] = _span(30.0, 40.0)
    duration: typing.List[float] = _span(0.1, 0.2)
    interval: typing.List[float] = _span(4.0, 8.0)


@dataclass
class RandomizeSettings:
    """The scenario's ``randomize`` section (off by default; see the module docstring)."""

    enabled: bool = False
    friction: FrictionRandomization = field(default_factory=FrictionRandomization)
    mass: MassRandomization = field(default_factory=MassRandomization)
    motor: MotorRandomization = field(default_factory=MotorRandomization)
    joints: JointRandomization = field(default_factory=JointRandomization)
    objects: ObjectRandomization = field(default_factory=ObjectRandomization)
    latency: LatencyRandomization = field(default_factory=LatencyRandomization)
    noise: NoiseRandomization = field(default_factory=NoiseRandomization)
    pushes: PushRandomization = field(default_factory=PushRandomization)

    def on(self, kind: str) -> bool:
        """Whether ``kind`` (one of the sections) is drawn and applied."""
        return bool(self.enabled and getattr(self, kind).enabled)

    def validate(self) -> None:
        """Raise ValueError naming the first bad field (``randomize.<kind>.<field>``)."""
        _boolean("randomize.enabled", self.enabled)
        for kind in _KINDS:
            section = getattr(self, kind)
            for f in fields(section):
                name, value = f"randomize.{kind}.{f.name}", getattr(section, f.name)
                if f.name == "enabled":
                    _boolean(name, value)
                elif isinstance(value, list):
                    _range(name, value, positive=kind != "latency")
                    if kind == "latency" and value[1] > MAX_LATENCY:
                        raise ValueError(f"{name} must end at most {MAX_LATENCY:g} s, got "
                                         f"{value!r}")
                else:
                    _non_negative(name, value)


def _boolean(name: str, value) -> None:
    if not isinstance(value, bool):
        raise ValueError(f"{name} must be true or false, got {value!r}")


def _non_negative(name: str, value) -> None:
    if (isinstance(value, bool) or not isinstance(value, (int, float))
            or not math.isfinite(value) or value < 0):
        raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")


def _range(name: str, value, positive: bool) -> None:
    ok = (len(value) == 2 and all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                  and math.isfinite(v) for v in value))
    if not ok or value[0] > value[1] or (value[0] <= 0 if positive else value[0] < 0):
        bound = "0 < low" if positive else "0 <= low"
        raise ValueError(f"{name} must be [low, high] with {bound} <= high, got {value!r}")


def kind_rng(seed: int, kind: str) -> np.random.Generator:
    """The generator of one kind's draws for ``seed`` (independent of every other use)."""
    return np.random.default_rng(
        np.random.SeedSequence(int(seed), spawn_key=(_STREAM, _KINDS.index(kind))))


@dataclass
class PhysicsSample:
    """One episode's drawn physics; None where a kind is off or does not apply (all scales
    are multipliers of the nominal model's values).

    Attributes:
        friction: Coulomb coefficient of terrain and feet.
        mass_scale: robot link name -> scale of its mass and inertia.
        base_com_offset: offset of the base's centre of mass [m], base frame.
        motor_strength, joint_damping, armature: joint name -> scale.
        valve: {"friction_torque": scale, "damping": scale} (task 2).
        object_mass, object_friction: free object (body) name -> scale (task 6).
        latency: command delay [s] (whole physics steps); latency_steps: that many steps.
        noise_key: the observation noise's key (two 32-bit halves); noise: the sigmas.
        pushes: (start [s], duration [s], fx [N], fy [N]) each, world frame, in time order.
    """

    friction: float | None = None
    mass_scale: dict[str, float] | None = None
    base_com_offset: list[float] | None = None
    motor_strength: dict[str, float] | None = None
    joint_damping: dict[str, float] | None = None
    armature: dict[str, float] | None = None
    valve: dict[str, float] | None = None
    object_mass: dict[str, float] | None = None
    object_friction: dict[str, float] | None = None
    latency: float | None = None
    latency_steps: int | None = None
    noise_key: tuple[int, int] | None = None
    noise: dict[str, float] | None = None
    pushes: list[tuple[float, float, float, float]] | None = None

    def report(self) -> dict[str, Any]:
        """The drawn values for the episode report's ``physics`` (kinds that are on only)."""
        out: dict[str, Any] = {}
        for f in fields(self):
            value = getattr(self, f.name)
            if value is None or f.name == "noise_key":
                continue
            if f.name == "pushes":
                value = [{"time": t, "duration": d, "force": [fx, fy]} for t, d, fx, fy in value]
            out[f.name] = value
        return out


def draw_physics(settings: RandomizeSettings, seed: int, testbed, horizon: float) -> PhysicsSample:
    """Draw one episode's physics for ``testbed`` from ``seed`` (pushes up to ``horizon`` [s],
    at most :data:`PUSH_HORIZON` when it is infinite)."""
    from pr2_drake.robot.params import ARM_JOINTS, LEG_JOINTS

    s, sample = settings, PhysicsSample()
    joints = ARM_JOINTS + LEG_JOINTS
    if s.on("friction"):
        sample.friction = _uniform(kind_rng(seed, "friction"), s.friction.range)
    if s.on("mass"):
        rng = kind_rng(seed, "mass")
        names = robot_link_names(testbed)
        sample.mass_scale = dict(zip(names, _uniforms(rng, s.mass.scale, len(names))))
        sample.base_com_offset = [float(v) for v in rng.uniform(-s.mass.base_com, s.mass.base_com,
                                                               3)]
    if s.on("motor"):
        sample.motor_strength = dict(zip(joints, _uniforms(kind_rng(seed, "motor"),
                                                           s.motor.strength, len(joints))))
    if s.on("joints"):
        rng = kind_rng(seed, "joints")
        sample.joint_damping = dict(zip(joints, _uniforms(rng, s.joints.damping, len(joints))))
        sample.armature = dict(zip(joints, _uniforms(rng, s.joints.armature, len(joints))))
    if s.on("objects"):
        _draw_objects(s.objects, kind_rng(seed, "objects"), testbed, sample)
    if s.on("latency"):
        dt = float(testbed.config.time_step)
        sample.latency_steps = int(round(_uniform(kind_rng(seed, "latency"), s.latency.range)
                                         / dt))
        sample.latency = sample.latency_steps * dt
    if s.on("noise"):
        key = kind_rng(seed, "noise").integers(0, 2**32, size=2)
        sample.noise_key = (int(key[0]), int(key[1]))
        sample.noise = {f.name: float(getattr(s.noise, f.name)) for f in fields(s.noise)
                        if f.name != "enabled"}
    if s.on("pushes"):
        end = PUSH_HORIZON if not math.isfinite(horizon) else float(horizon)
        sample.pushes = draw_pushes(s.pushes, kind_rng(seed, "pushes"), end)
    return sample


def draw_pushes(p: PushRandomization, rng: np.random.Generator, end: float):
    """Pushes (start, duration, fx, fy) whose start is before ``end`` [s], in time order: each
    push draws its gap from the previous start, then duration, magnitude and direction."""
    pushes, t = [], 0.0
    while True:
        t += _uniform(rng, p.interval)
        duration, force = _uniform(rng, p.duration), _uniform(rng, p.force)
        angle = float(rng.uniform(-math.pi, math.pi))
        if t >= end:
            return pushes
        pushes.append((t, duration, force * math.cos(angle), force * math.sin(angle)))


def max_pushes(p: PushRandomization, horizon: float) -> int:
    """How many pushes can start before ``horizon`` [s] (the push system's capacity)."""
    end = PUSH_HORIZON if not math.isfinite(horizon) else float(horizon)
    return int(math.ceil(end / p.interval[0])) + 1 if p.interval[0] > 0 else 0


def _draw_objects(o: ObjectRandomization, rng: np.random.Generator, testbed,
                  sample: PhysicsSample) -> None:
    plant = testbed.plant
    if plant.HasJointNamed("valve_joint"):
        sample.valve = {"friction_torque": _uniform(rng, o.valve_friction),
                        "damping": _uniform(rng, o.valve_damping)}
    names = free_object_names(testbed)
    if names:
        sample.object_mass = dict(zip(names, _uniforms(rng, o.mass, len(names))))
        sample.object_friction = dict(zip(names, _uniforms(rng, o.friction, len(names))))


def _uniform(rng: np.random.Generator, span) -> float:
    return float(rng.uniform(span[0], span[1]))


def _uniforms(rng: np.random.Generator, span, n: int) -> list[float]:
    return [float(v) for v in rng.uniform(span[0], span[1], n)]


def robot_link_names(testbed) -> list[str]:
    """The robot's bodies with mass, in body-index order."""
    plant = testbed.plant
    return [plant.get_body(i).name() for i in plant.GetBodyIndices(testbed.robot)
            if plant.get_body(i).default_mass() > 0]


def free_object_names(testbed) -> list[str]:
    """The graspable free bodies (task 6's objects), in the scene's order."""
    plant = testbed.plant
    return [plant.get_body(g.body).name() for g in testbed.scene.graspables
            if plant.get_body(g.body).is_floating_base_body()]


# -- applying a sample to a built testbed --------------------------------------------------------
def apply_physics(testbed, context, sample: PhysicsSample) -> None:
    """Set ``sample`` in ``context`` (the root context of a diagram holding ``testbed``):
    plant parameters, SceneGraph proximity properties and the parameters of the testbed's
    randomisation blocks. Every value is set from the nominal model, so applying twice, or
    one sample after another, gives the same context as applying the last once."""
    plant = testbed.plant
    pc = plant.GetMyMutableContextFromRoot(context)
    if sample.friction is not None:
        mu = sample.friction
        _set_friction(testbed, context, {g: (mu, mu) for g in terrain_and_feet(testbed)})
    if sample.mass_scale is not None:
        _set_robot_masses(testbed, pc, sample)
    if sample.joint_damping is not None:
        for name, scale in sample.joint_damping.items():
            joint = plant.GetJointByName(name, testbed.robot)
            joint.SetDamping(pc, joint.default_damping() * scale)
        for name, scale in sample.armature.items():
            actuator = plant.GetJointActuatorByName(name, testbed.robot)
            actuator.SetRotorInertia(pc, actuator.default_rotor_inertia() * scale)
    if sample.valve is not None:
        _set_valve(testbed, context, pc, sample.valve)
    if sample.object_mass is not None:
        _set_objects(testbed, context, pc, sample)
    blocks = testbed.randomization
    if sample.motor_strength is not None:
        peaks = nominal_peaks(testbed) * in_actuator_order(testbed, sample.motor_strength)
        blocks.peak.set_peaks(blocks.peak.GetMyMutableContextFromRoot(context), peaks)
    if sample.latency_steps is not None:
        blocks.delay.set_steps(blocks.delay.GetMyMutableContextFromRoot(context),
                               sample.latency_steps)
    if sample.noise_key is not None:
        for system in blocks.noise.values():
            system.set_key(system.GetMyMutableContextFromRoot(context), sample.noise_key)
    if sample.pushes is not None:
        blocks.pushes.set_schedule(blocks.pushes.GetMyMutableContextFromRoot(context),
                                   sample.pushes)


def terrain_and_feet(testbed) -> list:
    """Proximity geometries whose friction the ``friction`` kind sets: the world's geometry
    with the scenes' ground friction (floor, rocks, slope, steps; not walls, furniture or
    the valve's stem) and the robot's feet."""
    from pydrake.geometry import Role

    from pr2_drake.scene import GROUND_FRICTION

    plant, inspector = testbed.plant, testbed.scene_graph.model_inspector()
    feet = {plant.GetBodyFrameIdOrThrow(plant.GetBodyByName(b, testbed.robot).index())
            for b in FOOT_BODIES}
    world = plant.GetBodyFrameIdOrThrow(plant.world_body().index())
    ids = []
    for gid in inspector.GetAllGeometryIds(Role.kProximity):
        frame = inspector.GetFrameId(gid)
        if frame in feet:
            ids.append(gid)
        elif frame == world:
            f = _friction(inspector, gid)
            if f is not None and (f.static_friction(), f.dynamic_friction()) == (
                    GROUND_FRICTION.static_friction(), GROUND_FRICTION.dynamic_friction()):
                ids.append(gid)
    return ids


def _friction(inspector, gid):
    props = inspector.GetProximityProperties(gid)
    if props is None or not props.HasProperty("material", "coulomb_friction"):
        return None
    return props.GetProperty("material", "coulomb_friction")


def _set_friction(testbed, context, coefficients: dict) -> None:
    """Replace the (static, dynamic) friction of geometries in the SceneGraph's context; the
    other proximity properties stay the model's."""
    from pydrake.geometry import ProximityProperties, RoleAssign
    from pydrake.multibody.plant import CoulombFriction

    sg = testbed.scene_graph
    sg_context = sg.GetMyMutableContextFromRoot(context)
    inspector, source = sg.model_inspector(), testbed.plant.get_source_id()
    for gid, (static, dynamic) in coefficients.items():
        props = ProximityProperties(inspector.GetProximityProperties(gid))
        props.UpdateProperty("material", "coulomb_friction", CoulombFriction(static, dynamic))
        sg.AssignRole(sg_context, source, gid, props, RoleAssign.kReplace)


def _scaled_inertia(body, scale: float, offset=None):
    """The body's nominal spatial inertia about its origin with mass and central inertia x
    ``scale``, its centre of mass moved by ``offset`` [m] (body frame)."""
    from pydrake.multibody.tree import SpatialInertia

    M = body.default_spatial_inertia()
    p_com = np.asarray(M.get_com(), float)
    I_cm = M.Shift(p_com).CalcRotationalInertia()
    if offset is not None:
        p_com = p_com + np.asarray(offset, float)
    return SpatialInertia.MakeFromCentralInertia(M.get_mass() * scale, p_com,
                                                 I_cm * scale)


def _set_robot_masses(testbed, plant_context, sample: PhysicsSample) -> None:
    from pr2_drake.robot.model import BASE_BODY

    plant = testbed.plant
    for name, scale in sample.mass_scale.items():
        body = plant.GetBodyByName(name, testbed.robot)
        offset = sample.base_com_offset if name == BASE_BODY else None
        body.SetSpatialInertiaInBodyFrame(plant_context, _scaled_inertia(body, scale, offset))


def _set_valve(testbed, context, plant_context, valve: dict[str, float]) -> None:
    joint = testbed.plant.GetJointByName("valve_joint")
    joint.SetDamping(plant_context, joint.default_damping() * valve["damping"])
    friction = testbed.GetSubsystemByName("valve_friction")
    friction.set_torque(friction.GetMyMutableContextFromRoot(context),
                        friction.nominal_torque * valve["friction_torque"])


def _set_objects(testbed, context, plant_context, sample: PhysicsSample) -> None:
    plant, inspector = testbed.plant, testbed.scene_graph.model_inspector()
    masses, frictions = {}, {}
    for g in testbed.scene.graspables:
        body = plant.get_body(g.body)
        if body.name() not in sample.object_mass:
            continue
        scale = sample.object_mass[body.name()]
        body.SetSpatialInertiaInBodyFrame(plant_context, _scaled_inertia(body, scale))
        masses[int(g.body)] = body.default_mass() * scale
        mu = sample.object_friction[body.name()]
        for gid in plant.GetCollisionGeometriesForBody(body):
            f = _friction(inspector, gid)
            if f is not None:
                frictions[gid] = (f.static_friction() * mu, f.dynamic_friction() * mu)
    _set_friction(testbed, context, frictions)
    testbed.grasp.set_object_masses(masses)


def nominal_peaks(testbed) -> np.ndarray:
    """The nominal peak torques [Nm] in the robot's actuator order."""
    return in_actuator_order(testbed, {j.name: j.effort for j in testbed.params.joints})


def in_actuator_order(testbed, by_joint: dict[str, float]) -> np.ndarray:
    """Per-joint values (by name) in the robot's actuator order."""
    from pr2_drake.robot.params import ARM_JOINTS, LEG_JOINTS

    out = np.zeros(len(testbed.maps.actuators))
    out[testbed.maps.actuators] = [by_joint[n] for n in ARM_JOINTS + LEG_JOINTS]
    return out

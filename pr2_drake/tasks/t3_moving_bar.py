"""Task 3 - jumping over a moving bar.

Scene (``tasks/3_moving_bar.yaml``): flat ground and a low bar (a box 2.0 x 0.05 x 0.05 m, 1 cm
above the ground) lying along x, the robot's nominal heading. At ``start_time`` (2 s) the bar
starts moving along +y (from the robot's right to its left) at 1.0 m/s, travels 1.65 m through
the start region and stops. The robot gets over it by stepping over it (lifting each foot in
turn as it sweeps by) or by jumping. No heading noise.

The bar is a free body on a prismatic joint (axis = direction of motion) whose motion is
prescribed by a stiff implicit PD actuator of the plant (SAP treats it implicitly, so it is stable
at any stiffness) tracking the profile of :func:`bar_motion`, wired through
``Scene.add_systems``. The bar collides with the robot (the robot cannot stop it: the PD force is
up to 3000 N); it never touches the ground (it rides 1 cm above it on its joint).

Definitions used by the referee (sampled every 10 ms). With d the bar's direction of motion and
p_bar its centre, a foot's signed distance is s = (p_sole - p_bar) . d; the foot is on the *near*
side when s > 0 (the bar is coming at it) and on the *far* side when s < 0.
- A foot *crosses* the bar when it goes from the near to the far side while the bar is moving
  (between ``start_time`` and the stop), within the bar's length (|(p_sole - p_bar) . axis| <=
  length / 2, so walking round an end does not count).
- The robot is *airborne* when no robot body touches the ground (contact with the bar does not
  count as ground).
- *Jump over*: both feet cross within one airborne phase (take-off to landing); judged at landing.
- *Step over*: both feet have crossed and are on the far side, the robot is not airborne, and it
  was not a jump (e.g. one foot at a time, the other on the ground).
- Either item is awarded once the robot has then stayed up (not fallen) for ``settle_time``
  (0.5 s): it must land or step stably.
- *Contact*: a robot body touching the bar. Contacts closer in time than ``contact_gap`` (0.1 s)
  are one episode; each episode costs 5 points.

Score: the better of step (10) and jump (15) plus -5 per contact episode, clipped to 0..15 (so a
jump after a step gives 15, not 25). The episode is *complete* when the jump is earned (nothing
more to gain), or when the bar has stopped, the step is earned and no jump is pending. Otherwise
it runs until it falls, leaves the arena (3 x 3 m) or times out (4 min).

Feedback: ``bar_position`` (bar centre, world, m), ``bar_velocity`` (world, m/s) and
``bar_orientation`` (the bar's fixed orientation in world, quaternion w, x, y, z: its length
along the track frame's x, as the YAML lays it out).
Priors: ``bar_id`` (the bar body's name) and ``bar_size`` (m). Figures not in TASKS.md (bar
size, clearance, start delay, settle time, contact gap, arena) are our choices, in the YAML.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.geometry import Box
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import (
    FixedOffsetFrame,
    ModelInstanceIndex,
    PdControllerGains,
    PrismaticJoint,
    SpatialInertia,
)
from pydrake.systems.primitives import TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from pr2_drake.materials import add_textured_box, add_textured_boxes
from pr2_drake.scene import GROUND_FRICTION, Scene, add_flat_ground
from pr2_drake.tasks.base import EpisodeStatus, Referee, ScoreEvent, TaskDefinition, TaskSpec
from pr2_drake.tasks.regions import (
    SOLE_FRAME_NAMES,
    Rect,
    add_line_marker,
    add_marker,
    contact_pairs,
    rgba,
    touching,
)

FEET = ("left", "right")


@dataclass(frozen=True)
class BarProfile:
    """The prescribed motion: position along the track [m] and its rate [m/s] at time t [s]."""

    start_offset: float
    speed: float
    travel: float
    start_time: float

    @property
    def stop_time(self) -> float:
        return self.start_time + self.travel / self.speed

    def at(self, t: float) -> tuple[float, float]:
        if t <= self.start_time:
            return self.start_offset, 0.0
        if t >= self.stop_time:
            return self.start_offset + self.travel, 0.0
        return self.start_offset + self.speed * (t - self.start_time), self.speed

    def moving(self, t: float, tolerance: float = 0.0) -> bool:
        return self.start_time < t <= self.stop_time + tolerance


def bar_motion(profile: BarProfile) -> TrajectorySource:
    """Output port ``desired_state`` = [q_d, v_d] of the bar's prismatic joint at time t: the
    profile as a first-order hold (at rest, constant speed, at rest) and its derivative, in
    Drake's C++ (a TrajectorySource; before and after its breaks it holds its end values)."""
    t_stop = profile.stop_time
    breaks = [min(0.0, profile.start_time) - 1.0, profile.start_time, t_stop, t_stop + 1.0]
    end = profile.start_offset + profile.travel
    q = np.array([[profile.start_offset, profile.start_offset, end, end]])
    return TrajectorySource(PiecewisePolynomial.FirstOrderHold(breaks, q),
                            output_derivative_order=1)


@dataclass
class BarLayout:
    """Where the bar runs, from the YAML ``scene.bar``."""

    name: str
    size: np.ndarray
    center_x: float
    clearance: float
    direction: np.ndarray  # unit, horizontal (x, y)
    profile: BarProfile

    @staticmethod
    def from_spec(spec: TaskSpec) -> "BarLayout":
        b = spec.scene["bar"]
        d = np.asarray(b["direction"], float)
        d /= np.linalg.norm(d)
        return BarLayout(
            name=b["name"], size=np.asarray(b["size"], float), center_x=float(b["center_x"]),
            clearance=float(b["clearance"]), direction=d,
            profile=BarProfile(float(b["start_y"]), float(b["speed"]), float(b["travel"]),
                               float(b["start_time"])),
        )

    @property
    def axis(self) -> np.ndarray:
        """Horizontal unit vector along the bar's length."""
        return np.array([self.direction[1], -self.direction[0]])

    def X_WTrack(self) -> RigidTransform:
        """Track frame T: origin at the track centre, +y = direction of motion, +x = bar axis."""
        yaw = float(np.arctan2(self.direction[1], self.direction[0]) - np.pi / 2)
        return RigidTransform(RollPitchYaw(0, 0, yaw),
                              [self.center_x, 0.0, self.clearance + self.size[2] / 2])

    def center(self, offset: float) -> np.ndarray:
        """Bar centre in world for a track offset [m]."""
        return self.X_WTrack().translation() + offset * np.array([*self.direction, 0.0])


class MovingBarReferee(Referee):
    """Judges step over, jump over and bar contacts (see the module docstring)."""

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    def __init__(self, spec: TaskSpec, plant: MultibodyPlant, robot: ModelInstanceIndex,
                 scene: Scene):
        super().__init__(spec, plant, robot, scene)
        self.layout: BarLayout = scene.data["layout"]
        self._bar_index = plant.GetBodyByName(self.layout.name).index()
        self._slider_index = plant.GetJointByName(f"{self.layout.name}_slider").index()
        # The slider keeps the bar's orientation that of the track frame.
        self._bar_orientation = self.layout.X_WTrack().rotation().ToQuaternion().wxyz()
        self.settle_time = float(spec.scene["settle_time"])
        self.contact_gap = float(spec.scene["contact_gap"])
        self.robot_bodies = frozenset(plant.GetBodyIndices(robot))
        self.bar_bodies = frozenset([self.bar.index()])
        self.ground_bodies = frozenset([plant.world_body().index()])
        self._sole_indices = [plant.GetFrameByName(n, robot).index() for n in SOLE_FRAME_NAMES]
        self.period = 0.01

    # Multibody elements (bodies, joints, frames) are kept as indices: a stored element holds its
    # plant through a reference the garbage collector cannot see (pr2_drake.lifetime).
    @property
    def bar(self):
        return self.plant.get_body(self._bar_index)

    @property
    def slider(self):
        return self.plant.get_joint(self._slider_index)

    @property
    def soles(self):
        return [self.plant.get_frame(i) for i in self._sole_indices]

    # -- scoring: the better of step/jump, minus every contact episode ------------------------
    def award(self, status: EpisodeStatus, item: str, time: float) -> None:
        if item != "bar_contact" and status.earned(item):
            return
        status.items.append(ScoreEvent(item, self.spec.points(item), time))
        best = max((e.points for e in status.items if e.points > 0), default=0.0)
        penalty = sum(e.points for e in status.items if e.points < 0)
        status.score = float(np.clip(best + penalty, 0.0, self.spec.max_score))

    def completed(self, status: EpisodeStatus) -> bool:
        return status.earned("jump_over") or bool(status.memo.get("closed", False))

    # -- judging ------------------------------------------------------------------------------
    def judge(self, context, status: EpisodeStatus) -> None:
        t = context.get_time()
        m = status.memo
        pairs = contact_pairs(self.contact_results(context))
        L = self.layout

        # Contact episodes with the bar.
        if touching(pairs, self.robot_bodies, self.bar_bodies):
            last = m.get("bar_contact_last")
            if last is None or t - last > self.contact_gap:
                self.award(status, "bar_contact", t)
            m["bar_contact_last"] = t

        airborne = not touching(pairs, self.robot_bodies, self.ground_bodies)
        was_airborne = m.get("airborne", False)
        if airborne and not was_airborne:
            m["flight_crossed"] = []
        p_bar = self.bar.EvalPoseInWorld(self.ctx).translation()
        moving = L.profile.moving(t, tolerance=self.period)
        sides = m.setdefault("side", {})
        crossed = m.setdefault("crossed", {f: False for f in FEET})
        for foot, sole in zip(FEET, self.soles):
            r = sole.CalcPoseInWorld(self.ctx).translation()[:2] - p_bar[:2]
            side = 1 if float(r @ L.direction) > 0 else -1
            if sides.get(foot) == 1 and side == -1 and moving and \
                    abs(float(r @ L.axis)) <= L.size[0] / 2:
                crossed[foot] = True
                if airborne or was_airborne:
                    m.setdefault("flight_crossed", []).append(foot)
            elif side == 1:
                crossed[foot] = False
            sides[foot] = side

        over = all(crossed[f] for f in FEET) and all(sides[f] == -1 for f in FEET)
        pending = m.get("pending")
        if not airborne:
            if was_airborne and over and set(m.get("flight_crossed", [])) == set(FEET):
                m["pending"] = pending = ["jump_over", t]
            elif over and pending is None and not status.earned("step_over"):
                m["pending"] = pending = ["step_over", t]
            m["flight_crossed"] = []
        m["airborne"] = airborne
        if pending is not None and t - pending[1] >= self.settle_time - 1e-9:
            self.award(status, pending[0], t)
            m["pending"] = None
            pending = None
        if t > L.profile.stop_time and pending is None and status.earned("step_over"):
            m["closed"] = True

    # -- feedback -----------------------------------------------------------------------------
    def feedback(self, context) -> dict:
        x = self.GetInputPort("plant_state").Eval(context)
        q = x[self.slider.position_start()]
        v = x[self.plant.num_positions() + self.slider.velocity_start()]
        d = np.array([*self.layout.direction, 0.0])
        return {"bar_position": self.layout.center(q), "bar_velocity": v * d,
                "bar_orientation": self._bar_orientation}

    def instruction(self) -> str:
        return "Get over the moving bar without touching it: step over it or jump over it."


def _add_track(plant: MultibodyPlant, layout: "BarLayout", colors: dict) -> None:
    """Visual-only brushed-metal rails beyond both ends of the bar, along its whole run, with
    end blocks, so the bar reads as a machine on a track (no collision: the robot never
    reaches them)."""
    p = layout.profile
    lo, hi = p.start_offset - 0.15, p.start_offset + p.travel + 0.15
    X_WT = layout.X_WTrack()
    rail_h = layout.clearance + layout.size[2] + 0.02
    z_mid = rail_h / 2 - X_WT.translation()[2]  # in the track frame (origin at bar centre)
    boxes = []
    for sign in (-1, 1):
        x = sign * (layout.size[0] / 2 + 0.06)
        boxes.append((X_WT @ RigidTransform([x, (lo + hi) / 2, z_mid]), (0.08, hi - lo, rail_h)))
        for y in (lo, hi):
            boxes.append((X_WT @ RigidTransform([x, y, z_mid + 0.03]), (0.12, 0.08, rail_h + 0.06)))
    add_textured_boxes(plant, f"{layout.name}_track_rails", boxes,
                       rgba(colors.get("rails", [0.62, 0.64, 0.66])), "brushed_metal")


class Task(TaskDefinition):
    SEED_DRAWS_START_ONLY = True  # the seed draws the start pose alone

    def build_scene(self, plant: MultibodyPlant, rng: np.random.Generator) -> Scene:
        s = self.spec.scene
        colors = s["colors"]
        b = s["bar"]
        add_flat_ground(plant, color=rgba(colors["ground"]))
        start = Rect(tuple(self.spec.start_region["center"]), tuple(self.spec.start_region["size"]))
        add_marker(plant, "start_region", start, 0.001, colors["start"])
        layout = BarLayout.from_spec(self.spec)

        instance = plant.AddModelInstance(layout.name)
        inertia = SpatialInertia.SolidBoxWithMass(float(b["mass"]), *layout.size)
        bar = plant.AddRigidBody(layout.name, instance, inertia)
        shape = Box(*layout.size)
        plant.RegisterCollisionGeometry(bar, RigidTransform(), shape, layout.name, GROUND_FRICTION)
        add_textured_box(plant, layout.name, RigidTransform(), layout.size, rgba(colors["bar"]),
                         "painted_metal", body=bar)
        _add_track(plant, layout, colors)
        track = plant.AddFrame(FixedOffsetFrame(f"{layout.name}_track", plant.world_frame(),
                                                layout.X_WTrack()))
        slider = plant.AddJoint(PrismaticJoint(f"{layout.name}_slider", track, bar.body_frame(),
                                               [0.0, 1.0, 0.0]))
        slider.set_default_translation(layout.profile.start_offset)
        drive = plant.AddJointActuator(f"{layout.name}_drive", slider, float(b["force_limit"]))
        drive.set_controller_gains(PdControllerGains(p=float(b["kp"]), d=float(b["kd"])))
        # Thin lines where the bar rests before and after its run (visual only).
        half = layout.size[0] / 2 * layout.axis
        for tag, off in (("from", layout.profile.start_offset),
                         ("to", layout.profile.start_offset + layout.profile.travel)):
            c = layout.center(off)[:2]
            add_line_marker(plant, f"bar_{tag}", c - half, c + half, 0.001, colors["track"],
                            width=layout.size[1] + 0.02)

        def add_bar_motion(builder, plant_):
            motion = builder.AddNamedSystem("bar_motion", bar_motion(layout.profile))
            builder.Connect(motion.get_output_port(), plant_.get_desired_state_input_port(instance))

        return Scene(
            name=self.name,
            start=self.spec.sample_start(rng),
            priors={"bar_id": layout.name, "bar_size": layout.size.copy()},
            data={"layout": layout},
            add_systems=[add_bar_motion],
        )

    def make_referee(self, plant: MultibodyPlant, robot: ModelInstanceIndex,
                     scene: Scene) -> Referee:
        return MovingBarReferee(self.spec, plant, robot, scene)

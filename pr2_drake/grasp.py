"""Symbolic pick / release as physical attachments.

A pick latches only when the task's condition holds (the hand sphere inside the valve's enlarged
volume, or within 0.20 m of an object). The attachment is a stiff spring-damper between the hand
sphere centre H and a point A on the object, applied through the plant's externally applied
spatial forces, so the object's weight and the valve's resistance act on the robot:

- ``ball`` attachments hold p_WH on p_WA and leave rotation free (the valve of task 2);
- ``weld`` attachments also hold the object's orientation relative to the hand (task 6).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.math import SpatialForce
from pydrake.multibody.plant import ExternallyAppliedSpatialForce, MultibodyPlant
from pydrake.multibody.tree import BodyIndex, ModelInstanceIndex
from pydrake.systems.framework import LeafSystem

from pr2_drake.lifetime import weak_calc
from pr2_drake.ports import PICK_VALUES

HAND_BODIES = {"left_hand": "l_arm_sphere", "right_hand": "r_arm_sphere"}


@dataclass
class Graspable:
    """Something the robot may pick.

    Attributes:
        name: the name reported in ``pick_state`` (e.g. "cup", "valve").
        body: the body index in the plant.
        mode: "weld" (position and orientation held) or "ball" (position only).
        can_pick: predicate (p_WH, X_WO) -> bool deciding whether a pick latches, given the
            hand sphere centre and the object's pose in world.
    """

    name: str
    body: BodyIndex
    mode: str
    can_pick: Callable[[np.ndarray, RigidTransform], bool]


@dataclass
class PickState:
    """What the hands hold. ``hand`` is "left_hand"/"right_hand" or "" when nothing is held."""

    attached: bool = False
    hand: str = ""
    object: str = ""


@dataclass
class GraspGains:
    """Attachment spring-damper: N/m, N s/m, Nm/rad, Nm s/rad."""

    stiffness: float = 3000.0
    damping: float = 60.0
    rot_stiffness: float = 5.0
    rot_damping: float = 0.1


@dataclass
class _Attachment:
    hand: str
    graspable: int
    p_OA: np.ndarray  # attachment point in the object frame
    R_HO: np.ndarray  # object orientation relative to the hand at pick time
    pick_time: float = 0.0
    extra: dict = field(default_factory=dict)

    def __deepcopy__(self, memo) -> "_Attachment":
        # Drake copies abstract state at every update of this system (100 Hz): a direct copy
        # costs a fraction of the generic deepcopy. Fields are str, int, float and arrays.
        return _Attachment(self.hand, self.graspable, self.p_OA.copy(), self.R_HO.copy(),
                           self.pick_time, {k: np.array(v) for k, v in self.extra.items()})


class GraspSystem(LeafSystem):
    """Latches ``pick`` / ``release`` commands into attachments and applies their forces.

    Input ports:
        pick: str, "" (none), "left_hand" or "right_hand".
        release: bool, True detaches whatever is held.
        plant_state: the full plant state [q; v].
    Output ports:
        pick_state: :class:`PickState`.
        spatial_forces: list of ExternallyAppliedSpatialForce for the plant.

    The command ports are sampled every ``period`` seconds (default 0.01 s).

    Sleeping objects (:mod:`pr2_drake.sleep`): the graspables named by :meth:`set_sleeping`
    also get a force of -m g at their centre of mass in ``spatial_forces``, which cancels
    their weight exactly (set between simulator advances; none by default).
    """

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    def __init__(
        self,
        plant: MultibodyPlant,
        robot: ModelInstanceIndex,
        graspables: list[Graspable],
        period: float = 0.01,
        gains: GraspGains | None = None,
    ):
        super().__init__()
        self._plant = plant
        self._ctx = plant.CreateDefaultContext()
        self._graspables = list(graspables)
        self._gains = gains or GraspGains()
        # Body indices, not bodies: a stored body holds the plant through a reference the
        # garbage collector cannot see (pr2_drake.lifetime).
        self._hands = {k: plant.GetBodyByName(v, robot).index() for k, v in HAND_BODIES.items()}
        self._weld_gains = [_stable_gains(self._gains, plant, g) for g in self._graspables]
        self._pick = self.DeclareAbstractInputPort("pick", AbstractValue.Make(""))
        self._release = self.DeclareAbstractInputPort("release", AbstractValue.Make(False))
        self._state = self.DeclareVectorInputPort(
            "plant_state", plant.num_positions() + plant.num_velocities()
        )
        self._attachment = self.DeclareAbstractState(AbstractValue.Make(_NoAttachment()))
        # The graspables that sleep (indices into graspables), a sorted tuple.
        self._sleeping = self.DeclareAbstractState(AbstractValue.Make(()))
        # Copies (np.array): pydrake's arrays may view the plant's memory and keep it alive.
        g_W = np.array(plant.gravity_field().gravity_vector())
        self._weight = {}  # graspable -> (p_BoBcm_B, -m g_W): the weight's cancelling force
        self._lift_cache: dict[tuple[int, ...], list] = {}
        for i, g in enumerate(self._graspables):
            body = plant.get_body(g.body)
            if body.is_floating_base_body():
                self._weight[i] = (np.array(body.default_com()),
                                   -(float(body.default_mass()) * g_W))
        self.DeclarePeriodicUnrestrictedUpdateEvent(period, 0.0, self._update)
        self.DeclareAbstractOutputPort(
            "pick_state", lambda: AbstractValue.Make(PickState()), weak_calc(self._calc_pick_state)
        )
        self.DeclareAbstractOutputPort(
            "spatial_forces",
            lambda: AbstractValue.Make([ExternallyAppliedSpatialForce()]),
            weak_calc(self._calc_forces),
        )

    # -- helpers ------------------------------------------------------------------------------
    def _set_state(self, context) -> None:
        x = self._state.Eval(context)
        self._plant.SetPositionsAndVelocities(self._ctx, x)

    def _pose(self, body) -> RigidTransform:
        return self._plant.EvalBodyPoseInWorld(self._ctx, body)

    # -- sleeping objects ---------------------------------------------------------------------
    def set_sleeping(self, context, graspables) -> None:
        """Make the graspables with these indices (free bodies only) sleep in ``context`` (the
        grasp system's): their weight is cancelled from now on; all others are awake."""
        ids = tuple(sorted(int(i) for i in graspables))
        bad = [i for i in ids if i not in self._weight]
        if bad:
            raise ValueError(f"set_sleeping: graspables {bad} are not free bodies")
        context.get_mutable_abstract_state(1).set_value(ids)

    def set_object_masses(self, masses: dict[int, float]) -> None:
        """Cancel the weight of these masses [kg] (body index -> mass) for sleeping free
        graspables from now on: the masses a domain randomisation set in the plant's context
        (:func:`pr2_drake.randomize.apply_physics`); others keep their default mass."""
        g_W = np.array(self._plant.gravity_field().gravity_vector())
        for i, g in enumerate(self._graspables):
            body = self._plant.get_body(g.body)
            if i in self._weight:
                mass = masses.get(int(g.body), float(body.default_mass()))
                self._weight[i] = (self._weight[i][0], -(float(mass) * g_W))
        self._lift_cache = {}

    def sleeping(self, context) -> tuple[int, ...]:
        """Indices of the sleeping graspables in ``context``."""
        return context.get_abstract_state(1).get_value()

    def held_graspable(self, context) -> int | None:
        """Index of the graspable a hand holds in ``context``, or None."""
        a = context.get_abstract_state(0).get_value()
        return a.graspable if isinstance(a, _Attachment) else None

    # -- events -------------------------------------------------------------------------------
    def _update(self, context, state) -> None:
        current = context.get_abstract_state(0).get_value()
        release = self._release.HasValue(context) and bool(self._release.Eval(context))
        pick = self._pick.Eval(context) if self._pick.HasValue(context) else ""
        if pick is None:
            pick = ""
        if pick not in PICK_VALUES:
            raise ValueError(f"pick: expected one of {PICK_VALUES}, got {pick!r}")
        if isinstance(current, _Attachment):
            if release:
                state.get_mutable_abstract_state(0).set_value(_NoAttachment())
            return
        if not pick or release:
            return
        self._set_state(context)
        X_WH = self._pose(self._plant.get_body(self._hands[pick]))
        p_WH = X_WH.translation()
        # Of the objects whose condition holds, latch the one whose origin is nearest the hand.
        best = None
        for i, g in enumerate(self._graspables):
            X_WO = self._pose(self._plant.get_body(g.body))
            if g.can_pick(p_WH, X_WO):
                d = float(np.linalg.norm(X_WO.translation() - p_WH))
                if best is None or d < best[0]:
                    best = (d, i, X_WO)
        if best is not None:
            _, i, X_WO = best
            R_HO = (X_WH.rotation().inverse() @ X_WO.rotation()).matrix()
            if self._graspables[i].mode == "weld":
                # A is the object's centre of mass, held where it was relative to the hand
                # (p_HA), so the spring exerts no lever torque on a light object.
                p_OA = self._plant.get_body(self._graspables[i].body).default_com()
                p_HA = X_WH.inverse().multiply(X_WO.multiply(p_OA))
            else:
                # A is the material point of the object under the hand centre at pick time.
                p_OA = X_WO.inverse().multiply(p_WH)
                p_HA = np.zeros(3)
            state.get_mutable_abstract_state(0).set_value(
                _Attachment(pick, i, p_OA, R_HO, context.get_time(), {"p_HA": p_HA})
            )

    # -- outputs ------------------------------------------------------------------------------
    def _calc_pick_state(self, context, output) -> None:
        a = context.get_abstract_state(0).get_value()
        if isinstance(a, _Attachment):
            output.set_value(PickState(True, a.hand, self._graspables[a.graspable].name))
        else:
            output.set_value(PickState())

    def _calc_forces(self, context, output) -> None:
        output.set_value(self._attachment_forces(context)
                         + self._lifts(context.get_abstract_state(1).get_value()))

    def _lifts(self, sleeping: tuple[int, ...]) -> list[ExternallyAppliedSpatialForce]:
        """The forces cancelling the sleeping graspables' weights (made once per set: this
        output is computed at every physics step)."""
        lifts = self._lift_cache.get(sleeping)
        if lifts is None:
            lifts = []
            for i in sleeping:
                p_BoBcm_B, f_W = self._weight[i]
                lift = ExternallyAppliedSpatialForce()
                lift.body_index = self._graspables[i].body
                lift.p_BoBq_B = p_BoBcm_B
                lift.F_Bq_W = SpatialForce(np.zeros(3), f_W)
                lifts.append(lift)
            self._lift_cache = {sleeping: lifts}  # the last set only: sets change rarely
        return lifts

    def _attachment_forces(self, context) -> list[ExternallyAppliedSpatialForce]:
        # Evaluated at every physics step while a hand holds something: plain 3-vector
        # arithmetic on the poses' matrices (no RigidTransform products, ~2x faster).
        a = context.get_abstract_state(0).get_value()
        if not isinstance(a, _Attachment):
            return []
        self._set_state(context)
        plant, ctx = self._plant, self._ctx
        g = self._graspables[a.graspable]
        hand = plant.get_body(self._hands[a.hand])
        obj = plant.get_body(g.body)
        X_WH = plant.EvalBodyPoseInWorld(ctx, hand)
        X_WO = plant.EvalBodyPoseInWorld(ctx, obj)
        V_WH = plant.EvalBodySpatialVelocityInWorld(ctx, hand)
        V_WO = plant.EvalBodySpatialVelocityInWorld(ctx, obj)
        R_WH, R_WO = X_WH.rotation().matrix(), X_WO.rotation().matrix()
        w_WH, w_WO = V_WH.rotational(), V_WO.rotational()
        p_OA_W = R_WO @ a.p_OA
        p_WA = X_WO.translation() + p_OA_W
        v_WA = V_WO.translational() + _cross(w_WO, p_OA_W)
        gains = self._gains if g.mode != "weld" else self._weld_gains[a.graspable]
        # Force on the object at A, pulling A towards its held place Q on the hand (the hand
        # centre H in ball mode).
        p_HA = a.extra.get("p_HA", _ZERO3)
        p_HQ_W = R_WH @ p_HA
        p_WQ = X_WH.translation() + p_HQ_W
        v_WQ = V_WH.translational() + _cross(w_WH, p_HQ_W)
        f_A = gains.stiffness * (p_WQ - p_WA) + gains.damping * (v_WQ - v_WA)
        tau = _ZERO3
        if g.mode == "weld":
            # Rotation vector of R_err = R_WO_desired R_WO^T (desired: as at the pick).
            tau = gains.rot_stiffness * _rotation_vector(R_WH @ a.R_HO @ R_WO.T) + (
                gains.rot_damping * (w_WH - w_WO))
        on_object = ExternallyAppliedSpatialForce()
        on_object.body_index = g.body
        on_object.p_BoBq_B = a.p_OA
        on_object.F_Bq_W = SpatialForce(tau, f_A)
        on_hand = ExternallyAppliedSpatialForce()
        on_hand.body_index = hand.index()
        on_hand.p_BoBq_B = p_HA
        on_hand.F_Bq_W = SpatialForce(-tau, -f_A)
        return [on_object, on_hand]


_ZERO3 = np.zeros(3)
_ZERO3.flags.writeable = False


def _rotation_vector(R: np.ndarray) -> np.ndarray:
    """angle * axis [rad] of the rotation matrix R (angle in [0, pi])."""
    c = min(max(0.5 * (R[0, 0] + R[1, 1] + R[2, 2] - 1.0), -1.0), 1.0)
    vee = 0.5 * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    angle = math.acos(c)
    if angle < 1e-6:  # sin(angle) ~ angle: vee is the rotation vector
        return vee
    if angle < math.pi - 1e-3:
        return (angle / math.sin(angle)) * vee
    aa = RotationMatrix(R).ToAngleAxis()  # near pi: the axis from the symmetric part
    return aa.angle() * aa.axis()


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b of two 3-vectors: np.cross's arithmetic (the same result to the bit) without its
    generality, which costs ~25 us a call; this runs twice per physics step while holding."""
    a0, a1, a2 = a.tolist()
    b0, b1, b2 = b.tolist()
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def _stable_gains(gains: GraspGains, plant: MultibodyPlant, g: Graspable) -> GraspGains:
    """``gains`` capped for a welded object so the explicit spring-damper stays stable at the
    plant's time step: stiffness <= m (0.3/dt)^2, damping <= 0.5 m/dt, and likewise with the
    smallest central moment of inertia for the rotational terms."""
    dt = plant.time_step()
    body = plant.get_body(g.body)
    if dt <= 0 or g.mode != "weld":
        return gains
    m = body.default_mass()
    com = body.default_com()
    I_Bo = body.default_rotational_inertia().CopyToFullMatrix3()
    I_com = I_Bo - m * (np.dot(com, com) * np.eye(3) - np.outer(com, com))
    i_min = max(float(np.linalg.eigvalsh(I_com).min()), 1e-9)
    w = 0.3 / dt
    return GraspGains(
        stiffness=min(gains.stiffness, m * w * w),
        damping=min(gains.damping, 0.5 * m / dt),
        rot_stiffness=min(gains.rot_stiffness, i_min * w * w),
        rot_damping=min(gains.rot_damping, 0.5 * i_min / dt),
    )


class _NoAttachment:
    """Marker for the empty attachment state (no fields: a copy is the same marker)."""

    __slots__ = ()

    def __deepcopy__(self, memo) -> "_NoAttachment":
        # Drake copies this abstract state at every update of the grasp system (100 Hz); the
        # generic deepcopy of an empty object costs ~10 us.
        return self

"""StandingController: joint-space PD with weight compensation; legs torque-driven.

Leg efforts are ``tau = Kp (q_d - q) - Kd v + tau_static(q)``, where ``tau_static`` are the joint
torques that hold the robot still with its weight shared equally by the two soles (computed from
the gravity generalized forces and the sole Jacobians of a private plant). Arms are held in
position mode around the nominal pose.
"""


from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import JacobianWrtVariable
from pydrake.systems.framework import LeafSystem

from pr2_drake.params import Params
from pr2_drake.ports import (
    BODY_STATE_SIZE,
    JOINT_STATE_SIZE,
    N_ARMS,
    N_LEGS,
    P_WB,
    Q_ARMS,
    Q_LEGS,
    QUAT_WB,
    V_LEGS,
    JointGroupCommand,
)
from pr2_drake.robot.model import KuavoMaps, add_kuavo
from pr2_drake.robot.params import load_robot_params


@dataclass
class StandingParams(Params):
    """Gains [Nm/rad, Nm s/rad] per joint in the original order, and the update period [s]."""

    FILE: ClassVar[str] = "params/controllers/standing.yaml"
    period: float = 0.004
    leg_kp: list[float] = field(default_factory=lambda: [400.0] * N_LEGS)
    leg_kd: list[float] = field(default_factory=lambda: [8.0] * N_LEGS)
    arm_kp: list[float] = field(default_factory=lambda: [60.0] * N_ARMS)
    arm_kd: list[float] = field(default_factory=lambda: [3.0] * N_ARMS)

    def check(self) -> None:
        for name, n in (("leg_kp", N_LEGS), ("leg_kd", N_LEGS), ("arm_kp", N_ARMS),
                        ("arm_kd", N_ARMS)):
            if len(getattr(self, name)) != n:
                raise ValueError(f"StandingParams: {name} needs {n} values, "
                                 f"got {len(getattr(self, name))}")


class StandingPolicy:
    """The standing control law, usable without a diagram.

    ``legs, arms = policy.compute(joint_state, body_state)`` with the testbed's vector layouts.
    """

    def __init__(self, params: StandingParams | None = None):
        self.params = params or StandingParams.load()
        robot_params = load_robot_params()
        self.q_legs_d = robot_params.default_positions("legs")
        self.q_arms_d = robot_params.default_positions("arms")
        self._plant = MultibodyPlant(0.0)
        robot = add_kuavo(self._plant)
        self._plant.Finalize()
        self._maps = KuavoMaps.from_plant(self._plant, robot)
        self._ctx = self._plant.CreateDefaultContext()
        self._soles = [self._plant.GetFrameByName(f"{s}_sole") for s in ("l", "r")]
        self._mg = self._plant.CalcTotalMass(self._ctx) * 9.81
        self._leg_v = self._maps.v_joints[N_ARMS:]
        self._arm_v = self._maps.v_joints[:N_ARMS]
        self._kp = np.asarray(self.params.leg_kp)
        self._kd = np.asarray(self.params.leg_kd)

    def static_torques(self, joint_state: np.ndarray, body_state: np.ndarray) -> np.ndarray:
        """Joint torques [Nm] (18, original order) holding the robot still on both soles."""
        q = np.zeros(self._maps.nq)
        q[self._maps.q_base[:4]] = body_state[QUAT_WB]
        q[self._maps.q_base[4:]] = body_state[P_WB]
        q[self._maps.q_joints] = joint_state[Q_ARMS.start:Q_LEGS.stop]
        self._plant.SetPositions(self._ctx, q)
        tau = -self._plant.CalcGravityGeneralizedForces(self._ctx)
        world = self._plant.world_frame()
        f = np.array([0.0, 0.0, self._mg / 2])
        for sole in self._soles:
            J = self._plant.CalcJacobianTranslationalVelocity(
                self._ctx, JacobianWrtVariable.kV, sole, np.zeros(3), world, world
            )
            tau -= J.T @ f
        return tau[self._maps.v_joints]

    def compute(self, joint_state: np.ndarray, body_state: np.ndarray):
        """Returns (legs_command, arms_command) as JointGroupCommands."""
        tau_static = self.static_torques(joint_state, body_state)
        q = joint_state[Q_LEGS]
        v = joint_state[V_LEGS]
        tau = self._kp * (self.q_legs_d - q) - self._kd * v + tau_static[N_ARMS:]
        legs = JointGroupCommand.effort(tau)
        arms = JointGroupCommand.position(self.q_arms_d, self.params.arm_kp, self.params.arm_kd)
        return legs, arms


class StandingController(LeafSystem):
    """Diagram block of :class:`StandingPolicy`.

    Input ports: ``joint_state`` (54), ``body_state`` (13).
    Output ports: ``legs_command``, ``arms_command`` (JointGroupCommand), updated every
    ``params.period`` seconds and held in between.
    """

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    def __init__(self, params: StandingParams | None = None):
        super().__init__()
        self.policy = StandingPolicy(params)
        self._joint_state = self.DeclareVectorInputPort("joint_state", JOINT_STATE_SIZE)
        self._body_state = self.DeclareVectorInputPort("body_state", BODY_STATE_SIZE)
        legs0 = JointGroupCommand.effort(np.zeros(N_LEGS))
        arms0 = JointGroupCommand.position(self.policy.q_arms_d, self.policy.params.arm_kp,
                                           self.policy.params.arm_kd)
        self._legs = self.DeclareAbstractState(AbstractValue.Make(legs0))
        self._arms = self.DeclareAbstractState(AbstractValue.Make(arms0))
        self.DeclarePeriodicUnrestrictedUpdateEvent(self.policy.params.period, 0.0, self._update)
        self.DeclareStateOutputPort("legs_command", self._legs)
        self.DeclareStateOutputPort("arms_command", self._arms)

    def _update(self, context, state) -> None:
        legs, arms = self.policy.compute(
            self._joint_state.Eval(context), self._body_state.Eval(context)
        )
        state.get_mutable_abstract_state(int(self._legs)).set_value(legs)
        state.get_mutable_abstract_state(int(self._arms)).set_value(arms)

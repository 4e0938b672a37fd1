"""WalkingController: velocity command -> leg torques, as a Drake LeafSystem and in process.

Input ports:
    ``velocity_command`` (3): vx [m/s], vy [m/s], yaw_rate [rad/s] in the robot's heading frame.
        Unconnected = stand still. NaN/inf or a wrong size raise ValueError naming the port;
        values beyond ``limits`` in params/controllers/walking.yaml are clipped to them.
    ``joint_state`` (54), ``body_state`` (13): the testbed's observations (pr2_drake.ports).
    With ``arms="effort"`` only (not ``"balance"``):
    ``hand_targets`` (abstract, a list [left, right]): per hand None or a desired hand-sphere
        centre p_WH (3) [m] in world, optionally followed by an axis of the hand frame to keep
        vertical (6 values; e.g. a held object's "up", so it is carried and set down
        upright). NaN/inf or a wrong shape raise ValueError naming the port; targets beyond
        reach are clipped onto the workspace (within ``arms.reach_max`` of the shoulder,
        ``arms.z_min`` above the soles).
        Unconnected = no hand targets (posture).
    ``pick_state`` (abstract :class:`pr2_drake.grasp.PickState`): while a hand is attached,
        its contact force is a variable of the QP (bounded by ``qp.hand_force_max``), so the
        balance plans for the reaction. Unconnected = nothing held.
Output ports:
    ``legs_command``: :class:`pr2_drake.ports.JointGroupCommand`, mode "effort" [Nm].
    ``arms_command`` (``arms="effort"`` or ``"balance"``): mode "effort" [Nm], from the same QP.
    ``status`` (6): see :data:`pr2_drake.controllers.whole_body.STATUS_FIELDS`
        (qp_ok, consecutive QP failures, QP iterations, gait phase, stance side, falling).

With ``arms="position"`` (default) the arms are held by another block in position mode
(:class:`pr2_drake.controllers.posture.ArmPosture`) and the QP takes their torques as given.
With ``arms="balance"`` the QP drives the arms towards their pose (``arms.posture``) and nothing
else: they swing with the balance; no hand-force variables, and the arm torque rows are left
out of DAQP's problem (the torques are clamped after it).

The control law runs every ``control_period`` seconds (a periodic discrete update) and the torques
are held in between. The gait and planner memory live in the Python object
(:class:`pr2_drake.controllers.whole_body.WholeBodyController`), not in the Context: one
controller drives one simulation at a time; a simulation that restarts at an earlier time
resets it.

In process, without a Diagram (the PR2 platform's walking-server call)::

    walker = WalkingController()
    legs = walker.command(obs, vx, vy, yaw_rate)   # {"ctrl_mode": "effort", ...}

``command`` takes the time from ``obs["time"]`` and runs the control law once per
``control_period`` (holding the torques in between), so it can be called every env step.

Both paths call the same :meth:`WholeBodyController.update`.
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, LeafSystem

from pr2_drake.controllers.planning.terrain import FlatTerrain
from pr2_drake.controllers.planning.footsteps import FootstepPlanner
from pr2_drake.controllers.walking_params import WalkingParams
from pr2_drake.controllers.whole_body import (
    COMMAND_PORT,
    HAND_TARGETS_PORT,
    STATUS_FIELDS,
    WholeBodyController,
    check_command,
)
from pr2_drake.grasp import PickState
from pr2_drake.lifetime import weak_calc
from pr2_drake.observation import state_vectors
from pr2_drake.ports import (
    BODY_STATE_SIZE,
    EFFORT_ARMS,
    JOINT_STATE_SIZE,
    N_ARMS,
    N_LEGS,
    JointGroupCommand,
)


def _load(params: WalkingParams | str | None) -> WalkingParams:
    if params is None:
        return WalkingParams.load()
    if isinstance(params, WalkingParams):
        return params
    return WalkingParams.load(str(params))


class WalkingController(LeafSystem):
    """The built-in walking controller (see the module docstring for ports and units).

    Args:
        params: a WalkingParams, a path to a YAML file, or None for params/controllers/walking.yaml.
        footsteps: footstep planner (None: from the velocity command).
        terrain: terrain model of the footholds (None: flat ground).
        arms: "position" (arms held by another block), "effort" (the QP drives them, with hand
            targets) or "balance" (the QP drives them, posture only).
    """

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    def __init__(self, params: WalkingParams | str | None = None,
                 footsteps: FootstepPlanner | None = None, terrain: FlatTerrain | None = None,
                 arms: str = "position"):
        super().__init__()
        self.params = _load(params)
        self.core = WholeBodyController(self.params, footsteps, terrain, arms)
        self._cmd_port = self.DeclareVectorInputPort(COMMAND_PORT, 3)
        self._js_port = self.DeclareVectorInputPort("joint_state", JOINT_STATE_SIZE)
        self._bs_port = self.DeclareVectorInputPort("body_state", BODY_STATE_SIZE)
        self._arms = self.core.arms_driven
        self._hands = self.core.hands
        if self._hands:
            self._hand_port = self.DeclareAbstractInputPort(HAND_TARGETS_PORT,
                                                            AbstractValue.Make([None, None]))
            self._pick_port = self.DeclareAbstractInputPort("pick_state",
                                                            AbstractValue.Make(PickState()))
        n_status = len(STATUS_FIELDS)
        self._n_tau = N_LEGS + (N_ARMS if self._arms else 0)
        self._state = self.DeclareDiscreteState(self._n_tau + n_status)
        self.DeclarePeriodicDiscreteUpdateEvent(self.params.control_period, 0.0, self._update)
        self.DeclareInitializationDiscreteUpdateEvent(self._update)
        self.DeclareAbstractOutputPort(
            "legs_command", lambda: AbstractValue.Make(JointGroupCommand.effort(np.zeros(N_LEGS))),
            weak_calc(self._calc_legs),
            prerequisites_of_calc={self.discrete_state_ticket(self._state)})
        if self._arms:
            self.DeclareAbstractOutputPort(
                "arms_command",
                lambda: AbstractValue.Make(JointGroupCommand.effort(np.zeros(N_ARMS))),
                weak_calc(self._calc_arms),
                prerequisites_of_calc={self.discrete_state_ticket(self._state)})
        self.DeclareVectorOutputPort(
            "status", n_status, weak_calc(self._calc_status),
            prerequisites_of_calc={self.discrete_state_ticket(self._state)})
        self._t_in_process = 0.0
        self._t_last_update: float | None = None
        self._held: np.ndarray | None = None

    # ---- diagram path -------------------------------------------------------------------------
    def _update(self, context, discrete_state) -> None:
        # (The core checks the command: a ValueError naming this port.)
        port = self._cmd_port
        cmd = port.Eval(context) if port.HasValue(context) else np.zeros(3)
        joint_state = self._js_port.Eval(context)
        q, v = self.core.model.state_from_ports(joint_state, self._bs_port.Eval(context))
        t = context.get_time()
        if self._arms:
            targets, attached = None, (False, False)
            if self._hands:
                hp, pp = self._hand_port, self._pick_port
                targets = hp.Eval(context) if hp.HasValue(context) else None
                pick = pp.Eval(context) if pp.HasValue(context) else None
                attached = (bool(pick and pick.attached and pick.hand == "left_hand"),
                            bool(pick and pick.attached and pick.hand == "right_hand"))
            # The applied arm efforts (one step old) give the held hand's force estimate.
            applied = joint_state[EFFORT_ARMS] if t > 0.0 else None
            tau = self.core.update(t, q, v, cmd, applied, targets, attached)
            tau = np.concatenate([tau, self.core.tau_arms, self.core.info.vector()])
        else:
            # The applied arm efforts (one step old) tell the QP what the arm controller does.
            tau_arms = joint_state[EFFORT_ARMS] if t > 0.0 else None
            tau = np.concatenate([self.core.update(t, q, v, cmd, tau_arms),
                                  self.core.info.vector()])
        discrete_state.get_mutable_vector(self._state).SetFromVector(tau)

    def _calc_legs(self, context, output) -> None:
        tau = context.get_discrete_state(self._state).get_value()[:N_LEGS]
        output.set_value(JointGroupCommand.effort(tau.copy()))

    def _calc_arms(self, context, output) -> None:
        tau = context.get_discrete_state(self._state).get_value()[N_LEGS:self._n_tau]
        output.set_value(JointGroupCommand.effort(tau.copy()))

    def _calc_status(self, context, output: BasicVector) -> None:
        output.SetFromVector(context.get_discrete_state(self._state).get_value()[self._n_tau:])

    # ---- in-process path ---------------------------------------------------------------------
    def command(self, obs: Mapping[str, Any], vx: float, vy: float, yaw_rate: float,
                t: float | None = None) -> dict[str, Any]:
        """Leg action from a PR2 observation dict; call it at any rate (e.g. every env step).

        The control law runs at most once per ``control_period`` of simulated time, like the
        Diagram block: a call less than one period after the last update returns the held
        torques of that update.

        Args:
            obs: the observation (see :func:`pr2_drake.observation.state_vectors`); its ``"time"`` entry [s], when
                present, is the simulation time.
            vx, vy, yaw_rate: velocity command in the heading frame [m/s, m/s, rad/s].
            t: simulation time [s]; overrides ``obs["time"]``. With neither, the previous
                update's time plus ``control_period`` (then call once per control period).
        Returns:
            ``{"ctrl_mode": "effort", "joint_values": tau (10), "stiffness": None,
            "dampings": None}``.
        """
        cmd = check_command([vx, vy, yaw_rate], COMMAND_PORT)
        joint_state, body_state = state_vectors(obs)
        if t is None and isinstance(obs, Mapping) and obs.get("time") is not None:
            t = float(obs["time"])
            if not np.isfinite(t):
                raise ValueError(f"obs: time must be finite, got {obs['time']!r}")
        if t is None:
            t = self._t_in_process
        t = float(t)
        period = self.params.control_period
        last = self._t_last_update
        if (last is not None and self._held is not None
                and last - 1e-9 <= t < last + period - 1e-9):
            return self._action(self._held)  # within the control period: hold
        q, v = self.core.model.state_from_ports(joint_state, body_state)
        tau = self.core.update(t, q, v, cmd, joint_state[EFFORT_ARMS])
        self._t_last_update = t
        self._t_in_process = t + period
        self._held = tau.copy()
        return self._action(self._held)

    @staticmethod
    def _action(tau: np.ndarray) -> dict[str, Any]:
        return {"ctrl_mode": "effort", "joint_values": tau.copy(), "stiffness": None,
                "dampings": None}

    def reset(self) -> None:
        """Forget the gait state and the in-process clock."""
        self.core.reset()
        self._t_in_process = 0.0
        self._t_last_update = None
        self._held = None

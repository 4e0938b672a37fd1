"""JumpController: walking plus jumps, as a Drake LeafSystem and in process.

A jump is a plan (:class:`pr2_drake.controllers.planning.jump_planner.JumpPlanner`: crouch, launch by a
centroidal MPC, flight without contacts, landing with a CoM impedance, recovery) tracked by the
same whole-body QP as walking (:class:`pr2_drake.controllers.whole_body.WholeBodyController`):
between jumps the gait planner plans (stand or walk), during a jump the jump planner does, and
the walking planner takes over again from the measured state.

Input ports (those of :class:`pr2_drake.controllers.walking.WalkingController`, plus):
    ``jump_command`` (4): [t_takeoff [s] (simulation time), vx, vy [m/s] (CoM velocity at
        take-off, heading frame), apex [m] (CoM rise above its take-off height)]. All zero or
        unconnected: no jump. A request is taken once (a changed vector is a new request); it
        starts when the gait stands still and at least the crouch-and-launch time before
        take-off (a take-off sooner than that is postponed: ``jump_status`` says by how much).
        NaN/inf, a wrong size, a negative or too high apex, a too fast velocity, or a new
        request while a jump is under way raise ValueError naming ``jump_command``.
Output ports (those of the walking controller, plus):
    ``jump_status`` (6): phase (:class:`JumpPhase`), planned take-off time [s], take-off delay
        [s], last MPC solve ok (1/0), last MPC solve time [ms], jumps completed.

In process (no Diagram)::

    jumper = JumpController()
    legs = jumper.command(obs, jump=(t_takeoff, vx, vy, apex))   # velocity command optional

Arms: held by another block in position mode (:class:`pr2_drake.controllers.posture.ArmPosture`).
"""

from __future__ import annotations

import math
from typing import Any, Mapping

import numpy as np

from pr2_drake.controllers.planning.terrain import FlatTerrain
from pr2_drake.controllers.planning.footsteps import FootstepPlanner
from pr2_drake.controllers.frames import yaw_of
from pr2_drake.controllers.planning.gait import Phase
from pr2_drake.controllers.jump_params import JumpParams
from pr2_drake.controllers.planning.jump_planner import JumpPhase, JumpPlanner, JumpRequest
from pr2_drake.controllers.tracking.jump_objectives import (
    AngularMomentumObjective,
    Com3dObjective,
    ScaledPelvisObjective,
    SolesObjective,
)
from pr2_drake.controllers.walking import WalkingController
from pr2_drake.controllers.walking_params import WalkingParams
from pr2_drake.controllers.whole_body import COMMAND_PORT, WholeBodyController, check_command
from pr2_drake.lifetime import weak_calc
from pr2_drake.observation import state_vectors
from pr2_drake.ports import EFFORT_ARMS

JUMP_PORT = "jump_command"
JUMP_STATUS_FIELDS = ("phase", "t_takeoff", "takeoff_delay", "mpc_ok", "mpc_ms", "jumps")


def check_jump_command(command, params: JumpParams, port: str = JUMP_PORT):
    """A jump command as a :class:`JumpRequest`, or None for "no jump" (all zero); ValueError
    naming the port on a wrong size, NaN/inf, a negative apex, an apex above ``max_apex`` or a
    speed above ``max_speed``."""
    if command is None:
        return None
    try:
        c = np.asarray(command, dtype=float).reshape(-1)
    except (TypeError, ValueError) as err:
        raise ValueError(f"{port}: expected 4 numbers (t_takeoff, vx, vy, apex), got "
                         f"{command!r}") from err
    if c.shape != (4,):
        raise ValueError(f"{port}: expected 4 values (t_takeoff, vx, vy, apex), got shape "
                         f"{c.shape}")
    if not np.all(np.isfinite(c)):
        raise ValueError(f"{port}: command contains NaN or inf: {c}")
    if not np.any(c):
        return None
    if c[3] < 0.0:
        raise ValueError(f"{port}: apex height must be >= 0 m, got {c[3]:g}")
    if c[3] > params.max_apex:
        raise ValueError(f"{port}: apex height {c[3]:g} m exceeds max_apex {params.max_apex:g} m")
    if c[3] == 0.0:
        raise ValueError(f"{port}: apex height is 0 (use an all-zero command for no jump)")
    if c[0] < 0.0:
        raise ValueError(f"{port}: take-off time must be >= 0 s, got {c[0]:g}")
    if float(np.hypot(c[1], c[2])) > params.max_speed:
        raise ValueError(f"{port}: horizontal speed {np.hypot(c[1], c[2]):g} m/s exceeds "
                         f"max_speed {params.max_speed:g} m/s")
    return JumpRequest(float(c[0]), c[1:3].copy(), float(c[3]))


class JumpCore:
    """Walking core + jump planner + the jump's objectives, one tick at a time (plain Python).

    Args:
        core: the whole-body controller (its model, QP, contact and posture objectives are shared;
            arms in position mode).
        params: jump parameters (None: params/controllers/jumping.yaml).
    """

    def __init__(self, core: WholeBodyController, params: JumpParams | None = None):
        if core.arms_driven:
            raise ValueError("JumpController: arms='effort' is not supported (arms in position)")
        self.core = core
        self.params = params or JumpParams.load()
        p, m = self.params, core.model
        wp = core.params
        fz_max = wp.qp.fz_max_factor * m.mass * m.gravity
        self.planner = JumpPlanner(self.params, m, wp.gait.stand_com_height, fz_max)
        self.objectives = [Com3dObjective(), AngularMomentumObjective(m), ScaledPelvisObjective(wp.pelvis, m),
                      core.contacts,
                      SolesObjective(p.soles, p.soles_rot), core.posture]
        self.reset()

    def reset(self) -> None:
        self.planner.reset()
        self.pending: JumpRequest | None = None
        self.last_command = np.zeros(4)
        self.takeoff_delay = 0.0
        self.jumps = 0
        self.history: list[dict] = []

    @property
    def phase(self) -> JumpPhase:
        return self.planner.phase

    def request(self, t: float, command) -> None:
        """Take a jump command (see the module docstring); ValueError naming the port."""
        req = check_jump_command(command, self.params)
        c = np.zeros(4) if command is None else np.asarray(command, dtype=float).reshape(-1)
        if req is None or np.array_equal(c, self.last_command):
            return
        if self.planner.active or self.pending is not None:
            raise ValueError(f"{JUMP_PORT}: a jump is already under way (phase "
                             f"{self.planner.phase.name if self.planner.active else 'PENDING'}"
                             f"); a new request is taken after it ends")
        self.last_command = c.copy()
        self.pending = req
        self.takeoff_delay = 0.0

    def update(self, t: float, q: np.ndarray, v: np.ndarray, command, jump_command=None,
               tau_arms: np.ndarray | None = None) -> np.ndarray:
        """One control tick: leg torques [Nm]."""
        self.request(t, jump_command)
        core = self.core
        if not self.planner.active and self.pending is not None:
            req = self.pending
            lead = self.planner.lead_time(req)
            if t >= req.t_takeoff - lead - 1e-9 and core.phase == Phase.STAND \
                    and core.t_last is not None:
                late = t + lead - req.t_takeoff
                if late > 0.0:
                    # Too late for the full crouch: shorten it to half, then postpone.
                    spare = 0.5 * (self.params.crouch_time + self.params.crouch_hold)
                    delay = max(0.0, late - spare)
                    self.takeoff_delay = delay
                    req = JumpRequest(req.t_takeoff + delay, req.velocity, req.apex)
                core.model.update(q, v)
                heading = core.planner.heading
                if heading is None:
                    heading = yaw_of(core.model.base_rotation())
                self.planner.start(t, req, heading)
                self.pending = None
        if not self.planner.active:
            return core.update(t, q, v, command, tau_arms)
        core.model.update(q, v)
        plan = self.planner.update(t)
        if not self.planner.active:  # the jump ended this tick: walking takes over
            self.jumps += 1
            self.history.append(dict(self.planner.log))
            core.planner.reset()
            return core.update(t, q, v, command, tau_arms)
        # The jump's plan and objectives, tracked by the whole-body controller's own QP.
        return core.track(plan, self.objectives, q, v, tau_arms, self.params.joint_limit_horizon)


class JumpController(WalkingController):
    """The walking controller with jumps (see the module docstring).

    Args:
        params: walking parameters (WalkingParams, YAML path or None: params/controllers/walking.yaml).
        jump_params: jump parameters (JumpParams, YAML path or None: params/controllers/jumping.yaml).
        footsteps, terrain: as for :class:`WalkingController`.
    """

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    def __init__(self, params: WalkingParams | str | None = None,
                 jump_params: JumpParams | str | None = None,
                 footsteps: FootstepPlanner | None = None, terrain: FlatTerrain | None = None):
        super().__init__(params, footsteps, terrain, arms="position")
        if jump_params is None or isinstance(jump_params, str):
            jump_params = JumpParams.load(jump_params or "params/controllers/jumping.yaml")
        self.jump = JumpCore(self.core, jump_params)
        self._jump_port = self.DeclareVectorInputPort(JUMP_PORT, 4)
        self._jstate = self.DeclareDiscreteState(len(JUMP_STATUS_FIELDS))
        self.DeclareVectorOutputPort(
            "jump_status", len(JUMP_STATUS_FIELDS), weak_calc(self._calc_jump_status),
            prerequisites_of_calc={self.discrete_state_ticket(self._jstate)})

    def jump_status(self) -> np.ndarray:
        j = self.jump
        sol = j.planner.mpc_solution
        req = j.planner.request if j.planner.active else j.pending
        return np.array([float(j.phase), req.t_takeoff if req is not None else math.nan,
                         j.takeoff_delay, float(sol.ok) if sol is not None else 1.0,
                         1e3 * sol.solve_time if sol is not None else 0.0, float(j.jumps)])

    # ---- diagram path -------------------------------------------------------------------------
    def _update(self, context, discrete_state) -> None:
        cmd = self._cmd_port.Eval(context) if self._cmd_port.HasValue(context) else np.zeros(3)
        cmd = check_command(cmd, COMMAND_PORT)
        jump = self._jump_port.Eval(context) if self._jump_port.HasValue(context) else None
        joint_state = self._js_port.Eval(context)
        q, v = self.core.model.state_from_ports(joint_state, self._bs_port.Eval(context))
        t = context.get_time()
        tau_arms = joint_state[EFFORT_ARMS] if t > 0.0 else None
        if t == 0.0 and self.core.t_last is not None:
            self.jump.reset()  # a simulation that restarts
        tau = self.jump.update(t, q, v, cmd, jump, tau_arms)
        discrete_state.get_mutable_vector(self._state).SetFromVector(
            np.concatenate([tau, self.core.info.vector()]))
        discrete_state.get_mutable_vector(self._jstate).SetFromVector(self.jump_status())

    def _calc_jump_status(self, context, output) -> None:
        output.SetFromVector(context.get_discrete_state(self._jstate).get_value())

    # ---- in-process path ---------------------------------------------------------------------
    def command(self, obs: Mapping[str, Any], vx: float = 0.0, vy: float = 0.0,
                yaw_rate: float = 0.0, t: float | None = None, jump=None) -> dict[str, Any]:
        """Leg action from a PR2 observation dict (see :meth:`WalkingController.command`), with
        an optional jump request ``jump`` = (t_takeoff, vx, vy, apex) (see the module
        docstring; ValueError naming ``jump_command`` when invalid)."""
        cmd = check_command([vx, vy, yaw_rate], COMMAND_PORT)
        joint_state, body_state = state_vectors(obs)
        if t is None and isinstance(obs, Mapping) and obs.get("time") is not None:
            t = float(obs["time"])
            if not np.isfinite(t):
                raise ValueError(f"obs: time must be finite, got {obs['time']!r}")
        if t is None:
            t = self._t_in_process
        t = float(t)
        self.jump.request(t, jump)  # validate now, even within a held control period
        period = self.params.control_period
        last = self._t_last_update
        if (last is not None and self._held is not None
                and last - 1e-9 <= t < last + period - 1e-9):
            return self._action(self._held)
        q, v = self.core.model.state_from_ports(joint_state, body_state)
        tau = self.jump.update(t, q, v, cmd, None, joint_state[EFFORT_ARMS])
        self._t_last_update = t
        self._t_in_process = t + period
        self._held = tau.copy()
        return self._action(self._held)

    def reset(self) -> None:
        super().reset()
        self.jump.reset()



"""Task 2 reference agent: walk to the valve, take the rim with a hand and turn it.

:class:`ValveAgent` is a Diagram of a sequencer (:class:`ValveSequencer`) and the walking
controller with the arms in the whole-body QP (``WalkingController(arms="effort")``):

1. WALK: towards a standing point ``stand_distance`` from the valve axis, on the line from the
   robot to the ``valve_center`` prior (goal-velocity steering, :func:`goal_velocity`);
2. APPROACH: small steps (proportional velocity command) onto that point, facing the axis;
   then wait until the gait is standing;
3. REACH: the left hand rises beside the wheel, then moves over the rim, ``grasp_height`` above
   the wheel centre at angle ``angle_start`` about the axis (in the approach frame A: x from the
   robot to the axis, 180 deg = the rim point nearest the robot);
4. PICK: sends ``pick`` = "left_hand" until ``pick_state`` reports it attached (the hand
   centre is inside the enlarged valve volume);
5. TURN: the hand target moves along the circle about the valve axis through the picked
   point, to ``angle_end``; the attachment turns the wheel with it, and the QP carries the hand's
   contact force (pick_state input of the controller);
6. RELEASE once the hand has travelled ``release_angle`` about the axis; the hand goes back up
   and out, then to the arm posture; the robot stays standing.

Only the public observation (``body_state``, ``joint_state``, ``pick_state``) and the task's
priors (``valve_center``, ``valve_dimensions``) are used. Angles in rad unless named _deg;
positions in m, world frame W. Parameters: params/agents/valve.yaml.

(No ``from __future__ import annotations``: ``yaml_load_typed`` reads the field types.)
"""

import enum
import math
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Diagram

from pr2_drake.agents.sequencer import (
    Now,
    SequencerMemory,
    TaskSequencer,
    along_path,
    build_sequencer_agent,
)
from pr2_drake.agents.walk_to_goal import GoalPlannerParams, goal_velocity, yaw_from_quaternion
from pr2_drake.grasp import PickState
from pr2_drake.params import Params
from pr2_drake.ports import BODY_STATE_SIZE, JOINT_STATE_SIZE, P_WB, QUAT_WB


@dataclass
class ValveAgentParams(Params):
    """See params/agents/valve.yaml (m, s, deg where named)."""

    FILE: ClassVar[str] = "params/agents/valve.yaml"
    period: float = 0.02  # [s] sequencer update period
    stand_distance: float = 0.45  # base to valve axis, horizontal
    approach_radius: float = 0.30  # switch from WALK to APPROACH this close to the point
    position_tolerance: float = 0.03
    yaw_tolerance_deg: float = 4.0
    approach_gain: float = 1.0  # [1/s] velocity per m of position error
    approach_yaw_gain: float = 1.5  # [1/s]
    approach_speed: float = 0.12  # [m/s] cap of the approach steps
    settle_time: float = 1.0  # [s] standing still before reaching
    grasp_height: float = 0.13  # hand centre above the wheel centre
    grasp_radius: float = 0.24  # hand centre from the axis
    lift_clearance: float = 0.03  # the hand rises outside the rim's radius by this much
    angle_start_deg: float = 195.0  # in the approach frame A (180 = nearest rim point)
    angle_end_deg: float = 110.0
    reach_time: float = 1.5  # [s] per reach segment
    turn_speed_deg: float = 20.0  # [deg/s] hand target speed about the axis
    release_angle_deg: float = 70.0  # hand travel about the axis before release
    pick_timeout: float = 1.5  # [s] without attachment: retry closer to the axis
    hold_time: float = 0.5  # [s] at the end points before the next phase



class Stage(enum.IntEnum):
    WALK = 0
    APPROACH = 1
    SETTLE = 2
    REACH = 3
    PICK = 4
    TURN = 5
    RELEASE = 6
    RETRACT = 7
    DONE = 8


@dataclass
class ValveMemory(SequencerMemory):
    """What the valve sequencer remembers (besides :class:`SequencerMemory`): the standing
    point (x, y, yaw) and the approach frame's yaw [rad], the hand's path (waypoints in W [m],
    from ``path_t0`` [s]), where the hand picked the rim (angle in the approach frame, radius
    and height about the valve's centre) and its angle now, and the pick tries."""

    stage: int = Stage.WALK
    stand: np.ndarray | None = None
    yaw_A: float = 0.0
    path: list = field(default_factory=list)
    path_t0: float = 0.0
    phi_pick: float = 0.0
    r_pick: float = 0.0
    z_pick: float = 0.0
    phi_now: float = 0.0
    pick_tries: int = 0


class ValveSequencer(TaskSequencer):
    """Stages of the valve turn (see the module docstring).

    Inputs: ``body_state``, ``joint_state``, ``pick_state``, ``walker_status`` (the walking
    controller's status). Outputs: ``velocity_command`` (3), ``hand_targets`` ([left, right]),
    ``pick`` (str), ``release`` (bool), ``stage`` (1). Memory: :class:`ValveMemory`.
    """

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    HAND = 0  # left

    def __init__(self, center, rim_radius: float, params: ValveAgentParams | None = None,
                 goal_params: GoalPlannerParams | None = None):
        super().__init__()
        from pr2_drake.controllers.model import WholeBodyModel

        self.center = np.asarray(center, dtype=float).reshape(-1)
        if self.center.shape != (3,) or not np.all(np.isfinite(self.center)):
            raise ValueError(f"ValveSequencer: valve_center must be 3 finite values, got {center}")
        self.rim_radius = float(rim_radius)  # outer radius of the wheel [m]
        self.p = params or ValveAgentParams()
        self.goal_params = goal_params or GoalPlannerParams()
        self.model = WholeBodyModel()  # forward kinematics of the observed state (scratch)
        self._bs = self.DeclareVectorInputPort("body_state", BODY_STATE_SIZE)
        self._js = self.DeclareVectorInputPort("joint_state", JOINT_STATE_SIZE)
        self._pick_state = self.DeclareAbstractInputPort("pick_state",
                                                         AbstractValue.Make(PickState()))
        self.declare_sequencer(ValveMemory(r_pick=self.p.grasp_radius), self.p.period,
                               grasp=True)
        # The stages in the order an update tries them (one may hand over to the next).
        self._stages = ((Stage.WALK, self._walk), (Stage.APPROACH, self._approach),
                        (Stage.SETTLE, self._settle), (Stage.REACH, self._reach),
                        (Stage.PICK, self._pick), (Stage.TURN, self._turn),
                        (Stage.RELEASE, self._release), (Stage.RETRACT, self._retract),
                        (Stage.DONE, self._done))

    # ---- helpers -----------------------------------------------------------------------------
    @staticmethod
    def _go(m: ValveMemory, stage: Stage, t: float) -> None:
        m.stage = stage
        m.t_stage = t

    def _rim_point(self, m: ValveMemory, phi_A: float, r: float, dz: float) -> np.ndarray:
        """Point at angle phi_A (approach frame) and radius r about the axis, dz above c."""
        a = m.yaw_A + phi_A
        return self.center + np.array([r * math.cos(a), r * math.sin(a), dz])

    def _hand_angle(self, m: ValveMemory, p_WH: np.ndarray) -> float:
        """Angle of the hand about the valve axis in the approach frame [rad], within pi of
        ``angle_start_deg``."""
        d = p_WH - self.center
        ref = math.radians(self.p.angle_start_deg)
        a = math.atan2(d[1], d[0]) - m.yaw_A - ref
        return ref + math.atan2(math.sin(a), math.cos(a))

    # ---- the sequencer -----------------------------------------------------------------------
    def step(self, context, m: ValveMemory) -> None:
        t = context.get_time()
        p = self.p
        bs = self._bs.Eval(context)
        js = self._js.Eval(context)
        q, v = self.model.state_from_ports(js, bs)
        self.model.update(q, v)
        p_WB = bs[P_WB]
        now = Now(t, p_WB, yaw_from_quaternion(bs[QUAT_WB]), self.walker_standing(context),
                  t - m.t_stage, self._pick_state.Eval(context))
        m.pick = ""
        m.release = False
        c = self.center
        if m.stand is None:
            d = c[:2] - p_WB[:2]
            m.yaw_A = math.atan2(d[1], d[0])
            xy = c[:2] - p.stand_distance * np.array([math.cos(m.yaw_A), math.sin(m.yaw_A)])
            m.stand = np.array([xy[0], xy[1], m.yaw_A])
        for stage, run in self._stages:
            if m.stage == stage:
                run(m, now)

    def _walk(self, m: ValveMemory, now: Now) -> None:
        err = m.stand[:2] - now.p_WB[:2]
        if float(np.hypot(*err)) < self.p.approach_radius:
            self._go(m, Stage.APPROACH, now.t)
        else:
            m.cmd = goal_velocity(now.p_WB, now.yaw, m.stand[:2], self.goal_params)

    def _approach(self, m: ValveMemory, now: Now) -> None:
        p, yaw = self.p, now.yaw
        err_W = m.stand[:2] - now.p_WB[:2]
        e_yaw = math.atan2(math.sin(m.stand[2] - yaw), math.cos(m.stand[2] - yaw))
        cy, sy = math.cos(yaw), math.sin(yaw)
        ex, ey = cy * err_W[0] + sy * err_W[1], -sy * err_W[0] + cy * err_W[1]
        if (float(np.hypot(ex, ey)) < p.position_tolerance
                and abs(e_yaw) < math.radians(p.yaw_tolerance_deg)):
            m.cmd = np.zeros(3)
            self._go(m, Stage.SETTLE, now.t)
        else:
            s = p.approach_speed
            m.cmd = np.array([min(max(p.approach_gain * ex, -s), s),
                              min(max(p.approach_gain * ey, -s), s),
                              min(max(p.approach_yaw_gain * e_yaw, -0.4), 0.4)])

    def _settle(self, m: ValveMemory, now: Now) -> None:
        m.cmd = np.zeros(3)
        if not now.standing:
            m.t_stage = now.t
        elif now.elapsed >= self.p.settle_time:
            self._start_reach(m, now.t)

    def _reach(self, m: ValveMemory, now: Now) -> None:
        if self._follow_path(m, now.t):
            self._go(m, Stage.PICK, now.t)

    def _pick(self, m: ValveMemory, now: Now) -> None:
        p = self.p
        if now.pick.attached:
            p_WH = self.model.hand_point(self.HAND)[0]
            d = p_WH - self.center
            m.r_pick = float(np.hypot(d[0], d[1]))
            m.z_pick = float(d[2])
            m.phi_pick = self._hand_angle(m, p_WH)
            m.phi_now = m.phi_pick
            self._go(m, Stage.TURN, now.t)
        elif now.elapsed > p.pick_timeout:
            # Not in the volume: aim closer to the axis and lower, and try again.
            m.pick_tries += 1
            r = max(p.grasp_radius - 0.03 * m.pick_tries, 0.12)
            m.targets[self.HAND] = self._rim_point(
                m, math.radians(p.angle_start_deg), r, p.grasp_height - 0.01 * m.pick_tries)
            m.t_stage = now.t
        else:
            m.pick = "left_hand"

    def _turn(self, m: ValveMemory, now: Now) -> None:
        p = self.p
        if not now.pick.attached:
            self._go(m, Stage.PICK, now.t)  # lost the wheel: pick again where the hand is
            return
        end = math.radians(p.angle_end_deg)
        step = math.radians(p.turn_speed_deg) * p.period
        direction = 1.0 if end > m.phi_pick else -1.0
        m.phi_now += direction * step
        if direction * (m.phi_now - end) > 0:
            m.phi_now = end
        m.targets[self.HAND] = self._rim_point(m, m.phi_now, m.r_pick, m.z_pick)
        travelled = abs(self._hand_angle(m, self.model.hand_point(self.HAND)[0]) - m.phi_pick)
        if travelled >= math.radians(p.release_angle_deg) or (
                m.phi_now == end and now.elapsed > 30.0):
            self._go(m, Stage.RELEASE, now.t)

    def _release(self, m: ValveMemory, now: Now) -> None:
        m.release = True
        if not now.pick.attached and now.elapsed > self.p.hold_time:
            p_WH = self.model.hand_point(self.HAND)[0]
            up = p_WH + np.array([0.0, 0.0, 0.05])
            out = self._rim_point(m, self._hand_angle(m, p_WH), m.r_pick + 0.12, m.z_pick + 0.05)
            self._set_path(m, [up, out], now.t)
            self._go(m, Stage.RETRACT, now.t)

    def _retract(self, m: ValveMemory, now: Now) -> None:
        if self._follow_path(m, now.t):
            m.targets[self.HAND] = None
            self._go(m, Stage.DONE, now.t)

    @staticmethod
    def _done(m: ValveMemory, now: Now) -> None:
        m.cmd = np.zeros(3)

    def _start_reach(self, m: ValveMemory, t: float) -> None:
        p = self.p
        p_WH = self.model.hand_point(self.HAND)[0]
        rim_out = self.rim_radius + p.lift_clearance
        # Rise beside the wheel (outside its rim), then move over the grasp point.
        d = p_WH - self.center
        r_now = float(np.hypot(d[0], d[1]))
        rise_xy = p_WH[:2] if r_now > rim_out else (
            self.center[:2] + d[:2] * (rim_out / max(r_now, 1e-6)))
        rise = np.array([rise_xy[0], rise_xy[1], self.center[2] + p.grasp_height])
        grasp = self._rim_point(m, math.radians(p.angle_start_deg), p.grasp_radius,
                                p.grasp_height)
        self._set_path(m, [rise, grasp], t)
        self._go(m, Stage.REACH, t)

    def _set_path(self, m: ValveMemory, points: list, t: float) -> None:
        start = self.model.hand_point(self.HAND)[0].copy()
        m.path = [start] + [np.asarray(x, dtype=float) for x in points]
        m.path_t0 = t

    def _follow_path(self, m: ValveMemory, t: float) -> bool:
        """Move the hand target along the waypoints (``reach_time`` each, smooth); True when
        the last has been held for ``hold_time``."""
        T = self.p.reach_time
        m.targets[self.HAND], k = along_path(m.path, m.path_t0, t, T)
        return k >= len(m.path) - 1 + self.p.hold_time / T


class ValveAgent(Diagram):
    """Task 2 reference agent (see the module docstring).

    Input ports: ``joint_state``, ``body_state``, ``pick_state``. Output ports:
    ``legs_command``, ``arms_command`` (effort, from the whole-body QP), ``pick``,
    ``release``, ``velocity_command`` and ``stage`` (for plots).

    Args:
        priors: the task's priors; needs ``valve_center`` (x, y, z) in world [m].
        params: sequencer YAML (default params/agents/valve.yaml).
        goal_params: goal-planner YAML of the walk (default params/agents/goal_planner.yaml).
        walking_params: overrides of params/controllers/walking.yaml (default: none).
    """

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    def __init__(self, priors: dict[str, Any], params: str | None = None,
                 goal_params: str | None = None, walking_params: str | None = None):
        super().__init__()
        center = priors.get("valve_center")
        if center is None:
            raise ValueError(f"ValveAgent needs a 'valve_center' prior; got {sorted(priors)}")
        seq_params = ValveAgentParams.load(params)
        goal = GoalPlannerParams.load(goal_params)
        dims = priors.get("valve_dimensions") or {}
        rim_radius = 0.5 * float(dims.get("diameter", 0.54))
        build_sequencer_agent(self, ValveSequencer(center, rim_radius, seq_params, goal),
                              self.controller(priors, walking_params))

    @staticmethod
    def controller(priors: dict[str, Any], walking_params: str | None = None, **_):
        """The walking controller this agent drives, its arms in the QP (the command-level
        learning envs drive the same one); other parameter files are ignored."""
        from pr2_drake.controllers.walking import WalkingController
        from pr2_drake.controllers.walking_params import WalkingParams

        wparams = (WalkingParams.load(overrides=[walking_params]) if walking_params else None)
        return WalkingController(wparams, arms="effort")

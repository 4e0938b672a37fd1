"""Task 5 reference agent: climb the steps, cross the floor, press the button with a hand.

:class:`StepsButtonAgent` is a Diagram of a sequencer (:class:`StepsButtonSequencer`) and the
walking controller with the arms in the whole-body QP (``WalkingController(arms="effort")``),
footholds on treads (:class:`pr2_drake.controllers.planning.tread_steps.TreadFootstepPlanner`) and the
staircase as its terrain model (:func:`pr2_drake.controllers.planning.terrain.stairs_from_priors`),
with the stairs walking overrides (task 5's row: params/controllers/walking_stairs.yaml):

1. WALK: forward at ``walk_speed`` (at most ``stairs_speed`` over the steps) holding heading 0
   (+x, up the steps) and steering sideways onto the button's y, towards a standing point
   ``stand_distance`` before the button's face (:func:`walk_velocity`); the footstep planner
   puts every sole on a tread and steps to over each riser;
2. APPROACH: small steps (proportional velocity command) onto that point; then wait until the
   gait stands (SETTLE);
3. REACH: the right hand rises in front of the button (``pre_press`` before its face), then
   moves onto it, ``press_depth`` beyond the face (the hand sphere pushes on it);
4. PRESS: holds the target for ``hold_time`` (longer than the task's press time); then, if the
   hand sphere stopped more than ``press_tolerance`` short of the button's face (out of reach:
   the body stood too far back), the hand comes down, the standing point moves that much
   plus ``press_step`` nearer (at most ``press_max_shift`` in all) and APPROACH begins again,
   ``press_tries`` reaches in all;
5. DONE: keeps the hand on the button and stands.

Only the public observation (``body_state``, ``joint_state``) and the priors (``button_center``,
``step_height``, ``step_depth``, ``step_width``, ``step_count``, ``step_start_x``) are used.
Positions in m, world frame W; parameters: params/agents/steps_button.yaml.

(No ``from __future__ import annotations``: ``yaml_load_typed`` reads the field types.)
"""

import enum
import math
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
from pydrake.systems.framework import Diagram

from pr2_drake.agents.sequencer import (
    SequencerMemory,
    TaskSequencer,
    along_path,
    build_sequencer_agent,
)
from pr2_drake.agents.walk_to_goal import yaw_from_quaternion
from pr2_drake.params import Params
from pr2_drake.ports import BODY_STATE_SIZE, JOINT_STATE_SIZE, P_WB, QUAT_WB
from pr2_drake.robot.params import load_robot_params


@dataclass
class StepsButtonParams(Params):
    """See params/agents/steps_button.yaml (m, s, m/s)."""

    FILE: ClassVar[str] = "params/agents/steps_button.yaml"
    period: float = 0.02
    walk_speed: float = 0.25
    stairs_speed: float = 0.22
    stairs_lead: float = 0.6
    slow_radius: float = 0.4
    lateral_gain: float = 0.8
    max_lateral_speed: float = 0.08
    yaw_gain: float = 1.0
    stand_distance: float = 0.32
    approach_radius: float = 0.10
    approach_gain: float = 1.0
    approach_speed: float = 0.10
    position_tolerance: float = 0.03
    settle_time: float = 1.0
    hand: int = 1
    pre_press: float = 0.06
    press_depth: float = 0.02
    reach_time: float = 1.5
    hold_time: float = 1.0
    press_tolerance: float = 0.01
    press_step: float = 0.02
    press_max_shift: float = 0.10
    press_tries: int = 3



def walk_velocity(ex: float, ey: float, x: float, p: StepsButtonParams,
                  stairs_x: tuple[float, float] | None = None) -> tuple[float, float]:
    """WALK's command (vx, vy) [m/s] for the stand point's offset (ex, ey) [m] in the heading
    frame, the base at x [m] (W). Forward at ``walk_speed``, slowing within ``slow_radius``;
    past the stand point (ex < 0) it backs up to it, never on towards the post (a forward
    floor walked a robot that drifted sideways into the post and off the floor's end).
    Within ``stairs_x`` (the x span the agent slows over, see :class:`StepsButtonSequencer`)
    at most ``stairs_speed``: a faster CoM ran ahead of the short steps before a riser and a
    toe caught its nosing. Sideways: ``lateral_gain`` ey within ``max_lateral_speed``."""
    vx = (p.walk_speed * min(1.0, ex / p.slow_radius) if ex > 0.0
          else max(p.approach_gain * ex, -p.approach_speed))
    if stairs_x is not None and stairs_x[0] < x < stairs_x[1]:
        vx = min(vx, p.stairs_speed)
    vy = min(max(p.lateral_gain * ey, -p.max_lateral_speed), p.max_lateral_speed)
    return vx, vy


class Stage(enum.IntEnum):
    WALK = 0
    APPROACH = 1
    SETTLE = 2
    REACH = 3
    PRESS = 4
    DONE = 5


@dataclass
class StepsButtonMemory(SequencerMemory):
    """What the sequencer remembers (besides :class:`SequencerMemory`): the hand's path
    (waypoints in W [m], from ``path_t0`` [s]), the reaches made so far and how far [m] the
    standing point has moved towards the button since the first (a press out of reach)."""

    stage: int = Stage.WALK
    path: list = field(default_factory=list)
    path_t0: float = 0.0
    reaches: int = 0
    stand_shift: float = 0.0


class StepsButtonSequencer(TaskSequencer):
    """Stages of the task (see the module docstring).

    Inputs: ``body_state``, ``joint_state``, ``walker_status``. Outputs: ``velocity_command``
    (3), ``hand_targets`` ([left, right]), ``stage`` (1). Memory: :class:`StepsButtonMemory`.

    Args:
        button_center: p_W of the button's front face centre [m].
        params: the sequencer's parameters (default params/agents/steps_button.yaml).
        stairs_x: x of the first riser and of the last tread's end [m] (W): WALK is at most
            ``stairs_speed`` from ``stairs_lead`` before the first to the second (None: no cap).
    """

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    def __init__(self, button_center, params: StepsButtonParams | None = None,
                 stairs_x: tuple[float, float] | None = None):
        super().__init__()
        from pr2_drake.controllers.model import WholeBodyModel

        self.button = np.asarray(button_center, dtype=float).reshape(-1)
        if self.button.shape != (3,) or not np.all(np.isfinite(self.button)):
            raise ValueError(f"StepsButtonSequencer: button_center must be 3 finite values, "
                             f"got {button_center}")
        self.p = params or StepsButtonParams()
        self.model = WholeBodyModel()  # forward kinematics of the observed state (scratch)
        self.hand_radius = float(load_robot_params().raw["arms"]["hand_sphere"]["radius"])
        self.stand = np.array([self.button[0] - self.p.stand_distance, self.button[1]])
        # x span [m] where the forward command is at most stairs_speed: from stairs_lead
        # before the first riser to the end of the last tread (None: walk_speed throughout)
        self.stairs_x = None if stairs_x is None else (float(stairs_x[0]) - self.p.stairs_lead,
                                                      float(stairs_x[1]))
        self._bs = self.DeclareVectorInputPort("body_state", BODY_STATE_SIZE)
        self._js = self.DeclareVectorInputPort("joint_state", JOINT_STATE_SIZE)
        self.declare_sequencer(StepsButtonMemory(), self.p.period, grasp=False)

    def _stand_point(self, m: StepsButtonMemory) -> np.ndarray:
        """Where the soles' midpoint stands for the reach (xy, W) [m]: ``stand_distance``
        before the button's face, moved ``stand_shift`` towards it (heading 0: along +x)."""
        return self.stand + np.array([m.stand_shift, 0.0])

    def _soles_error(self, context, bs: np.ndarray, cy: float, sy: float,
                     m: StepsButtonMemory) -> tuple[float, float]:
        """Stand point minus the soles' midpoint (xy), in the heading frame [m]."""
        js = self._js.Eval(context)
        self.model.update(*self.model.state_from_ports(js, bs))
        mid = 0.5 * (self.model.sole_pose(0).translation()[:2]
                     + self.model.sole_pose(1).translation()[:2])
        err = self._stand_point(m) - mid
        return cy * err[0] + sy * err[1], -sy * err[0] + cy * err[1]

    @staticmethod
    def _go(m: StepsButtonMemory, stage: Stage, t: float) -> None:
        m.stage = stage
        m.t_stage = t

    def step(self, context, m: StepsButtonMemory) -> None:
        t = context.get_time()
        p = self.p
        bs = self._bs.Eval(context)
        p_WB = bs[P_WB]
        yaw = yaw_from_quaternion(bs[QUAT_WB])
        standing = self.walker_standing(context)
        err = self._stand_point(m) - p_WB[:2]
        cy, sy = math.cos(yaw), math.sin(yaw)
        ex, ey = cy * err[0] + sy * err[1], -sy * err[0] + cy * err[1]  # heading frame
        yaw_rate = min(max(-p.yaw_gain * yaw, -0.3), 0.3)  # hold heading 0 (up the steps)
        if m.stage == Stage.WALK:
            if math.hypot(ex, ey) < p.approach_radius:
                self._go(m, Stage.APPROACH, t)
            else:
                vx, vy = walk_velocity(ex, ey, float(p_WB[0]), p, self.stairs_x)
                m.cmd = np.array([vx, vy, yaw_rate])
        if m.stage == Stage.APPROACH:
            # Between the soles, not the base: the base sways a few cm sideways with every
            # step, more than the tolerance, and its error flipped the small steps back and
            # forth; the soles' midpoint moves only by the steps.
            ex, ey = self._soles_error(context, bs, cy, sy, m)
            if math.hypot(ex, ey) < p.position_tolerance:
                m.cmd = np.zeros(3)
                self._go(m, Stage.SETTLE, t)
            else:
                s = p.approach_speed
                m.cmd = np.array([min(max(p.approach_gain * ex, -s), s),
                                  min(max(p.approach_gain * ey, -s), s), yaw_rate])
        if m.stage == Stage.SETTLE:
            m.cmd = np.zeros(3)
            if not standing:
                m.t_stage = t
            elif t - m.t_stage >= p.settle_time:
                js = self._js.Eval(context)
                self.model.update(*self.model.state_from_ports(js, bs))
                start = self.model.hand_point(p.hand)[0].copy()
                front = self.button - np.array([p.pre_press, 0.0, 0.0])
                press = self.button + np.array([p.press_depth, 0.0, 0.0])
                m.path = [start, front, press]
                m.path_t0 = t
                m.reaches += 1
                self._go(m, Stage.REACH, t)
        if m.stage == Stage.REACH:
            m.targets[p.hand], k = along_path(m.path, m.path_t0, t, p.reach_time)
            if k >= len(m.path) - 1:
                self._go(m, Stage.PRESS, t)
        if m.stage == Stage.PRESS and t - m.t_stage >= p.hold_time:
            self._after_press(context, bs, m, t)

    def _after_press(self, context, bs: np.ndarray, m: StepsButtonMemory, t: float) -> None:
        """DONE, or, when the hand sphere stopped short of the button's face (see the module
        docstring, PRESS) and reaches are left, down with the hand and APPROACH a nearer point."""
        p = self.p
        js = self._js.Eval(context)
        self.model.update(*self.model.state_from_ports(js, bs))
        p_WH = self.model.hand_point(p.hand)[0]
        short = float(self.button[0] - p_WH[0]) - self.hand_radius  # [m] sphere to face (x)
        shift = min(m.stand_shift + short + p.press_step, p.press_max_shift)
        if short <= p.press_tolerance or m.reaches >= p.press_tries or shift <= m.stand_shift:
            self._go(m, Stage.DONE, t)
            return
        m.stand_shift = shift
        m.targets[p.hand] = None
        m.cmd = np.zeros(3)
        self._go(m, Stage.APPROACH, t)


class StepsButtonAgent(Diagram):
    """Task 5 reference agent (see the module docstring).

    Input ports: ``joint_state``, ``body_state``. Output ports: ``legs_command``,
    ``arms_command`` (effort, from the whole-body QP), ``velocity_command`` and ``stage``.

    Args:
        priors: the task's priors (see the module docstring).
        params: sequencer YAML (default params/agents/steps_button.yaml).
        walking_params: overrides of params/controllers/walking.yaml (task 5's row:
            params/controllers/walking_stairs.yaml).
    """

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    def __init__(self, priors: dict[str, Any], params: str | None = None,
                 walking_params: str | None = None):
        super().__init__()
        center = priors.get("button_center")
        if center is None:
            raise ValueError(f"StepsButtonAgent needs a 'button_center' prior; got "
                             f"{sorted(priors)}")
        seq_params = StepsButtonParams.load(params)
        stairs_x = None
        if all(k in priors for k in ("step_start_x", "step_depth", "step_count")):
            x0 = float(priors["step_start_x"])
            stairs_x = (x0, x0 + float(priors["step_depth"]) * int(priors["step_count"]))
        build_sequencer_agent(self, StepsButtonSequencer(center, seq_params, stairs_x),
                              self.controller(priors, walking_params))

    @staticmethod
    def controller(priors: dict[str, Any], walking_params: str | None = None, **_):
        """The walking controller this agent drives: the staircase from the priors as its
        terrain, footholds on the treads, the arms in the QP (the command-level learning envs
        drive the same one); other parameter files are ignored."""
        from pr2_drake.controllers.planning.terrain import stairs_from_priors
        from pr2_drake.controllers.planning.tread_steps import TreadFootstepPlanner
        from pr2_drake.controllers.walking import WalkingController
        from pr2_drake.controllers.walking_params import WalkingParams

        wparams = WalkingParams.load(overrides=[walking_params] if walking_params else [])
        terrain = stairs_from_priors(priors)
        footsteps = TreadFootstepPlanner(wparams.gait, wparams.limits.start_threshold, terrain)
        return WalkingController(wparams, footsteps=footsteps, terrain=terrain, arms="effort")

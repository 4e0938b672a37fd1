"""Task 5 reference agent: climb the steps, cross the floor, press the button with a hand.

:class:`StepsButtonAgent` is a Diagram of a sequencer (:class:`StepsButtonSequencer`) and the
walking controller with the arms in the whole-body QP (``WalkingController(arms="effort")``),
footholds on treads (:class:`pr2_drake.controllers.planning.tread_steps.TreadFootstepPlanner`) and the
staircase as its terrain model (:func:`pr2_drake.controllers.planning.terrain.stairs_from_priors`),
with the stairs walking overrides (task 5's row: params/controllers/walking_stairs.yaml):

1. WALK: forward at ``walk_speed`` holding heading 0 (+x, up the steps) and steering sideways
   onto the button's y, towards a standing point ``stand_distance`` before the button's face;
   the footstep planner puts every sole on a tread and steps to over each riser;
2. APPROACH: small steps (proportional velocity command) onto that point; then wait until the
   gait stands (SETTLE);
3. REACH: the right hand rises in front of the button (``pre_press`` before its face), then
   moves onto it, ``press_depth`` beyond the face (the hand sphere pushes on it);
4. PRESS: holds the target for ``hold_time`` (longer than the task's press time);
5. DONE: keeps the hand on the button and stands.

Only the public observation (``body_state``, ``joint_state``) and the priors (``button_center``,
``step_height``, ``step_depth``, ``step_width``, ``step_count``, ``step_start_x``) are used.
Positions in m, world frame W; parameters: params/agents/steps_button.yaml.

(No ``from __future__ import annotations``: ``yaml_load_typed`` reads the field types.)
"""

import enum
import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from pydrake.systems.framework import Diagram, DiagramBuilder

from pr2_drake.agents.sequencer import TaskSequencer
from pr2_drake.agents.walk_to_goal import yaw_from_quaternion
from pr2_drake.params import Params
from pr2_drake.ports import BODY_STATE_SIZE, JOINT_STATE_SIZE, P_WB, QUAT_WB


@dataclass
class StepsButtonParams(Params):
    """See params/agents/steps_button.yaml (m, s, m/s)."""

    FILE: ClassVar[str] = "params/agents/steps_button.yaml"
    period: float = 0.02
    walk_speed: float = 0.25
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



class Stage(enum.IntEnum):
    WALK = 0
    APPROACH = 1
    SETTLE = 2
    REACH = 3
    PRESS = 4
    DONE = 5


def _smooth(s: float) -> float:
    s = min(max(s, 0.0), 1.0)
    return s * s * (3.0 - 2.0 * s)


class StepsButtonSequencer(TaskSequencer):
    """Stages of the task (see the module docstring).

    Inputs: ``body_state``, ``joint_state``, ``walker_status``. Outputs: ``velocity_command``
    (3), ``hand_targets`` ([left, right]), ``stage`` (1).
    """

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    def __init__(self, button_center, params: StepsButtonParams | None = None):
        super().__init__()
        from pr2_drake.controllers.model import WholeBodyModel

        self.button = np.asarray(button_center, dtype=float).reshape(-1)
        if self.button.shape != (3,) or not np.all(np.isfinite(self.button)):
            raise ValueError(f"StepsButtonSequencer: button_center must be 3 finite values, "
                             f"got {button_center}")
        self.p = params or StepsButtonParams()
        self.model = WholeBodyModel()  # forward kinematics of the observed state
        self.stand = np.array([self.button[0] - self.p.stand_distance, self.button[1]])
        self._bs = self.DeclareVectorInputPort("body_state", BODY_STATE_SIZE)
        self._js = self.DeclareVectorInputPort("joint_state", JOINT_STATE_SIZE)
        self._status = self.DeclareVectorInputPort("walker_status", 6)
        self.DeclareDiscreteState(1)
        self.declare_command_outputs(grasp=False)
        self.DeclarePeriodicUnrestrictedUpdateEvent(self.p.period, 0.0, self._update)
        self.reset()

    def reset(self) -> None:
        self.stage = Stage.WALK
        self.t_stage = 0.0
        self.cmd = np.zeros(3)
        self.targets: list = [None, None]
        self.path: list = []
        self.path_t0 = 0.0
        self.t_last = -1.0

    def _go(self, stage: Stage, t: float) -> None:
        self.stage = stage
        self.t_stage = t

    def _update(self, context, state) -> None:
        t = context.get_time()
        if t < self.t_last - 1e-9:
            self.reset()
        self.t_last = t
        p = self.p
        bs = self._bs.Eval(context)
        p_WB = bs[P_WB]
        yaw = yaw_from_quaternion(bs[QUAT_WB])
        standing = int(self._status.Eval(context)[3]) == 0
        err = self.stand - p_WB[:2]
        cy, sy = math.cos(yaw), math.sin(yaw)
        ex, ey = cy * err[0] + sy * err[1], -sy * err[0] + cy * err[1]  # heading frame
        yaw_rate = min(max(-p.yaw_gain * yaw, -0.3), 0.3)  # hold heading 0 (up the steps)
        if self.stage == Stage.WALK:
            if math.hypot(ex, ey) < p.approach_radius:
                self._go(Stage.APPROACH, t)
            else:
                vx = p.walk_speed * min(1.0, max(ex, 0.0) / p.slow_radius)
                vy = min(max(p.lateral_gain * ey, -p.max_lateral_speed), p.max_lateral_speed)
                self.cmd = np.array([max(vx, 0.05), vy, yaw_rate])
        if self.stage == Stage.APPROACH:
            if math.hypot(ex, ey) < p.position_tolerance:
                self.cmd = np.zeros(3)
                self._go(Stage.SETTLE, t)
            else:
                s = p.approach_speed
                self.cmd = np.array([min(max(p.approach_gain * ex, -s), s),
                                     min(max(p.approach_gain * ey, -s), s), yaw_rate])
        if self.stage == Stage.SETTLE:
            self.cmd = np.zeros(3)
            if not standing:
                self.t_stage = t
            elif t - self.t_stage >= p.settle_time:
                js = self._js.Eval(context)
                self.model.update(*self.model.state_from_ports(js, bs))
                start = self.model.hand_point(p.hand)[0].copy()
                front = self.button - np.array([p.pre_press, 0.0, 0.0])
                press = self.button + np.array([p.press_depth, 0.0, 0.0])
                self.path = [start, front, press]
                self.path_t0 = t
                self._go(Stage.REACH, t)
        if self.stage == Stage.REACH:
            k = (t - self.path_t0) / p.reach_time
            seg = min(int(k), len(self.path) - 2)
            a, b = self.path[seg], self.path[seg + 1]
            self.targets[p.hand] = a + (b - a) * _smooth(k - seg)
            if k >= len(self.path) - 1:
                self._go(Stage.PRESS, t)
        if self.stage == Stage.PRESS and t - self.t_stage >= p.hold_time:
            self._go(Stage.DONE, t)
        state.get_mutable_discrete_state().get_mutable_vector(0).SetAtIndex(0, float(self.stage))


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
        from pr2_drake.controllers.planning.terrain import stairs_from_priors
        from pr2_drake.controllers.planning.tread_steps import TreadFootstepPlanner
        from pr2_drake.controllers.walking import WalkingController
        from pr2_drake.controllers.walking_params import WalkingParams

        center = priors.get("button_center")
        if center is None:
            raise ValueError(f"StepsButtonAgent needs a 'button_center' prior; got "
                             f"{sorted(priors)}")
        seq_params = StepsButtonParams.load(params)
        wparams = WalkingParams.load(overrides=[walking_params] if walking_params else [])
        terrain = stairs_from_priors(priors)
        footsteps = TreadFootstepPlanner(wparams.gait, wparams.limits.start_threshold, terrain)
        builder = DiagramBuilder()
        seq = builder.AddNamedSystem("sequencer", StepsButtonSequencer(center, seq_params))
        walker = builder.AddNamedSystem("walker", WalkingController(
            wparams, footsteps=footsteps, terrain=terrain, arms="effort"))
        js = builder.ExportInput(walker.GetInputPort("joint_state"), "joint_state")
        bs = builder.ExportInput(walker.GetInputPort("body_state"), "body_state")
        builder.ConnectInput(js, seq.GetInputPort("joint_state"))
        builder.ConnectInput(bs, seq.GetInputPort("body_state"))
        builder.Connect(walker.GetOutputPort("status"), seq.GetInputPort("walker_status"))
        builder.Connect(seq.GetOutputPort("velocity_command"),
                        walker.GetInputPort("velocity_command"))
        builder.Connect(seq.GetOutputPort("hand_targets"), walker.GetInputPort("hand_targets"))
        builder.ExportOutput(walker.GetOutputPort("legs_command"), "legs_command")
        builder.ExportOutput(walker.GetOutputPort("arms_command"), "arms_command")
        builder.ExportOutput(seq.GetOutputPort("velocity_command"), "velocity_command")
        builder.ExportOutput(seq.GetOutputPort("stage"), "stage")
        builder.BuildInto(self)

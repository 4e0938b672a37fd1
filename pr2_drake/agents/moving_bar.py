"""Task 3 reference agent: jump over the moving bar with the jump controller.

:class:`MovingBarAgent` is a Diagram of a jump timer (:class:`BarJumpPlanner`), the
:class:`pr2_drake.controllers.jumping.JumpController` (walking + jumps on one whole-body QP) and
the arm posture block, with the testbed's port names (``joint_state``, ``body_state``,
``task_feedback`` in; ``legs_command``, ``arms_command`` out).

The robot stands facing +x (across the bar's path: it never turns, which would take longer than
the bar gives). Once the bar moves (``bar_velocity`` in the feedback), the timer predicts when it
passes under each sole and sends one jump request (:func:`takeoff_time`): take-off time, apex
and a sideways velocity against the bar's motion, so that the bar sweeps under both soles within
the measured time window in which both soles are above the bar's top. Only the public
observation and feedback are used: ``body_state``, ``bar_position``, ``bar_velocity``.

Why sideways: facing across the path, the bar (0.05 m wide) must pass both soles, 0.22 m apart
(heel/toe spheres 0.02 m wide): about 0.29 m of relative travel. At 1 m/s that needs 0.29 s with
both soles above 0.06 m, more than the robot's highest reliable jump gives (about 0.26 s,
bench jumping); jumping at 0.4 m/s against the bar brings it to 0.21 s.

Parameters: params/agents/moving_bar.yaml (m, s). (No ``from __future__ import
annotations``: ``yaml_load_typed`` reads the field types.)
"""

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, Diagram, DiagramBuilder, LeafSystem

from pr2_drake.agents.walk_to_goal import yaw_from_quaternion
from pr2_drake.lifetime import weak_calc
from pr2_drake.params import Params
from pr2_drake.ports import BODY_STATE_SIZE, P_WB, QUAT_WB


@dataclass
class MovingBarParams(Params):
    """See params/agents/moving_bar.yaml."""

    FILE: ClassVar[str] = "params/agents/moving_bar.yaml"
    apex: float = 0.18
    lateral_speed: float = 0.4
    clear_from: float = 0.040
    clear_until: float = 0.318
    clearance_margin: float = 0.008
    band_margin: float = 0.005
    sole_half_width: float = 0.01
    hip_half_width: float = 0.11
    min_bar_speed: float = 0.5
    period: float = 0.02



@dataclass
class JumpTiming:
    """A planned jump over the bar: take-off time [s], jump velocity (W, xy) [m/s], and the
    spare time [s] of the soles-clear window over the bar's passage (split evenly before and
    after; negative: the jump cannot clear the bar)."""

    t_takeoff: float
    velocity_W: np.ndarray
    spare: float


def takeoff_time(t: float, soles_xy: np.ndarray, bar_xy: np.ndarray, bar_vel_xy: np.ndarray,
                 bar_width: float, p: MovingBarParams) -> JumpTiming:
    """When to take off so that the bar passes under both soles in the middle of the window in
    which both are above it.

    With d the bar's direction and s its speed, a sole at u = (p_sole - p_bar) . d (> 0: not yet
    reached) is under the bar while |u| < w (w = bar half width + sole half width + margin).
    The robot stands until take-off; after it, jumping at ``lateral_speed`` against d, the soles
    approach the bar at s_rel = s + lateral_speed. Both soles are above the bar from
    t_to + clear_from to t_to + clear_until. Centring the passage [first sole in, last sole out]
    in that window gives mean(u(t_to)) = s_rel (clear_from + clear_until) / 2.
    """
    s = float(np.hypot(*bar_vel_xy))
    d = np.asarray(bar_vel_xy, float) / s
    u0 = (np.asarray(soles_xy, float) - np.asarray(bar_xy, float)) @ d
    w = 0.5 * bar_width + p.sole_half_width + p.band_margin
    s_rel = s + p.lateral_speed
    mid = 0.5 * (p.clear_from + p.clear_until)
    t_to = t + (float(u0.mean()) - s_rel * mid) / s
    need = (float(u0.max() - u0.min()) + 2.0 * w) / s_rel
    return JumpTiming(t_to, -p.lateral_speed * d, (p.clear_until - p.clear_from) - need)


SAMPLES = 4  # bar positions the speed is measured from (three finite differences)


class BarJumpPlanner(LeafSystem):
    """``body_state`` and ``task_feedback`` in, ``jump_command`` (4) out: zeros until the bar
    moves, then one request (t_takeoff, vx, vy in the heading frame, apex), held. Its memory
    (the request, the bar's last positions) is discrete state."""

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    def __init__(self, bar_width: float, params: MovingBarParams | None = None):
        super().__init__()
        self.params = params or MovingBarParams.load()
        self.bar_width = float(bar_width)
        self._body = self.DeclareVectorInputPort("body_state", BODY_STATE_SIZE)
        self._fb = self.DeclareAbstractInputPort("task_feedback", AbstractValue.Make(dict()))
        self._cmd = self.DeclareDiscreteState(4)
        # The bar's last SAMPLES positions: (t [s], x, y [m]) each, oldest first, and how many.
        self._hist = self.DeclareDiscreteState(3 * SAMPLES + 1)
        self.DeclarePeriodicDiscreteUpdateEvent(self.params.period, 0.0, self._update)
        self.DeclareVectorOutputPort("jump_command", 4, weak_calc(self._calc),
                                     prerequisites_of_calc={self.discrete_state_ticket(
                                         self._cmd)})

    def _update(self, context, state) -> None:
        cmd = state.get_mutable_vector(self._cmd)
        if np.any(cmd.get_value()):
            return  # one request per episode
        fb = self._fb.Eval(context)
        t = context.get_time()
        v = np.asarray(fb.get("bar_velocity", np.zeros(3)), float)[:2]
        pos = np.asarray(fb.get("bar_position", np.zeros(3)), float)[:2]
        hist = self._samples(context) + [(t, pos)]
        del hist[:-SAMPLES]
        memory = np.zeros(3 * SAMPLES + 1)
        for k, (tk, pk) in enumerate(hist):
            memory[3 * k:3 * k + 3] = tk, pk[0], pk[1]
        memory[-1] = len(hist)
        state.get_mutable_vector(self._hist).SetFromVector(memory)
        if float(np.hypot(*v)) < self.params.min_bar_speed or len(hist) < SAMPLES:
            return
        # Wait for a steady speed: the bar's drive overshoots for a few tens of ms after it
        # starts, and the timing divides by the speed. Use the speed from positions (finite
        # differences over the last samples) once three agree within 1 %.
        fd = [(hist[k + 1][1] - hist[k][1]) / (hist[k + 1][0] - hist[k][0]) for k in range(3)]
        sp = [float(np.hypot(*f)) for f in fd]
        if max(sp) - min(sp) > 0.01 * max(sp):
            return
        v = fd[-1]
        body = self._body.Eval(context)
        yaw = yaw_from_quaternion(body[QUAT_WB])
        c, s = math.cos(yaw), math.sin(yaw)
        p = body[P_WB][:2]
        hw = self.params.hip_half_width
        soles = np.array([p + hw * np.array([-s, c]), p - hw * np.array([-s, c])])
        timing = takeoff_time(t, soles, pos, v, self.bar_width, self.params)
        v_H = np.array([c * timing.velocity_W[0] + s * timing.velocity_W[1],
                        -s * timing.velocity_W[0] + c * timing.velocity_W[1]])
        cmd.SetFromVector([timing.t_takeoff, v_H[0], v_H[1], self.params.apex])

    def _samples(self, context) -> list:
        """The bar's last positions in ``context``: [(t [s], p_xy [m])], oldest first."""
        h = context.get_discrete_state(self._hist).get_value()
        return [(float(h[3 * k]), h[3 * k + 1:3 * k + 3].copy()) for k in range(int(h[-1]))]

    def _calc(self, context, output: BasicVector) -> None:
        output.SetFromVector(context.get_discrete_state(self._cmd).get_value())


class MovingBarAgent(Diagram):
    """Jump timer + jump controller + arm posture (see the module docstring).

    Args:
        priors: the task's priors; ``bar_size`` (length, width, height) [m] gives the width.
        params: agent YAML (default params/agents/moving_bar.yaml).
        jump_params: overrides of params/controllers/jumping.yaml (task 3's row:
            params/controllers/jumping_bar.yaml, the jump the clear window was measured with).
    """

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    def __init__(self, priors: dict[str, Any] | None = None, params: str | None = None,
                 jump_params: str | None = None):
        super().__init__()
        from pr2_drake.controllers.posture import ArmPosture

        priors = priors or {}
        size = priors.get("bar_size", (2.0, 0.05, 0.05))
        p = MovingBarParams.load(params)
        builder = DiagramBuilder()
        timer = builder.AddNamedSystem("bar_jump_planner", BarJumpPlanner(float(size[1]), p))
        jumper = builder.AddNamedSystem("jumper", self.controller(priors, jump_params))
        arms = builder.AddNamedSystem("arm_posture", ArmPosture(
            stiffness=jumper.params.arm_stiffness, damping=jumper.params.arm_damping))
        builder.ExportInput(jumper.GetInputPort("joint_state"), "joint_state")
        body = builder.ExportInput(jumper.GetInputPort("body_state"), "body_state")
        builder.ConnectInput(body, timer.GetInputPort("body_state"))
        builder.ExportInput(timer.GetInputPort("task_feedback"), "task_feedback")
        builder.Connect(timer.GetOutputPort("jump_command"), jumper.GetInputPort("jump_command"))
        builder.ExportOutput(jumper.GetOutputPort("legs_command"), "legs_command")
        builder.ExportOutput(arms.GetOutputPort("arms_command"), "arms_command")
        builder.ExportOutput(jumper.GetOutputPort("jump_status"), "jump_status")
        builder.BuildInto(self)

    @staticmethod
    def controller(priors: dict[str, Any] | None = None, jump_params: str | None = None, **_):
        """The jump controller this agent drives (the command-level learning envs drive the
        same one); other parameter files are ignored."""
        from pr2_drake.controllers.jump_params import JumpParams
        from pr2_drake.controllers.jumping import JumpController

        jp = JumpParams.load(overrides=[jump_params] if jump_params else [])
        return JumpController(None, jp)

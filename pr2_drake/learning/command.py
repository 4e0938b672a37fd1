"""The command level: a policy acts through the built-in whole-body controllers.

:class:`CommandLevel` is a Diagram block with the testbed's port names: an ``action`` input
(a vector in [-1, 1], held between env steps) decoded by :class:`ActionDecoder` into the
commands of the controller the task's reference agent drives (its class method
``controller(priors, **agent_params)``, with the agent's parameter files from
tasks/registry.yaml: rough-terrain footholds on task 1, the slope on 4, treads on 5, the jump
controller on 3, the arms in the QP on 2, 5 and 6). What the action holds depends on that
controller and the scene (:class:`ActionLayout`; ranges in params/learning/command.yaml):

- ``walk`` (always): vx, vy, yaw rate in the heading frame, -1..1 scaled to the walking
  controller's limits (vx: +1 -> ``vx_max``, -1 -> ``vx_min``) times ``velocity_scale``;
- ``jump`` (the jump controller, task 3): trigger, delay, vx, vy, apex. A trigger going above 0
  while no jump is pending or under way requests one: take-off ``delay`` (0..``jump_delay_max``)
  after now, CoM velocity (vx, vy) (heading frame, capped at ``max_speed``), apex
  ``jump_apex_min``..``max_apex``;
- ``hands`` (the arms in the QP, tasks 2, 5, 6): per hand (left, right) on, x, y, z: on > 0
  sets the hand target at (x, y, z) in the heading frame H (origin at the base, x forward,
  z up; -1..1 -> ``hand_min``..``hand_max``), else the arm posture;
- ``grasp`` (a scene with graspables, tasks 2, 6): pick_left, pick_right, release: > 0 sends
  ``pick`` with that hand (left first) / ``release``.
"""

from dataclasses import dataclass, field
from typing import Any, ClassVar, List

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, Diagram, DiagramBuilder, LeafSystem

from pr2_drake.lifetime import weak_calc
from pr2_drake.params import Params
from pr2_drake.ports import BODY_STATE_SIZE, P_WB, QUAT_WB

PARTS = {
    "walk": ("vx", "vy", "yaw_rate"),
    "jump": ("jump_trigger", "jump_delay", "jump_vx", "jump_vy", "jump_apex"),
    "hands": ("left_on", "left_x", "left_y", "left_z", "right_on", "right_x", "right_y",
              "right_z"),
    "grasp": ("pick_left", "pick_right", "release"),
}


@dataclass
class CommandLevelParams(Params):
    """See params/learning/command.yaml (s, m)."""

    FILE: ClassVar[str] = "params/learning/command.yaml"
    control_dt: float = 0.1
    velocity_scale: float = 1.0
    hand_min: List[float] = field(default_factory=lambda: [-0.1, -0.6, -0.45])
    hand_max: List[float] = field(default_factory=lambda: [0.7, 0.6, 0.6])
    jump_delay_max: float = 1.0
    jump_apex_min: float = 0.05
    jump_status_period: float = 0.01

    def check(self) -> None:
        if not 0.0 < self.velocity_scale <= 1.0:
            raise ValueError(f"velocity_scale must be in (0, 1], got {self.velocity_scale}")
        if self.control_dt <= 0.0:
            raise ValueError(f"control_dt must be > 0 s, got {self.control_dt}")
        if np.any(np.asarray(self.hand_max) <= np.asarray(self.hand_min)):
            raise ValueError("hand_max must exceed hand_min in x, y and z")


@dataclass
class ActionLayout:
    """Which parts (:data:`PARTS`) an action holds, in order; ``names`` one per entry."""

    parts: tuple

    @property
    def names(self) -> tuple:
        return tuple(n for p in self.parts for n in PARTS[p])

    @property
    def size(self) -> int:
        return len(self.names)

    def slice(self, part: str) -> slice:
        start = 0
        for p in self.parts:
            if p == part:
                return slice(start, start + len(PARTS[p]))
            start += len(PARTS[p])
        raise KeyError(part)


def heading_rotation(body_state: np.ndarray) -> tuple[np.ndarray, float]:
    """(R_WH (3x3), yaw): the heading frame's rotation (the base's yaw only) [rad]."""
    w, x, y, z = body_state[QUAT_WB]
    yaw = float(np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z)))
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]), yaw


def _unit(a: float, lo: float, hi: float) -> float:
    """-1..1 -> lo..hi (clipped)."""
    a = min(max(float(a), -1.0), 1.0)
    return lo + 0.5 * (a + 1.0) * (hi - lo)


class ActionDecoder(LeafSystem):
    """``action`` (and ``body_state``, ``jump_status`` with a jump part) in; the controller's
    commands out: ``velocity_command`` (3), ``hand_targets`` ([left, right]), ``jump_command``
    (4), ``pick`` (str), ``release`` (bool), each where the layout has its part (see the
    module docstring). The jump request is discrete state: (last trigger, command (4))."""

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    def __init__(self, layout: ActionLayout, params: CommandLevelParams, walk_limits,
                 jump_limits: tuple[float, float] | None = None):
        super().__init__()
        self.layout, self.params = layout, params
        s = params.velocity_scale
        self._v_hi = s * np.array([walk_limits.vx_max, walk_limits.vy_max,
                                   walk_limits.yaw_rate_max])
        self._v_lo = s * np.array([-walk_limits.vx_min, walk_limits.vy_max,
                                   walk_limits.yaw_rate_max])
        self._jump_limits = jump_limits
        self._action = self.DeclareVectorInputPort("action", layout.size)
        self._body = self.DeclareVectorInputPort("body_state", BODY_STATE_SIZE)
        self.DeclareVectorOutputPort("velocity_command", 3, weak_calc(self._calc_velocity))
        parts = layout.parts
        if "hands" in parts:
            self.DeclareAbstractOutputPort("hand_targets", lambda: AbstractValue.Make([None, None]),
                                           weak_calc(self._calc_hands))
        if "grasp" in parts:
            self.DeclareAbstractOutputPort("pick", lambda: AbstractValue.Make(""),
                                           weak_calc(self._calc_pick))
            self.DeclareAbstractOutputPort("release", lambda: AbstractValue.Make(False),
                                           weak_calc(self._calc_release))
        if "jump" in parts:
            self._jump_status = self.DeclareVectorInputPort("jump_status", 6)
            self._jump = self.DeclareDiscreteState(5)
            self.DeclarePeriodicDiscreteUpdateEvent(params.jump_status_period, 0.0,
                                                    self._update_jump)
            self.DeclareVectorOutputPort(
                "jump_command", 4, weak_calc(self._calc_jump),
                prerequisites_of_calc={self.discrete_state_ticket(self._jump)})

    def _part(self, context, part: str) -> np.ndarray:
        return np.clip(self._action.Eval(context)[self.layout.slice(part)], -1.0, 1.0)

    def _calc_velocity(self, context, output: BasicVector) -> None:
        a = self._part(context, "walk")
        output.SetFromVector(np.where(a >= 0.0, a * self._v_hi, a * self._v_lo))

    def _calc_hands(self, context, output) -> None:
        a = self._part(context, "hands")
        body = self._body.Eval(context)
        R_WH, _ = heading_rotation(body)
        lo, hi = self.params.hand_min, self.params.hand_max
        targets = []
        for side in (0, 1):
            on, *xyz = a[4 * side:4 * side + 4]
            if on <= 0.0:
                targets.append(None)
                continue
            p_H = np.array([_unit(xyz[k], lo[k], hi[k]) for k in range(3)])
            targets.append(body[P_WB] + R_WH @ p_H)
        output.set_value(targets)

    def _calc_pick(self, context, output) -> None:
        a = self._part(context, "grasp")
        output.set_value("left_hand" if a[0] > 0.0 else "right_hand" if a[1] > 0.0 else "")

    def _calc_release(self, context, output) -> None:
        output.set_value(bool(self._part(context, "grasp")[2] > 0.0))

    def _update_jump(self, context, discrete_state) -> None:
        state = discrete_state.get_mutable_vector(self._jump)
        last, command = state.get_value()[0], state.get_value()[1:].copy()
        trigger, delay, vx, vy, apex = self._part(context, "jump")
        busy = not np.isnan(self._jump_status.Eval(context)[1])  # a take-off pending/active
        if trigger > 0.0 >= last and not busy:
            max_speed, max_apex = self._jump_limits
            v = np.array([vx, vy]) * max_speed
            n = float(np.hypot(*v))
            if n > max_speed:
                v *= max_speed / n
            command = np.array([context.get_time() + _unit(delay, 0.0, self.params.jump_delay_max),
                                v[0], v[1], _unit(apex, self.params.jump_apex_min, max_apex)])
        state.SetFromVector(np.concatenate([[trigger], command]))

    def _calc_jump(self, context, output: BasicVector) -> None:
        output.SetFromVector(context.get_discrete_state(self._jump).get_value()[1:])


def build_controller(task_entry, priors: dict[str, Any]):
    """The controller the task's reference agent drives (``controller`` of its class, with
    its registry row's parameter files)."""
    from pr2_drake.agents import load_agent_class

    cls = load_agent_class(task_entry.agent)
    make = getattr(cls, "controller", None)
    if make is None:
        raise ValueError(f"the agent {task_entry.agent} of task {task_entry.name} has no "
                         "controller(priors, **params) to drive at the command level")
    return make(priors, **task_entry.agent_params)


class CommandLevel(Diagram):
    """Action decoder + the task's controller (+ arm posture where the controller leaves the
    arms), with the testbed's port names.

    Input ports: ``action`` (:attr:`layout` size), ``joint_state``, ``body_state``,
    ``pick_state`` (the arms in the QP). Output ports: ``legs_command``, ``arms_command``,
    ``pick``, ``release`` (with a grasp part), ``velocity_command``.

    Args:
        task: the task (id or name).
        priors: the task's priors.
        graspables: whether the scene has objects to pick (adds the grasp part).
        params: the decoder's ranges (default params/learning/command.yaml).
    """

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    def __init__(self, task, priors: dict[str, Any], graspables: bool,
                 params: CommandLevelParams | None = None):
        super().__init__()
        from pr2_drake.controllers.jumping import JumpController
        from pr2_drake.controllers.posture import ArmPosture
        from pr2_drake.tasks import task_entry

        params = params or CommandLevelParams.load()
        controller = build_controller(task_entry(task), priors)
        jumps = isinstance(controller, JumpController)
        hands = controller.core.arms_driven
        parts = ("walk",) + (("jump",) if jumps else ()) + (("hands",) if hands else ()) + (
            ("grasp",) if graspables else ())
        self.layout = ActionLayout(parts)
        self.params = params
        jump_limits = ((controller.jump.params.max_speed, controller.jump.params.max_apex)
                       if jumps else None)
        builder = DiagramBuilder()
        decoder = builder.AddNamedSystem("decoder", ActionDecoder(
            self.layout, params, controller.params.limits, jump_limits))
        walker = builder.AddNamedSystem("controller", controller)
        builder.ExportInput(decoder.GetInputPort("action"), "action")
        body = builder.ExportInput(walker.GetInputPort("body_state"), "body_state")
        builder.ConnectInput(body, decoder.GetInputPort("body_state"))
        builder.ExportInput(walker.GetInputPort("joint_state"), "joint_state")
        builder.Connect(decoder.GetOutputPort("velocity_command"),
                        walker.GetInputPort("velocity_command"))
        if hands:
            builder.ExportInput(walker.GetInputPort("pick_state"), "pick_state")
            builder.Connect(decoder.GetOutputPort("hand_targets"),
                            walker.GetInputPort("hand_targets"))
            builder.ExportOutput(walker.GetOutputPort("arms_command"), "arms_command")
        else:
            arms = builder.AddNamedSystem("arm_posture", ArmPosture(
                stiffness=controller.params.arm_stiffness, damping=controller.params.arm_damping))
            builder.ExportOutput(arms.GetOutputPort("arms_command"), "arms_command")
        if jumps:
            builder.Connect(decoder.GetOutputPort("jump_command"),
                            walker.GetInputPort("jump_command"))
            builder.Connect(walker.GetOutputPort("jump_status"),
                            decoder.GetInputPort("jump_status"))
        builder.ExportOutput(walker.GetOutputPort("legs_command"), "legs_command")
        if graspables:
            builder.ExportOutput(decoder.GetOutputPort("pick"), "pick")
            builder.ExportOutput(decoder.GetOutputPort("release"), "release")
        builder.ExportOutput(decoder.GetOutputPort("velocity_command"), "velocity_command")
        builder.BuildInto(self)
        self.controller = controller

    def connect(self, builder: DiagramBuilder, testbed) -> None:
        """Connect this block (added to ``builder``) to the testbed by port name; ``action``
        stays free (the env fixes it; a policy block drives it)."""
        for i in range(self.num_input_ports()):
            name = self.get_input_port(i).get_name()
            if name != "action":
                builder.Connect(testbed.GetOutputPort(name), self.get_input_port(i))
        for i in range(self.num_output_ports()):
            name = self.get_output_port(i).get_name()
            if testbed.HasInputPort(name):
                builder.Connect(self.get_output_port(i), testbed.GetInputPort(name))

    def reset(self) -> None:
        """Forget the controller's memory kept outside the Context (its gait, QP warm start,
        jump planner): what a fresh build starts with."""
        self.controller.reset()

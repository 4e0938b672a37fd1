"""Reference agents for the walking tasks: steer the walking controller to the goal prior.

:class:`GoalVelocityPlanner` turns the base pose and a goal into a body velocity command: it
points the body at the goal, walks forward, slows down near it and stops inside it.
:class:`WalkToGoalAgent` is a Diagram of planner + :class:`WalkingController` + arm posture with
the testbed's port names, so ``pr2-drake run --task 1 --agent
pr2_drake.agents.walk_to_goal:WalkToGoalAgent`` wires it by name. It uses only the public
observation (``body_state``, ``joint_state``) and the task's ``goal_center`` prior.

Task reference agents (the defaults of ``pr2-drake run --task 1`` and ``--task 4``):

- :class:`RockyRoadAgent` (task 1): unknown stones: swing soles aim below the stance sole and
  touch down when their descent is blocked (contact inferred from kinematics), slower walking,
  steering along the line from its start to the goal (pure pursuit: a robot pushed or drifted
  sideways walks back to the line instead of on towards the goal from where it is), its arms
  swung by the walking QP rather than held (``arms="balance"``)
  (params/controllers/walking_rough.yaml, params/agents/goal_planner_rough.yaml).
- :class:`SlopeAgent` (task 4): footholds on the incline from the ``slope_angle_deg`` prior and
  the measured pitch of the stance sole, capped at the goal height; soles land pitched like the
  incline; the first step onto the ramp is caught as an early (blocked) touchdown
  (params/controllers/walking_slope.yaml).
"""


import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from pydrake.systems.framework import BasicVector, Diagram, DiagramBuilder, LeafSystem

from pr2_drake.lifetime import weak_calc
from pr2_drake.params import Params
from pr2_drake.ports import BODY_STATE_SIZE, P_WB, QUAT_WB


@dataclass
class GoalPlannerParams(Params):
    """Speeds in m/s and rad/s, distances in m, angles in rad."""

    FILE: ClassVar[str] = "params/agents/goal_planner.yaml"
    forward_speed: float = 0.25
    max_yaw_rate: float = 0.4
    yaw_gain: float = 1.2
    slow_radius: float = 0.5
    stop_radius: float = 0.12
    turn_in_place_angle: float = 0.6
    lateral_gain: float = 0.0
    max_lateral_speed: float = 0.08
    lookahead: float = 0.0  # [m] > 0: steer along the line from the start (pure pursuit)



def yaw_from_quaternion(q_wxyz: np.ndarray) -> float:
    """Heading [rad] of a body whose orientation is the unit quaternion (w, x, y, z)."""
    w, x, y, z = q_wxyz.tolist() if isinstance(q_wxyz, np.ndarray) else q_wxyz
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def pursuit_point(p_WB: np.ndarray, p_start: np.ndarray, p_goal: np.ndarray,
                  lookahead: float) -> np.ndarray:
    """The point [m] ``lookahead`` along the line from ``p_start`` to ``p_goal`` (xy, W) beyond
    the base's projection onto it; the goal itself once that passes the goal. (Scalar
    arithmetic: it runs at every control tick.)"""
    ax, ay = float(p_start[0]), float(p_start[1])
    bx, by = float(p_goal[0]), float(p_goal[1])
    ux, uy = bx - ax, by - ay
    length = math.hypot(ux, uy)
    if length < 1e-9:
        return np.array([bx, by])
    ux, uy = ux / length, uy / length
    s = (float(p_WB[0]) - ax) * ux + (float(p_WB[1]) - ay) * uy + lookahead
    if s >= length:
        return np.array([bx, by])
    s = max(s, 0.0)
    return np.array([ax + s * ux, ay + s * uy])


def goal_velocity(p_WB: np.ndarray, yaw: float, p_goal: np.ndarray,
                  params: GoalPlannerParams, p_start: np.ndarray | None = None) -> np.ndarray:
    """[vx, vy, yaw_rate] in the heading frame that takes the base at p_WB towards p_goal.

    With ``params.lookahead`` > 0 and a start ``p_start``, the body points at the pursuit point
    on the line from the start to the goal (:func:`pursuit_point`), so that a base that drifted
    off that line walks back to it within about a lookahead; the speed still follows the
    distance to the goal. (Scalar arithmetic: every agent calls it at the control rate.)"""
    px, py = float(p_WB[0]), float(p_WB[1])
    dx, dy = float(p_goal[0]) - px, float(p_goal[1]) - py
    dist = float(np.hypot(dx, dy))
    if dist < params.stop_radius:
        return np.zeros(3)
    if params.lookahead > 0.0 and p_start is not None:
        aim = pursuit_point(p_WB, p_start, p_goal, params.lookahead)
        dx, dy = float(aim[0]) - px, float(aim[1]) - py
    error = math.atan2(dy, dx) - yaw
    error = math.atan2(math.sin(error), math.cos(error))
    # (min/max: np.clip's values for these nonzero bounds, without its call overhead)
    yaw_rate = min(max(params.yaw_gain * error, -params.max_yaw_rate), params.max_yaw_rate)
    if abs(error) > params.turn_in_place_angle:
        return np.array([0.0, 0.0, yaw_rate])
    speed = params.forward_speed * min(1.0, dist / params.slow_radius)
    vx = speed * math.cos(error)
    lateral = dist * math.sin(error)
    vy = min(max(params.lateral_gain * lateral, -params.max_lateral_speed),
             params.max_lateral_speed)
    return np.array([max(0.0, vx), vy, yaw_rate])


class GoalVelocityPlanner(LeafSystem):
    """``body_state`` in, ``velocity_command`` (vx, vy, yaw rate) out, towards ``goal`` (x, y).

    With ``params.lookahead`` > 0 it steers along the line from where the base stood at the
    start (discrete state: [latched, x, y], latched at initialisation or at the first check,
    every ``LATCH_PERIOD``, that sees a valid body_state) to the goal."""

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    #: [s] how often the start is checked for until it is latched.
    LATCH_PERIOD = 0.05

    def __init__(self, goal, params: GoalPlannerParams | None = None):
        super().__init__()
        self.goal = np.asarray(goal, dtype=float)[:2]
        if self.goal.shape != (2,) or not np.all(np.isfinite(self.goal)):
            raise ValueError(f"GoalVelocityPlanner: goal must be finite (x, y), got {goal}")
        self.params = params or GoalPlannerParams()
        self._body = self.DeclareVectorInputPort("body_state", BODY_STATE_SIZE)
        self._start = None
        prerequisites = {self.all_input_ports_ticket()}
        if self.params.lookahead > 0.0:
            self._start = self.DeclareDiscreteState(3)
            self.DeclareInitializationDiscreteUpdateEvent(self._latch)
            self.DeclarePeriodicDiscreteUpdateEvent(self.LATCH_PERIOD, 0.0, self._latch)
            prerequisites.add(self.discrete_state_ticket(self._start))
        self.DeclareVectorOutputPort("velocity_command", 3, weak_calc(self._calc),
                                     prerequisites_of_calc=prerequisites)

    def _latch(self, context, discrete_state) -> None:
        start = discrete_state.get_mutable_vector(self._start)
        if start[0] > 0.5:
            return
        x = self._body.Eval(context)
        if np.all(np.isfinite(x)) and float(np.dot(x[QUAT_WB], x[QUAT_WB])) > 0.5:
            start.SetFromVector([1.0, float(x[P_WB][0]), float(x[P_WB][1])])

    def _calc(self, context, output: BasicVector) -> None:
        x = self._body.Eval(context)
        p_start = None
        if self._start is not None:
            start = context.get_discrete_state(self._start).get_value()
            if start[0] > 0.5:
                p_start = start[1:]
        output.SetFromVector(
            goal_velocity(x[P_WB], yaw_from_quaternion(x[QUAT_WB]), self.goal, self.params,
                          p_start)
        )


class WalkToGoalAgent(Diagram):
    """Planner + walking controller + arm posture, with the testbed's port names.

    Input ports: ``joint_state``, ``body_state``. Output ports: ``legs_command``,
    ``arms_command``, ``velocity_command`` (for plotting).

    Args:
        priors: the task's priors; needs ``goal_center`` (x, y[, z]) in world [m].
        params: goal-planner YAML (default params/agents/goal_planner.yaml).
        walking_params: overrides of params/controllers/walking.yaml (a partial YAML).

    The task agents' files are named in their task's registry row (tasks/registry.yaml).
    """

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    #: "position": the arms held by :class:`pr2_drake.controllers.posture.ArmPosture`;
    #: "balance": driven by the walking controller's QP (posture objective only).
    ARMS = "position"

    def __init__(self, priors: dict[str, Any], params: str | None = None,
                 walking_params: str | None = None):
        super().__init__()
        from pr2_drake.controllers.posture import ArmPosture

        goal = priors.get("goal_center", priors.get("goal"))
        if goal is None:
            raise ValueError(
                f"WalkToGoalAgent needs a 'goal_center' prior; the task gives {sorted(priors)}"
            )
        planner_params = GoalPlannerParams.load(params)
        builder = DiagramBuilder()
        planner = builder.AddNamedSystem("planner", GoalVelocityPlanner(goal, planner_params))
        walker = builder.AddNamedSystem("walker", self.controller(priors, walking_params,
                                                                  arms=self.ARMS))
        arms = walker if self.ARMS != "position" else builder.AddNamedSystem("arm_posture",
                                                                         ArmPosture())
        builder.ExportInput(walker.GetInputPort("joint_state"), "joint_state")
        body = builder.ExportInput(walker.GetInputPort("body_state"), "body_state")
        builder.ConnectInput(body, planner.GetInputPort("body_state"))
        builder.Connect(planner.GetOutputPort("velocity_command"),
                        walker.GetInputPort("velocity_command"))
        builder.ExportOutput(walker.GetOutputPort("legs_command"), "legs_command")
        builder.ExportOutput(arms.GetOutputPort("arms_command"), "arms_command")
        builder.ExportOutput(planner.GetOutputPort("velocity_command"), "velocity_command")
        builder.BuildInto(self)

    @classmethod
    def controller(cls, priors: dict[str, Any], walking_params: str | None = None,
                   arms: str = "position", **_):
        """The walking controller this agent steers (terrain from the priors, gains from
        ``walking_params``, ``arms`` as :attr:`ARMS`); the command-level learning envs drive
        the same one with the arms in position mode (:mod:`pr2_drake.learning.command`).
        Other parameter files are ignored."""
        from pr2_drake.controllers.walking import WalkingController
        from pr2_drake.controllers.walking_params import WalkingParams

        goal = priors.get("goal_center", priors.get("goal"))
        wparams = WalkingParams.load(overrides=[walking_params] if walking_params else [])
        terrain = cls.make_terrain(priors, np.asarray(goal, dtype=float))
        return WalkingController(wparams, terrain=terrain, arms=arms)

    @classmethod
    def make_terrain(cls, priors: dict[str, Any], goal: np.ndarray):
        """The walking controller's terrain model (None: flat, the controller's default)."""
        return None


class SlopeAgent(WalkToGoalAgent):
    """Task 4 reference agent: walks up an incline of known angle (``slope_angle_deg`` prior)
    to ``goal_center``. Footholds on the incline follow the plane the stance sole stands on,
    capped at the goal height (the plateau); swing soles land pitched like the incline."""

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    @classmethod
    def make_terrain(cls, priors, goal):
        from pr2_drake.controllers.planning.terrain import SlopeTerrain

        angle = priors.get("slope_angle_deg")
        if angle is None:
            raise ValueError(f"SlopeAgent needs a 'slope_angle_deg' prior; got {sorted(priors)}")
        z_top = float(goal[2]) if goal.shape[0] > 2 else np.inf
        return SlopeTerrain(math.radians(float(angle)), goal, z_top)


class RockyRoadAgent(WalkToGoalAgent):
    """Task 1 reference agent: walks over unknown low stones to ``goal_center``: higher, slower
    steps, touchdown detected from contact (a blocked swing sole) rather than the plan. The
    walking QP drives the arms, lightly held to their pose (``arms="balance"``; the weight in
    params/controllers/walking_rough.yaml), rather than a position-mode posture block."""

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    ARMS = "balance"

    #: [m] swing soles aim this far below the stance sole (stone heights vary by 2 cm).
    LANDING_DROP = 0.025

    @classmethod
    def make_terrain(cls, priors, goal):
        from pr2_drake.controllers.planning.terrain import RoughTerrain

        return RoughTerrain(cls.LANDING_DROP)

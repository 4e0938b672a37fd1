"""The actuation adapter: per-group joint commands -> plant actuation (Nm).

Position and velocity modes are spring-dampers computed here from the commanded stiffness and
damping (they are per-tick values in the PR2 action, so they cannot be the plant's fixed implicit
PD gains); effort mode passes torques through. Every torque is clamped to the joint's peak torque.

An explicit spring-damper is stable only while the gains suit the time step and the joint's
inertia: the adapter caps stiffness at ``I / dt^2`` and damping at ``I / dt`` per joint, with I
the smallest diagonal of the joint-space mass matrix seen at the nominal and zero poses, and
warns once per port when it caps a commanded gain.
"""

from __future__ import annotations

import warnings

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, LeafSystem

from pr2_drake.ports import JointGroupCommand, validate_command
from pr2_drake.robot.model import KuavoMaps
from pr2_drake.robot.params import GROUPS, RobotParams


class ActuationAdapter(LeafSystem):
    """Turns ``arms_command`` and ``legs_command`` into the robot's actuation vector.

    Input ports:
        arms_command, legs_command: :class:`JointGroupCommand` (abstract).
        robot_state: the robot model instance's state [q; v] from the plant.
    Output ports:
        actuation: torques [Nm] in the plant's actuator order for the robot instance.

    An unconnected command port means zero effort for that group.

    Args:
        params: robot parameters (effort limits, group sizes).
        maps: index maps of the robot instance (joint order, actuator order, sizes).
        default_gains: {group: (stiffness, damping)} used when a command carries none.
        gain_limits: {group: (max_stiffness, max_damping)} per-joint arrays (original order)
            that keep the explicit spring-damper stable; None = no cap.
    """

    def __init__(
        self,
        params: RobotParams,
        maps: KuavoMaps,
        default_gains: dict[str, tuple[float, float]],
        gain_limits: dict[str, tuple[np.ndarray, np.ndarray]] | None = None,
    ):
        super().__init__()
        self._groups = {}
        offset = 0
        for group, names in GROUPS.items():
            n = len(names)
            sl = slice(offset, offset + n)
            stiffness, damping = default_gains[group]
            k_max, d_max = (gain_limits or {}).get(group, (np.full(n, np.inf), np.full(n, np.inf)))
            self._groups[group] = dict(
                port=self.DeclareAbstractInputPort(
                    f"{group}_command", AbstractValue.Make(JointGroupCommand())
                ),
                q=maps.q_joints[sl],
                v=maps.nq + maps.v_joints[sl],
                act=maps.actuators[sl],
                limit=params.effort_limits(group),
                stiffness=np.minimum(float(stiffness), k_max),
                damping=np.minimum(float(damping), d_max),
                k_max=np.asarray(k_max, dtype=float),
                d_max=np.asarray(d_max, dtype=float),
                warned=False,
                n=n,
            )
            offset += n
        self._state_port = self.DeclareVectorInputPort("robot_state", maps.nq + maps.nv)
        self._n_act = len(maps.actuators)
        self.DeclareVectorOutputPort("actuation", self._n_act, self._calc_actuation)

    def _calc_actuation(self, context, output: BasicVector) -> None:
        x = self._state_port.Eval(context)
        tau = np.zeros(self._n_act)
        for group, g in self._groups.items():
            port = g["port"]
            if not port.HasValue(context):
                continue
            cmd = validate_command(port.get_name(), port.Eval(context), g["n"])
            tau[g["act"]] = np.clip(self.group_effort(cmd, x[g["q"]], x[g["v"]], g), -g["limit"],
                                    g["limit"])
        output.SetFromVector(tau)

    def group_effort(self, cmd: JointGroupCommand, q: np.ndarray, v: np.ndarray,
                     g: dict) -> np.ndarray:
        """Unclamped effort of one group [Nm] for its positions q [rad] and velocities v."""
        if cmd.mode == "effort":
            return np.asarray(cmd.values, dtype=float)
        damping = g["damping"] if cmd.damping is None else self._cap(g, cmd.damping, "d_max")
        if cmd.mode == "velocity":
            return damping * (cmd.values - v)
        stiffness = g["stiffness"] if cmd.stiffness is None else self._cap(g, cmd.stiffness, "k_max")
        return stiffness * (cmd.values - q) - damping * v

    @staticmethod
    def _cap(g: dict, gains: np.ndarray, limit: str) -> np.ndarray:
        capped = np.minimum(gains, g[limit])
        if not g["warned"] and np.any(capped < gains):
            g["warned"] = True
            name = "stiffness" if limit == "k_max" else "damping"
            warnings.warn(
                f"{g['port'].get_name()}: {name} {np.asarray(gains)} capped at "
                f"{np.round(g[limit], 1)} to keep the spring-damper stable at this time step",
                stacklevel=2,
            )
        return capped

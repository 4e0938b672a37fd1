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

from pr2_drake.lifetime import weak_calc
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
        effort_scale: clamp at this multiple of the peak torques (a domain randomisation's
            strongest motor, :mod:`pr2_drake.randomize_systems`; its own clamp follows).
    """

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    def __init__(
        self,
        params: RobotParams,
        maps: KuavoMaps,
        default_gains: dict[str, tuple[float, float]],
        gain_limits: dict[str, tuple[np.ndarray, np.ndarray]] | None = None,
        effort_scale: float = 1.0,
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
                limit=params.effort_limits(group) * effort_scale,
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
        self._tau = np.zeros(self._n_act)
        for g in self._groups.values():
            g["neg_limit"] = -g["limit"]
        self._group_list = list(self._groups.values())
        self._gains_cache = None
        self.DeclareVectorOutputPort("actuation", self._n_act, weak_calc(self._calc_actuation))

    def _calc_actuation(self, context, output: BasicVector) -> None:
        # Evaluated every physics step: effort-mode torques are clamped once per command
        # object (see _prepared) and the robot state is read only for position/velocity modes.
        x = None
        tau = self._tau
        tau.fill(0.0)
        for g in self._group_list:
            port = g["port"]
            if not port.HasValue(context):  # neither connected nor fixed: zero effort
                continue
            cmd = port.Eval(context)
            mode, values, stiffness, damping = self._prepared(cmd, g)
            if mode == "effort":
                tau[g["act"]] = g["cache"][2]
                continue
            if x is None:
                x = self._state_port.Eval(context)
            if mode == "velocity":
                effort = damping * (values - x[g["v"]])
            else:
                effort = stiffness * (values - x[g["q"]]) - damping * x[g["v"]]
            limit = g["limit"]
            np.minimum(effort, limit, out=effort)
            np.maximum(effort, g["neg_limit"], out=effort)
            tau[g["act"]] = effort
        output.SetFromVector(tau)

    def _prepared(self, cmd: JointGroupCommand, g: dict):
        """Validated command with its effective gains, recomputed only when the command
        object changes (Drake hands back the same object until the upstream value changes)."""
        cached = g.get("cache")
        if cached is not None and cached[0] is cmd:
            return cached[1]
        validate_command(g["port"].get_name(), cmd, g["n"])
        values = np.asarray(cmd.values, dtype=float)
        damping = g["damping"] if cmd.damping is None else self._cap(g, cmd.damping, "d_max")
        stiffness = (g["stiffness"] if cmd.stiffness is None
                     else self._cap(g, cmd.stiffness, "k_max"))
        prepared = (cmd.mode, values, stiffness, damping)
        effort = (np.clip(values, -g["limit"], g["limit"]) if cmd.mode == "effort" else None)
        g["cache"] = (cmd, prepared, effort)
        return prepared

    def group_effort(self, cmd: JointGroupCommand, q: np.ndarray, v: np.ndarray,
                     group: str) -> np.ndarray:
        """Clamped effort [Nm] of ``group`` for a command at positions q [rad] and
        velocities v [rad/s] (the law the adapter applies, for tests and tools)."""
        g = self._groups[group]
        mode, values, stiffness, damping = self._prepared(cmd, g)
        if mode == "effort":
            effort = values
        elif mode == "velocity":
            effort = damping * (values - v)
        else:
            effort = stiffness * (values - q) - damping * v
        return np.clip(effort, -g["limit"], g["limit"])

    def gains_in_effect(self, context) -> tuple[np.ndarray, np.ndarray]:
        """(stiffness [Nm/rad], damping [Nm s/rad]), each (18,): arms then legs in the
        original order, as the spring-damper applies them now: the group's current command's
        gains if it carries them, else the defaults, capped at the stable limits."""
        cmds = [g["port"].Eval(context) if g["port"].HasValue(context) else None
                for g in self._group_list]
        cached = self._gains_cache
        if cached is not None and all(a is b for a, b in zip(cached[0], cmds)):
            return cached[1].copy(), cached[2].copy()  # same command objects: same gains
        k, d = [], []
        for g, cmd in zip(self._group_list, cmds):
            stiffness, damping = g["stiffness"], g["damping"]
            if cmd is not None:
                _, _, stiffness, damping = self._prepared(cmd, g)
            k.append(np.broadcast_to(stiffness, (g["n"],)))
            d.append(np.broadcast_to(damping, (g["n"],)))
        self._gains_cache = (cmds, np.concatenate(k), np.concatenate(d))
        return self._gains_cache[1].copy(), self._gains_cache[2].copy()

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

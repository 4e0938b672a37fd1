"""The actuation adapter: per-group joint commands -> plant actuation (Nm).

Position and velocity modes are spring-dampers computed here from the commanded stiffness and
damping (they are per-tick values in the PR2 action, so they cannot be the plant's fixed implicit
PD gains); effort mode passes torques through. Every torque is clamped to the joint's peak torque.

An explicit spring-damper is stable only while the gains suit the time step and the joint's
inertia: the adapter caps stiffness at ``I / dt^2`` and damping at ``I / dt`` per joint, with I
the smallest diagonal of the joint-space mass matrix seen at the nominal and zero poses, and
warns once per port when it caps a commanded gain.

Where the work happens: the commands change at the control rate, the robot state at every
physics step. Everything that depends on the commands alone (validation, gains, targets, the
clamped efforts) is the ``actuation_law`` output, recomputed only when a command or the effort
limits change (:class:`ActuationLaw`). Only the spring-damper rows need the state at every step, so the
plant's actuation comes through a ``PortSwitch`` (:func:`add_actuation`, Drake's C++): while no
group is in position or velocity mode (walking controllers with the arms in their QP) it
forwards the cached efforts and no Python runs at the physics step; otherwise it forwards
``spring_actuation``, one vectorised line of numpy per step.

The effort limits (peak torques [Nm], 18 joints, arms then legs in the original order) are a
numeric parameter of the adapter's Context: :meth:`ActuationAdapter.effort_limits` and
:meth:`ActuationAdapter.set_effort_limits` (a domain randomisation can scale them per episode).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import (
    BasicVector,
    DiagramBuilder,
    InputPortIndex,
    LeafSystem,
    OutputPort,
)
from pydrake.systems.primitives import PortSwitch

from pr2_drake.lifetime import weak_calc
from pr2_drake.ports import JointGroupCommand, validate_command
from pr2_drake.robot.model import KuavoMaps
from pr2_drake.robot.params import GROUPS, RobotParams

#: ``actuation_source`` values: the PortSwitch input that carries the actuation (the switch's
#: input 0 is its selector; :func:`add_actuation` declares "effort" and "spring" after it).
EFFORT_SOURCE, SPRING_SOURCE = InputPortIndex(1), InputPortIndex(2)


@dataclass
class ActuationLaw:
    """What the current commands ask for, per actuator (the plant's actuator order).

    ``effort``: the clamped efforts of the groups in effort mode (zero in the other rows).
    The m rows ``rows`` in position or velocity mode get, at the state x,
    ``clamp(s[:m] + s[m:], -limit, limit)`` with ``s = gains * (target - x[qv])``: ``qv`` the
    state indices of their positions then velocities, ``target`` [q_d; v_d], ``gains``
    [stiffness; damping] (position rows: v_d = 0; velocity rows: stiffness 0).
    ``uses_state``: m > 0.
    """

    effort: np.ndarray
    rows: np.ndarray
    qv: np.ndarray
    target: np.ndarray
    gains: np.ndarray
    limit: np.ndarray
    neg_limit: np.ndarray

    @property
    def uses_state(self) -> bool:
        return len(self.rows) > 0


class ActuationAdapter(LeafSystem):
    """Turns ``arms_command`` and ``legs_command`` into the robot's actuation vector.

    Input ports:
        arms_command, legs_command: :class:`JointGroupCommand` (abstract).
        robot_state: the robot model instance's state [q; v] from the plant.
    Output ports (wire them with :func:`add_actuation`):
        effort_actuation: torques [Nm] in the plant's actuator order when no group needs the
            state (the clamped efforts; zero for unconnected groups); recomputed only when a
            command or the effort limits change.
        spring_actuation: the whole law, every group, at the current state.
        actuation_source: the PortSwitch input to use (:data:`EFFORT_SOURCE` or
            :data:`SPRING_SOURCE`).
        actuation_law: :class:`ActuationLaw`, what the commands ask for.

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
        limits = []
        for group, names in GROUPS.items():
            n = len(names)
            sl = slice(offset, offset + n)
            stiffness, damping = default_gains[group]
            k_max, d_max = (gain_limits or {}).get(group, (np.full(n, np.inf), np.full(n, np.inf)))
            self._groups[group] = dict(
                port=self.DeclareAbstractInputPort(
                    f"{group}_command", AbstractValue.Make(JointGroupCommand())
                ),
                joints=sl,
                act=maps.actuators[sl],
                stiffness=np.minimum(float(stiffness), k_max),
                damping=np.minimum(float(damping), d_max),
                k_max=np.asarray(k_max, dtype=float),
                d_max=np.asarray(d_max, dtype=float),
                limit=params.effort_limits(group) * effort_scale,
                warned=False,
                n=n,
            )
            limits.append(self._groups[group]["limit"])
            offset += n
        self._group_list = list(self._groups.values())
        self._actuators = np.asarray(maps.actuators)
        self._n_act = len(maps.actuators)
        # State indices per actuator: tau[a] acts on q[_q_of_act[a]], v[_v_of_act[a]].
        self._q_of_act = np.zeros(self._n_act, dtype=int)
        self._v_of_act = np.zeros(self._n_act, dtype=int)
        self._q_of_act[maps.actuators] = maps.q_joints
        self._v_of_act[maps.actuators] = maps.nq + maps.v_joints
        self._state_port = self.DeclareVectorInputPort("robot_state", maps.nq + maps.nv)
        self._limits = self.DeclareNumericParameter(BasicVector(np.concatenate(limits)))
        self._gains_cache = None
        self._springs_cache = None
        n_act = self._n_act
        none = np.zeros(0, dtype=int)
        empty = ActuationLaw(np.zeros(n_act), none, none, *(np.zeros(0) for _ in range(4)))
        # Computed when a command or the effort limits change, not at every physics step.
        self._law = self.DeclareAbstractOutputPort(
            "actuation_law", lambda: AbstractValue.Make(empty), weak_calc(self._calc_law),
            prerequisites_of_calc={g["port"].ticket() for g in self._group_list}
            | {self.all_parameters_ticket()})
        law_only = {self._law.cache_entry().ticket()}
        self.DeclareVectorOutputPort("effort_actuation", n_act, weak_calc(self._calc_effort),
                                     prerequisites_of_calc=law_only)
        self.DeclareVectorOutputPort("spring_actuation", n_act, weak_calc(self._calc_spring))
        self.DeclareAbstractOutputPort(
            "actuation_source", lambda: AbstractValue.Make(EFFORT_SOURCE),
            weak_calc(self._calc_source), prerequisites_of_calc=law_only)

    # -- effort limits (a Context parameter) --------------------------------------------------
    def effort_limits(self, context) -> np.ndarray:
        """Peak torques [Nm] in effect in ``context`` (this system's), 18: arms then legs."""
        return context.get_numeric_parameter(int(self._limits)).CopyToVector()

    def set_effort_limits(self, context, limits) -> None:
        """Set the peak torques [Nm] (18, arms then legs, positive) in ``context``."""
        limits = np.asarray(limits, dtype=float)
        if limits.shape != (self._n_act,) or not np.all(limits > 0) or not np.all(
                np.isfinite(limits)):
            raise ValueError(f"effort limits must be {self._n_act} positive finite values [Nm], "
                             f"got {limits}")
        context.get_mutable_numeric_parameter(int(self._limits)).SetFromVector(limits)

    # -- the law, once per command ------------------------------------------------------------
    def _calc_law(self, context, value: AbstractValue) -> None:
        limit = np.empty(self._n_act)
        limit[self._actuators] = self.effort_limits(context)
        ff = np.zeros(self._n_act)
        springs = []  # (group, command) of the groups in position or velocity mode
        for g in self._group_list:
            port = g["port"]
            if not port.HasValue(context):  # neither connected nor fixed: zero effort
                continue
            cmd = port.Eval(context)
            mode, values, _, _ = self._prepared(cmd, g)
            if mode == "effort":
                ff[g["act"]] = values
            else:
                springs.append((g, cmd))
        # np.clip(ff, -limit, limit) bit for bit, without np.clip's dispatch (zero in the
        # spring-damper rows).
        effort = np.minimum(np.maximum(ff, -limit), limit)
        value.set_value(ActuationLaw(effort, *self._spring_rows(springs, limit)))

    def _spring_rows(self, springs: list, limit: np.ndarray) -> tuple:
        """(rows, qv, target, gains, limit, neg_limit) of :class:`ActuationLaw` for the
        groups in position or velocity mode, rebuilt only when one of their commands or the
        limits change (a walking controller changes the legs' efforts every tick, while the
        arms' posture command stays the same object)."""
        cached = self._springs_cache
        key = limit.tobytes()
        if (cached is not None and cached[1] == key and len(cached[0]) == len(springs)
                and all(a is cmd for a, (_, cmd) in zip(cached[0], springs))):
            return cached[2]
        rows, qv_q, qv_v, q_d, v_d, k, d = [], [], [], [], [], [], []
        for g, cmd in springs:
            mode, values, stiffness, damping = self._prepared(cmd, g)
            act, n = g["act"], g["n"]
            rows.append(act)
            qv_q.append(self._q_of_act[act])
            qv_v.append(self._v_of_act[act])
            zero = np.zeros(n)
            velocity = mode == "velocity"
            q_d.append(zero if velocity else values)
            v_d.append(values if velocity else zero)
            k.append(zero if velocity else np.broadcast_to(stiffness, (n,)))
            d.append(np.broadcast_to(damping, (n,)))
        if rows:
            rows_ = np.concatenate(rows)
            law = (rows_, np.concatenate(qv_q + qv_v), np.concatenate(q_d + v_d),
                   np.concatenate(k + d), limit[rows_], -limit[rows_])
        else:
            none = np.zeros(0, dtype=int)
            law = (none, none, *(np.zeros(0) for _ in range(4)))
        # The command objects are kept, so an identity match is the same command.
        self._springs_cache = ([cmd for _, cmd in springs], key, law)
        return law

    def _calc_effort(self, context, output: BasicVector) -> None:
        output.SetFromVector(self._law.Eval(context).effort)

    def _calc_source(self, context, output) -> None:
        output.set_value(SPRING_SOURCE if self._law.Eval(context).uses_state else EFFORT_SOURCE)

    def _calc_spring(self, context, output: BasicVector) -> None:
        # Every physics step while a group is in position or velocity mode.
        law: ActuationLaw = self._law.Eval(context)
        s = law.target - self._state_port.Eval(context)[law.qv]
        s *= law.gains
        m = len(law.rows)
        tau_s = s[:m] + s[m:]  # stiffness (q_d - q) + damping (v_d - v)
        np.minimum(tau_s, law.limit, out=tau_s)
        np.maximum(tau_s, law.neg_limit, out=tau_s)
        tau = law.effort.copy()
        tau[law.rows] = tau_s
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
        g["cache"] = (cmd, prepared)
        return prepared

    def group_effort(self, cmd: JointGroupCommand, q: np.ndarray, v: np.ndarray,
                     group: str, limits: np.ndarray | None = None) -> np.ndarray:
        """Clamped effort [Nm] of ``group`` for a command at positions q [rad] and
        velocities v [rad/s] (the law the adapter applies, for tests and tools), with the
        group's peak torques ``limits`` (default: the model's)."""
        g = self._groups[group]
        limits = g["limit"] if limits is None else limits
        mode, values, stiffness, damping = self._prepared(cmd, g)
        if mode == "effort":
            effort = values
        elif mode == "velocity":
            effort = damping * (values - v)
        else:
            effort = stiffness * (values - q) - damping * v
        return np.clip(effort, -limits, limits)

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


def add_actuation(builder: DiagramBuilder, adapter: ActuationAdapter) -> OutputPort:
    """Add a PortSwitch (C++) that forwards ``adapter``'s (already in ``builder``) cached
    efforts or its per-step spring-damper; returns the switch's output, the plant's actuation
    [Nm] in its actuator order."""
    size = adapter.GetOutputPort("effort_actuation").size()
    switch = builder.AddNamedSystem("actuation_switch", PortSwitch(size))
    for name, index in (("effort", EFFORT_SOURCE), ("spring", SPRING_SOURCE)):
        port = switch.DeclareInputPort(name)
        assert port.get_index() == index, "PortSwitch's port order changed"
        builder.Connect(adapter.GetOutputPort(f"{name}_actuation"), port)
    builder.Connect(adapter.GetOutputPort("actuation_source"),
                    switch.get_port_selector_input_port())
    return switch.get_output_port()

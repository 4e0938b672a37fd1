"""The domain randomisation's blocks in the testbed, and where they are wired.

:class:`RandomizationBlocks` is made by the testbed from its config's ``randomize`` settings
(:mod:`pr2_drake.randomize`) and adds only the blocks of the kinds that are on; with
randomisation off every hook hands its port back unchanged, so the diagram is the one without
this module. The hooks (a line each in :mod:`pr2_drake.testbed`):

- :meth:`~RandomizationBlocks.command`: ``arms_command``/``legs_command`` go through a
  :class:`CommandDelay` (latency) before the actuation adapter;
- :attr:`~RandomizationBlocks.effort_scale` and :meth:`~RandomizationBlocks.actuation`: the
  adapter clamps at the strength range's upper end, then :class:`PeakTorque` at each joint's
  drawn peak torque (motor strength);
- :meth:`~RandomizationBlocks.observation`: ``joint_state``/``body_state`` pass an
  :class:`ObservationNoise` (noise);
- :meth:`~RandomizationBlocks.add_pushes`: :class:`BasePushes` on the plant's applied
  generalized force (summed with what a scene already feeds there, e.g. the valve's friction).

Every drawn value is a numeric parameter of these systems (set by
:func:`pr2_drake.randomize.apply_physics`); their only state is the delay's command history.
"""

from __future__ import annotations

import copy
import math
import weakref

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, DiagramBuilder, InputPort, LeafSystem, OutputPort
from pydrake.systems.primitives import Adder

from pr2_drake.lifetime import weak_calc
from pr2_drake.ports import QUAT_WB, JointGroupCommand
from pr2_drake.randomize import PUSH_HORIZON, RandomizeSettings, max_pushes, nominal_peaks

_NOISE_STREAMS = {"joint_state": 1, "body_state": 2}


class _History:
    """A command history, newest first. Stored commands are never changed, so a copy of the
    state (Drake copies abstract state at every update) shares them."""

    __slots__ = ("items",)

    def __init__(self, items: tuple = ()):
        self.items = items

    def __deepcopy__(self, memo) -> "_History":
        return _History(self.items)


class CommandDelay(LeafSystem):
    """Delays each joint group's command by ``steps`` physics steps (a numeric parameter,
    0..capacity): the output at step n is the input of step n - steps, the history filled
    with the input at initialization (the command held since before the episode).
    ``steps = 0`` passes the input through.

    Ports: ``<group>_command`` in and out (:class:`JointGroupCommand`) for each group; an
    unconnected input means zero effort, as at the actuation adapter.
    """

    __slots__ = ()

    def __init__(self, group_sizes: dict[str, int], period: float, capacity: int):
        super().__init__()
        self._capacity = max(int(capacity), 1)
        self._steps = self.DeclareNumericParameter(BasicVector([0.0]))
        self._groups = []
        for group, n in group_sizes.items():
            name = f"{group}_command"
            port = self.DeclareAbstractInputPort(name, AbstractValue.Make(JointGroupCommand()))
            state = self.DeclareAbstractState(AbstractValue.Make(_History()))
            zero = JointGroupCommand.effort(np.zeros(n))
            self._groups.append((port, state, zero))
            self.DeclareAbstractOutputPort(
                name, lambda: AbstractValue.Make(JointGroupCommand()),
                _weak_group_calc(self, len(self._groups) - 1))
        self.DeclarePeriodicUnrestrictedUpdateEvent(period, 0.0, self._update)
        self.DeclareInitializationUnrestrictedUpdateEvent(self._fill)

    def set_steps(self, context, steps: int) -> None:
        """Delay by ``steps`` physics steps in ``context`` (this system's)."""
        if not 0 <= steps <= self._capacity:
            raise ValueError(f"latency of {steps} steps is beyond the buffer's {self._capacity}")
        context.get_mutable_numeric_parameter(self._steps).SetAtIndex(0, float(steps))

    def _input(self, context, port, zero) -> JointGroupCommand:
        return port.Eval(context) if port.HasValue(context) else zero

    def _fill(self, context, state) -> None:
        for port, index, zero in self._groups:
            cmd = copy.deepcopy(self._input(context, port, zero))
            state.get_mutable_abstract_state(index).set_value(_History((cmd,) * self._capacity))

    def _update(self, context, state) -> None:
        keep = self._capacity
        for port, index, zero in self._groups:
            cmd = copy.deepcopy(self._input(context, port, zero))
            items = context.get_abstract_state(index).get_value().items
            state.get_mutable_abstract_state(index).set_value(_History((cmd,) + items[:keep - 1]))

    def _delayed(self, context, output, group: int) -> None:
        port, index, zero = self._groups[group]
        steps = int(context.get_numeric_parameter(self._steps).GetAtIndex(0))
        items = context.get_abstract_state(index).get_value().items
        if steps == 0 or not items:  # (no history before initialization)
            output.set_value(self._input(context, port, zero))
        else:
            output.set_value(items[steps - 1])



def _weak_group_calc(delay: CommandDelay, group: int):
    """The output calc of one group's delayed command, holding its system weakly (see
    :func:`pr2_drake.lifetime.weak_calc`)."""
    ref = weakref.ref(delay)

    def calc(context, output):
        ref()._delayed(context, output, group)

    return calc


class PeakTorque(LeafSystem):
    """Clamps each actuation torque to +-its peak (a numeric parameter, [Nm], actuator order).

    Ports: ``actuation`` in, ``actuation`` out (the plant's actuator order)."""

    __slots__ = ()

    def __init__(self, peaks: np.ndarray):
        super().__init__()
        n = len(peaks)
        self._u = self.DeclareVectorInputPort("actuation", n)
        self.DeclareNumericParameter(BasicVector(np.asarray(peaks, float)))
        self.DeclareVectorOutputPort("actuation", n, weak_calc(self._calc))

    def set_peaks(self, context, peaks: np.ndarray) -> None:
        context.get_mutable_numeric_parameter(0).SetFromVector(np.asarray(peaks, float))

    def _calc(self, context, output) -> None:
        peak = context.get_numeric_parameter(0).value()
        output.SetFromVector(np.clip(self._u.Eval(context), -peak, peak))


class ObservationNoise(LeafSystem):
    """Adds white Gaussian noise (standard deviations ``sigma``, per entry) to a vector,
    fresh at each physics step k = round(t / period): the noise of step k is drawn from a
    counter-based generator (Philox) keyed by the ``key`` parameter (two 32-bit halves) and
    counter (k, stream), so it is a function of the Context alone, whoever reads it and how
    often. With ``quaternion`` (the index of a unit quaternion w, x, y, z in the vector), the
    quaternion is instead turned by a rotation vector of deviation ``orientation_sigma`` [rad]
    (body frame), drawn from the draws of its first three entries.

    Ports: ``clean`` in, ``noisy`` out.
    """

    __slots__ = ()

    def __init__(self, sigma: np.ndarray, period: float, stream: int,
                 quaternion: int | None = None, orientation_sigma: float = 0.0):
        super().__init__()
        self._sigma = np.asarray(sigma, float)
        n = len(self._sigma)
        self._period, self._stream = float(period), int(stream)
        self._quat, self._sigma_r = quaternion, float(orientation_sigma)
        self._scratch: list = []  # a kept generator, fully reset before each draw (_normals)
        self.DeclareNumericParameter(BasicVector([0.0, 0.0]))
        self._x = self.DeclareVectorInputPort("clean", n)
        self.DeclareVectorOutputPort("noisy", n, weak_calc(self._calc))

    def set_key(self, context, key: tuple[int, int]) -> None:
        context.get_mutable_numeric_parameter(0).SetFromVector([float(key[0]), float(key[1])])

    def _calc(self, context, output) -> None:
        hi, lo = context.get_numeric_parameter(0).value()
        k = int(round(context.get_time() / self._period))
        draws = _normals(self._scratch, (int(hi) << 32) | int(lo), (k, self._stream),
                         len(self._sigma))
        x = self._x.Eval(context)
        y = x + self._sigma * draws
        if self._quat is not None:
            i = self._quat
            y[i:i + 4] = _turned(x[i:i + 4], self._sigma_r * draws[i:i + 3])
        output.SetFromVector(y)


def _normals(scratch: list, key: int, counter: tuple[int, int], n: int) -> np.ndarray:
    """n standard normals from Philox(key, counter): the same as a fresh
    ``Generator(Philox(key=key, counter=[*counter, 0, 0]))`` would draw, by resetting a
    kept generator's whole state (twice as fast as making one)."""
    if not scratch or scratch[0] != key:
        bits = np.random.Philox(key=key)
        scratch[:] = [key, bits, np.random.Generator(bits)]
    bits = scratch[1]
    state = bits.state
    state["state"]["counter"][:] = (counter[0], counter[1], 0, 0)
    state["buffer_pos"], state["has_uint32"], state["uinteger"] = 4, 0, 0
    bits.state = state
    return scratch[2].standard_normal(n)


def _turned(q: np.ndarray, r: np.ndarray) -> np.ndarray:
    """The unit quaternion q (w, x, y, z) composed with the rotation vector r [rad] (body)."""
    rx, ry, rz = float(r[0]), float(r[1]), float(r[2])
    angle = math.sqrt(rx * rx + ry * ry + rz * rz)
    if angle == 0.0:
        return np.array(q, float)
    c, s = math.cos(angle / 2), math.sin(angle / 2) / angle
    bx, by, bz = s * rx, s * ry, s * rz
    w, x, y, z = (float(v) for v in q)
    out = np.array([w * c - x * bx - y * by - z * bz,
                    w * bx + x * c + y * bz - z * by,
                    w * by - x * bz + y * c + z * bx,
                    w * bz + x * by - y * bx + z * c])
    return out / math.sqrt(float(out @ out))


class BasePushes(LeafSystem):
    """Horizontal pushes on the robot's base: generalized forces at the floating base's
    translational velocities (a force at the base frame's origin, world frame).

    The schedule is a numeric parameter of ``capacity`` rows (start [s], duration [s], fx [N],
    fy [N]), in time order; unused rows start at +inf. A push acts on the physics steps whose
    time t satisfies start <= t < start + duration.

    Ports: ``generalized_force`` out (the plant's nv).
    """

    __slots__ = ()

    def __init__(self, nv: int, v_force: np.ndarray, capacity: int):
        super().__init__()
        self._nv, self._v = int(nv), np.asarray(v_force, int)[:2]
        self._capacity = int(capacity)
        rows = np.zeros((self._capacity, 4))
        rows[:, 0] = np.inf
        self.DeclareNumericParameter(BasicVector(rows.ravel()))
        self.DeclareVectorOutputPort("generalized_force", self._nv, weak_calc(self._calc))

    def set_schedule(self, context, pushes) -> None:
        """Set the pushes (start, duration, fx, fy) in ``context`` (this system's)."""
        if len(pushes) > self._capacity:
            raise ValueError(f"{len(pushes)} pushes exceed the capacity of {self._capacity}")
        rows = np.zeros((self._capacity, 4))
        rows[:, 0] = np.inf
        if len(pushes):
            rows[:len(pushes)] = np.asarray(pushes, float)
        context.get_mutable_numeric_parameter(0).SetFromVector(rows.ravel())

    def _calc(self, context, output) -> None:
        rows = context.get_numeric_parameter(0).value()
        t = context.get_time()
        i = int(np.searchsorted(rows[0::4], t, side="right")) - 1
        f = np.zeros(self._nv)
        if i >= 0 and t < rows[4 * i] + rows[4 * i + 1]:
            f[self._v] = rows[4 * i + 2:4 * i + 4]
        output.SetFromVector(f)


class RandomizationBlocks:
    """Builds and finds the randomisation's blocks of one testbed (see the module docstring).

    Args:
        settings: the scenario's ``randomize`` section (None: off).
        time_step: the physics step [s] (the delay's and the noise's period).
        task: the task definition (None: flat ground); its time limit is the longest episode
            the pushes' capacity covers (without one: :data:`pr2_drake.randomize.PUSH_HORIZON`).
    """

    def __init__(self, settings: RandomizeSettings | None, time_step: float, task=None):
        self.settings = settings or RandomizeSettings()
        self.time_step = float(time_step)
        limit = None if task is None else task.spec.time_limit
        self.push_horizon = PUSH_HORIZON if limit is None else float(limit)
        self.delay: CommandDelay | None = None
        self.peak: PeakTorque | None = None
        self.noise: dict[str, ObservationNoise] = {}
        self.pushes: BasePushes | None = None

    def on(self, kind: str) -> bool:
        return self.settings.on(kind)

    @property
    def effort_scale(self) -> float:
        """The actuation adapter's clamp, x the peak torques: the strength range's upper end
        (then :class:`PeakTorque` clamps at each drawn peak), else 1."""
        return float(self.settings.motor.strength[1]) if self.on("motor") else 1.0

    def raise_effort_limits(self, plant, robot) -> None:
        """Before ``plant.Finalize()``: raise the robot's actuator effort limits (where the
        plant clamps the actuation) by :attr:`effort_scale`, so a motor drawn stronger than
        nominal gets its torque (:class:`PeakTorque` clamps at the drawn peak)."""
        if not self.on("motor"):
            return
        from pr2_drake.robot.params import ARM_JOINTS, LEG_JOINTS

        for name in ARM_JOINTS + LEG_JOINTS:
            index = plant.GetJointActuatorByName(name, robot).index()
            actuator = plant.get_mutable_joint_actuator(index)
            actuator.set_effort_limit(actuator.effort_limit() * self.effort_scale)

    def command(self, builder: DiagramBuilder, adapter_input: InputPort) -> InputPort:
        """The port to export for a group's command: the delay's input, else the adapter's."""
        if not self.on("latency"):
            return adapter_input
        if self.delay is None:
            from pr2_drake.robot.params import GROUPS

            capacity = math.ceil(self.settings.latency.range[1] / self.time_step - 1e-9)
            self.delay = builder.AddNamedSystem("command_delay", CommandDelay(
                {g: len(names) for g, names in GROUPS.items()}, self.time_step, capacity))
        name = adapter_input.get_name()
        builder.Connect(self.delay.GetOutputPort(name), adapter_input)
        return self.delay.GetInputPort(name)

    def actuation(self, builder: DiagramBuilder, actuation: OutputPort, testbed) -> OutputPort:
        """The port to feed the plant's actuation: clamped at the drawn peak torques, else
        ``actuation`` itself."""
        if not self.on("motor"):
            return actuation
        self.peak = builder.AddNamedSystem("peak_torque", PeakTorque(nominal_peaks(testbed)))
        builder.Connect(actuation, self.peak.get_input_port())
        return self.peak.get_output_port()

    def observation(self, builder: DiagramBuilder, name: str, port: OutputPort) -> OutputPort:
        """The port to export as observation ``name``: noisy, else ``port`` itself."""
        if not self.on("noise"):
            return port
        n = self.settings.noise
        if name == "joint_state":
            size = port.size()
            sigma = np.zeros(size)
            n_joints = size // 3
            sigma[:n_joints] = n.joint_position
            sigma[n_joints:2 * n_joints] = n.joint_velocity
            system = ObservationNoise(sigma, self.time_step, _NOISE_STREAMS[name])
        else:
            sigma = np.concatenate([[n.base_position] * 3, [0.0] * 4,
                                    [n.base_linear_velocity] * 3, [n.base_angular_velocity] * 3])
            system = ObservationNoise(sigma, self.time_step, _NOISE_STREAMS[name],
                                      quaternion=QUAT_WB.start, orientation_sigma=n.base_orientation)
        self.noise[name] = builder.AddNamedSystem(f"{name}_noise", system)
        builder.Connect(port, self.noise[name].get_input_port())
        return self.noise[name].get_output_port()

    def add_pushes(self, builder: DiagramBuilder, testbed) -> None:
        """Add :class:`BasePushes` on the plant's applied generalized force input, acting at
        the floating base's translational velocities (a force at the base frame's origin,
        world frame)."""
        if not self.on("pushes"):
            return
        from pr2_drake.robot.model import BASE_BODY

        plant = testbed.plant
        base = plant.GetBodyByName(BASE_BODY, testbed.robot)
        v_force = base.floating_velocities_start_in_v() + np.arange(3, 6)
        capacity = max_pushes(self.settings.pushes, self.push_horizon)
        self.pushes = builder.AddNamedSystem("base_pushes", BasePushes(
            plant.num_velocities(), v_force, capacity))
        add_to_input(builder, plant.get_applied_generalized_force_input_port(),
                     self.pushes.get_output_port())


def add_to_input(builder: DiagramBuilder, port: InputPort, source: OutputPort) -> None:
    """Connect ``source`` to the vector input ``port``; where something already feeds it, feed
    the sum of both through an Adder instead."""
    if not builder.IsConnectedOrExported(port):
        builder.Connect(source, port)
        return
    key = (port.get_system(), port.get_index())
    system, index = builder.connection_map()[key]
    old = system.get_output_port(index)
    builder.Disconnect(old, port)
    adder = builder.AddNamedSystem(f"{port.get_name()}_sum", Adder(2, port.size()))
    builder.Connect(old, adder.get_input_port(0))
    builder.Connect(source, adder.get_input_port(1))
    builder.Connect(adder.get_output_port(), port)


"""Velocity sources for the walking controller: a fixed schedule, Meshcat sliders, a gamepad.

Each is a LeafSystem with one output port ``velocity_command`` (vx [m/s], vy [m/s],
yaw rate [rad/s], in the robot's heading frame), ready to wire to
:class:`pr2_drake.controllers.walking.WalkingController`.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
from pydrake.geometry import Meshcat
from pydrake.systems.framework import BasicVector, LeafSystem

from pr2_drake.lifetime import weak_calc

SLIDERS = (("vx [m/s]", -0.2, 0.35), ("vy [m/s]", -0.1, 0.1), ("yaw rate [rad/s]", -0.5, 0.5))


class VelocitySchedule(LeafSystem):
    """Piecewise-constant commands: ``[(t_start, vx, vy, yaw_rate), ...]`` sorted by time.

    Before the first entry the command is zero.
    """

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    def __init__(self, schedule: Sequence[Sequence[float]]):
        super().__init__()
        rows = np.asarray(schedule, dtype=float)
        if rows.ndim != 2 or rows.shape[1] != 4 or not np.all(np.isfinite(rows)):
            raise ValueError("VelocitySchedule: entries must be (t_start, vx, vy, yaw_rate)")
        if np.any(np.diff(rows[:, 0]) < 0):
            raise ValueError("VelocitySchedule: entries must be sorted by t_start")
        self._rows = rows
        self.DeclareVectorOutputPort("velocity_command", 3, weak_calc(self._calc))

    def _calc(self, context, output: BasicVector) -> None:
        k = np.searchsorted(self._rows[:, 0], context.get_time(), side="right") - 1
        output.SetFromVector(np.zeros(3) if k < 0 else self._rows[k, 1:])


class MeshcatVelocitySliders(LeafSystem):
    """Three Meshcat sliders (vx, vy, yaw rate) in the Meshcat control panel."""

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    def __init__(self, meshcat: Meshcat):
        super().__init__()
        self._meshcat = meshcat
        for name, lo, hi in SLIDERS:
            meshcat.AddSlider(name, lo, hi, 0.01, 0.0)
        self.DeclareVectorOutputPort("velocity_command", 3, weak_calc(self._calc))

    def _calc(self, context, output: BasicVector) -> None:
        output.SetFromVector([self._meshcat.GetSliderValue(name) for name, _, _ in SLIDERS])


class GamepadVelocity(LeafSystem):
    """A gamepad in the Meshcat browser tab: left stick drives, right stick turns.

    Press a button on the pad with the Meshcat tab focused to connect it; until then, and
    inside the dead zone, the command is zero.
    """

    __slots__ = ()  # pr2_drake.lifetime: keeps the diagram collectable

    def __init__(self, meshcat: Meshcat, max_command=(0.3, 0.1, 0.4), dead_zone: float = 0.1):
        super().__init__()
        self._meshcat = meshcat
        self._max = np.asarray(max_command, dtype=float)
        self._dead = float(dead_zone)
        self.DeclareVectorOutputPort("velocity_command", 3, weak_calc(self._calc))

    def _calc(self, context, output: BasicVector) -> None:
        pad = self._meshcat.GetGamepad()
        if pad.index is None or len(pad.axes) < 4:
            output.SetFromVector(np.zeros(3))
            return
        axes = np.asarray(pad.axes[:4], dtype=float)
        axes[np.abs(axes) < self._dead] = 0.0
        # Stick up is negative on most pads; left is negative.
        output.SetFromVector(self._max * np.array([-axes[1], -axes[0], -axes[2]]))

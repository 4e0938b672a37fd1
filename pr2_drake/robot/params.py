"""KUAVO robot parameters, read from models/kuavo/params.yaml.

The parameter file is the one source of truth for the robot: the URDF is generated from it
(:mod:`pr2_drake.robot.generate`) and the joint maps below are read from it, so the joint order
used on every port is the original platform's order.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
from pydrake.common.yaml import yaml_load_file

from pr2_drake.paths import data_path

ARM_JOINTS: tuple[str, ...] = (
    "l_shoulder_y", "l_shoulder_z", "l_shoulder_x", "l_elbow",
    "r_shoulder_y", "r_shoulder_z", "r_shoulder_x", "r_elbow",
)
LEG_JOINTS: tuple[str, ...] = (
    "l_hip_z", "l_hip_x", "l_hip_y", "l_knee", "l_ankle",
    "r_hip_z", "r_hip_x", "r_hip_y", "r_knee", "r_ankle",
)
GROUPS: dict[str, tuple[str, ...]] = {"arms": ARM_JOINTS, "legs": LEG_JOINTS}


@dataclass(frozen=True)
class JointSpec:
    """One actuated revolute joint. Angles in rad, effort in Nm, velocity in rad/s."""

    name: str
    group: str
    axis: tuple[float, float, float]  # in the parent frame, left-side convention
    lower: float
    upper: float
    effort: float
    velocity: float


@dataclass(frozen=True)
class RobotParams:
    """The parsed parameter file. ``raw`` keeps the YAML tree for the generator."""

    path: Path
    raw: dict[str, Any]
    joints: tuple[JointSpec, ...]

    @property
    def total_mass(self) -> float:
        return float(self.raw["total_mass"])

    @property
    def height(self) -> float:
        return float(self.raw["height"])

    def joint(self, name: str) -> JointSpec:
        for j in self.joints:
            if j.name == name:
                return j
        raise KeyError(f"unknown joint {name!r}; joints are {[j.name for j in self.joints]}")

    def group(self, group: str) -> tuple[JointSpec, ...]:
        if group not in GROUPS:
            raise ValueError(f"unknown joint group {group!r}; expected one of {list(GROUPS)}")
        return tuple(j for j in self.joints if j.group == group)

    def effort_limits(self, group: str) -> np.ndarray:
        return np.array([j.effort for j in self.group(group)])

    def position_limits(self, group: str) -> tuple[np.ndarray, np.ndarray]:
        js = self.group(group)
        return np.array([j.lower for j in js]), np.array([j.upper for j in js])

    def default_positions(self, group: str) -> np.ndarray:
        """Nominal standing pose of one group, in the original joint order [rad]."""
        pose = self.raw["default_pose"]["joints"]
        return np.array([float(pose[j.name]) for j in self.group(group)])


def load_robot_params(path: str | Path | None = None) -> RobotParams:
    """Read and check a KUAVO parameter file (default: the shipped models/kuavo/params.yaml)."""
    if path is None:
        return _default_params()
    return _load(Path(path))


@lru_cache(maxsize=1)
def _default_params() -> RobotParams:
    return _load(data_path("models", "kuavo", "params.yaml"))


def _load(path: Path) -> RobotParams:
    raw = yaml_load_file(str(path))
    joints = []
    for entry in raw["joints"]:
        joints.append(
            JointSpec(
                name=entry["name"],
                group=entry["group"],
                axis=tuple(float(a) for a in entry["axis"]),
                lower=math.radians(entry["lower_deg"]),
                upper=math.radians(entry["upper_deg"]),
                effort=float(entry["effort"]),
                velocity=float(entry["velocity"]),
            )
        )
    names = tuple(j.name for j in joints)
    expected = ARM_JOINTS + LEG_JOINTS
    if names != expected:
        raise ValueError(
            f"{path}: joints must be listed in the original order {expected}, got {names}"
        )
    for j in joints:
        if not j.lower < j.upper:
            raise ValueError(f"{path}: joint {j.name} has lower limit >= upper limit")
        if j.effort <= 0:
            raise ValueError(f"{path}: joint {j.name} needs a positive effort limit")
    missing = set(expected) - set(raw["default_pose"]["joints"])
    if missing:
        raise ValueError(f"{path}: default_pose lacks joints {sorted(missing)}")
    return RobotParams(path=path, raw=raw, joints=tuple(joints))

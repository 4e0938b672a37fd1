"""Planar rotations and headings shared by the planners and the tracking objectives.

Angles in rad, about the world's z axis (up) unless said; a heading (yaw) is measured from +x
towards +y.
"""

from __future__ import annotations

import math

import numpy as np


def rot_z(yaw: float) -> np.ndarray:
    """R_WA (3 x 3) of a frame A turned by ``yaw`` about z."""
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rot_y(angle: float) -> np.ndarray:
    """R_WA (3 x 3) of a frame A turned by ``angle`` about y: the numbers and the column-major
    layout of pydrake's ``RotationMatrix.MakeYRotation(angle).matrix()``, without its objects."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]], order="F")


def rot2(yaw: float) -> np.ndarray:
    """The 2 x 2 rotation by ``yaw`` in the xy plane."""
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s], [s, c]])


def yaw_of(R: np.ndarray) -> float:
    """Heading [rad] of a rotation matrix (its x axis projected on the xy plane)."""
    return float(np.arctan2(R[1, 0], R[0, 0]))


def wrap(angle: float) -> float:
    """``angle`` wrapped into [-pi, pi) [rad]."""
    return float((angle + np.pi) % (2 * np.pi) - np.pi)

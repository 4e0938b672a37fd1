"""The learning envs' observation: a dict of float32 vectors from the testbed's port values.

Keys (the flat form, :meth:`Observer.flatten`, concatenates them in this, alphabetical,
order, which is also gymnasium's ``FlattenObservation`` order):

- ``body`` (13): the base relative to the task's reference point R (the first of the priors
  ``goal_center``, ``valve_center``, ``button_center``, ``coffee_table_center``; else the
  world origin): p_B - p_R in world axes (3) [m], cos and sin of the heading (2), roll and
  pitch (2) [rad], the base's linear (3) [m/s] and angular (3) [rad/s] velocity in the heading
  frame H (origin at the base, x forward, z up);
- ``feedback`` (task-dependent, absent where a task has none): valve: valve angle [rad]
  (read from the plant: privileged), left and right hand holding (0/1); moving bar: the bar's
  position (3) [m] and velocity (3) [m/s] in H; slope: the slope angle [rad]; steps and button:
  riser height, tread depth [m], step count, distance along x from the base to the first
  riser [m]; object search: left and right hand holding (0/1);
- ``joints`` (54): the testbed's ``joint_state`` (positions, velocities, applied efforts; arms
  then legs, :mod:`pr2_drake.ports`);
- ``progress`` (2): score / max score, and simulated time / the episode's limit;
- ``target`` (3): R in the heading frame H [m] (where to go or reach);
- with the camera (``camera=True``): ``rgb`` (h, w, 3) uint8 and ``depth`` (h, w, 1) float32
  [m] (0 too near, :data:`DEPTH_MAX` beyond), the head camera's last frame downsized (not
  part of the flat form).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pr2_drake.ports import BODY_STATE_SIZE, JOINT_STATE_SIZE, P_WB, QUAT_WB, V_WB, W_WB

REFERENCE_PRIORS = ("goal_center", "valve_center", "button_center", "coffee_table_center")
DEPTH_MAX = 10.0  # [m] depth beyond this (or beyond the camera's range) reads this


def reference_point(priors: dict[str, Any]) -> np.ndarray:
    """The task's reference point R [m], world frame (see the module docstring)."""
    for key in REFERENCE_PRIORS:
        if priors.get(key) is not None:
            p = np.zeros(3)
            v = np.asarray(priors[key], dtype=float).reshape(-1)[:3]
            p[:v.size] = v
            return p
    return np.zeros(3)


def roll_pitch_yaw(q_wxyz: np.ndarray) -> np.ndarray:
    """(roll, pitch, yaw) [rad] of a unit quaternion (w, x, y, z), ZYX convention."""
    w, x, y, z = q_wxyz
    roll = np.arctan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2.0 * (w * y - z * x), -1.0, 1.0))
    yaw = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return np.array([roll, pitch, yaw])


def _holding(pick_state) -> np.ndarray:
    attached = bool(pick_state is not None and pick_state.attached)
    hand = pick_state.hand if attached else ""
    return np.array([hand == "left_hand", hand == "right_hand"], dtype=float)


def _valve(values, priors, p_WB, R_WH):
    return np.concatenate([[values["valve_angle"]], _holding(values.get("pick_state"))])


def _moving_bar(values, priors, p_WB, R_WH):
    fb = values.get("task_feedback") or {}
    p = np.asarray(fb.get("bar_position", np.zeros(3)), dtype=float)
    v = np.asarray(fb.get("bar_velocity", np.zeros(3)), dtype=float)
    return np.concatenate([R_WH.T @ (p - p_WB), R_WH.T @ v])


def _slope(values, priors, p_WB, R_WH):
    return np.array([np.radians(float(priors["slope_angle_deg"]))])


def _steps_button(values, priors, p_WB, R_WH):
    return np.array([priors["step_height"], priors["step_depth"], priors["step_count"],
                     priors["step_start_x"] - p_WB[0]], dtype=float)


def _object_search(values, priors, p_WB, R_WH):
    return _holding(values.get("pick_state"))


#: Per task (registry name): (size, f(values, priors, p_WB, R_WH) -> vector).
FEEDBACK = {"valve": (3, _valve), "moving_bar": (6, _moving_bar), "slope": (1, _slope),
            "steps_button": (4, _steps_button), "object_search": (2, _object_search)}


class Observer:
    """Builds the observation of one task (see the module docstring).

    Args:
        task_name: the task's registry name (None: flat ground).
        priors: the task's priors.
        camera_shape: (height, width) of the downsized camera images, or None (no camera).
    """

    def __init__(self, task_name: str | None, priors: dict[str, Any],
                 camera_shape: tuple[int, int] | None = None):
        self.priors = dict(priors)
        self.reference = reference_point(priors)
        self._feedback = FEEDBACK.get(task_name)
        self.camera_shape = camera_shape

    def shapes(self) -> dict[str, tuple]:
        """Each key's shape (float32; ``rgb`` uint8), in the flat form's order."""
        shapes = {"body": (13,)}
        if self._feedback is not None:
            shapes["feedback"] = (self._feedback[0],)
        shapes.update({"joints": (JOINT_STATE_SIZE,), "progress": (2,), "target": (3,)})
        if self.camera_shape is not None:
            h, w = self.camera_shape
            shapes.update({"depth": (h, w, 1), "rgb": (h, w, 3)})
        return dict(sorted(shapes.items()))

    def observe(self, values: dict[str, Any], progress: tuple[float, float]) -> dict[str, Any]:
        """The observation from port values (``joint_state``, ``body_state``; ``pick_state``,
        ``task_feedback``, ``rgbd`` where used; ``valve_angle`` on the valve task) and
        (score / max score, time / limit)."""
        body = np.asarray(values["body_state"], dtype=float)
        if body.shape != (BODY_STATE_SIZE,):
            raise ValueError(f"body_state must be {BODY_STATE_SIZE} values, got {body.shape}")
        p_WB = body[P_WB]
        roll, pitch, yaw = roll_pitch_yaw(body[QUAT_WB])
        c, s = np.cos(yaw), np.sin(yaw)
        R_WH = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        obs = {
            "body": np.concatenate([p_WB - self.reference, [c, s, roll, pitch],
                                    R_WH.T @ body[V_WB], R_WH.T @ body[W_WB]]),
            "joints": np.asarray(values["joint_state"], dtype=float),
            "progress": np.clip(np.asarray(progress, dtype=float), 0.0, 1.0),
            "target": R_WH.T @ (self.reference - p_WB),
        }
        if self._feedback is not None:
            obs["feedback"] = self._feedback[1](values, self.priors, p_WB, R_WH)
        out = {k: np.asarray(v, dtype=np.float32) for k, v in obs.items()}
        if self.camera_shape is not None:
            out.update(self._camera(values["rgbd"]))
        return dict(sorted(out.items()))

    def _camera(self, frame) -> dict[str, np.ndarray]:
        import cv2

        h, w = self.camera_shape
        rgb = cv2.resize(np.ascontiguousarray(frame.color[..., :3]), (w, h),
                         interpolation=cv2.INTER_AREA)
        depth = cv2.resize(np.asarray(frame.depth, dtype=np.float32).reshape(
            frame.depth.shape[0], frame.depth.shape[1]), (w, h), interpolation=cv2.INTER_NEAREST)
        depth = np.clip(np.nan_to_num(depth, nan=0.0, posinf=DEPTH_MAX, neginf=0.0), 0.0,
                        DEPTH_MAX)
        return {"rgb": rgb.astype(np.uint8), "depth": depth[..., None].astype(np.float32)}

    def flatten(self, obs: dict[str, Any]) -> np.ndarray:
        """The flat form: the vector keys (not the camera's) concatenated in key order."""
        return np.concatenate([np.asarray(obs[k], dtype=np.float32).reshape(-1)
                               for k in self.shapes() if k not in ("rgb", "depth")])

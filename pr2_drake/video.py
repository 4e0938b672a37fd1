"""Head-camera video: a block that writes the testbed's ``rgbd`` frames to an mp4 file."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import DiagramBuilder, LeafSystem

from pr2_drake.camera import CameraSettings, RgbdFrame

FOURCC = "mp4v"


def depth_to_color(depth: np.ndarray, z_near: float, z_far: float) -> np.ndarray:
    """HxW depth [m] as an HxWx3 RGB uint8 colour map (turbo on log depth from ``z_near``
    (red) to ``z_far`` (blue) [m]); pixels with no return (inf or 0) are black."""
    valid = np.isfinite(depth) & (depth > 0)
    t = np.zeros(depth.shape, np.float32)
    t[valid] = np.clip((np.log(depth[valid]) - np.log(z_near)) / np.log(z_far / z_near), 0, 1)
    rgb = cv2.applyColorMap((255 * (1 - t)).astype(np.uint8), cv2.COLORMAP_TURBO)[..., ::-1]
    rgb[~valid] = 0
    return np.ascontiguousarray(rgb)


class CameraRecorder(LeafSystem):
    """Writes one video frame per camera sample: colour, or colour | depth side by side.

    Input port ``rgbd`` (:class:`pr2_drake.camera.RgbdFrame`). The camera's sampler refreshes
    its frame at t = k / fps; this block writes at t = (k + 1/2) / fps, so every sample is
    written once: an episode of T seconds gives round(T * fps) frames, at ``fps`` frames per
    second of video (video time = simulated time). Call :meth:`close` when done.
    """

    __slots__ = ()  # see pr2_drake.lifetime: lets the collector free the diagram

    def __init__(self, path: str | Path, camera: CameraSettings, depth: bool = False):
        super().__init__()
        self.path = str(path)
        self.depth = depth
        self.z_range = (camera.z_near, min(camera.z_far, 10.0))
        self.size = (camera.width * (2 if depth else 1), camera.height)
        self.frames = 0
        self._writer = cv2.VideoWriter(self.path, cv2.VideoWriter_fourcc(*FOURCC),
                                       float(camera.fps), self.size)
        if not self._writer.isOpened():
            raise ValueError(f"--record-camera: cannot open a video writer for {self.path!r}")
        self._in = self.DeclareAbstractInputPort("rgbd", AbstractValue.Make(RgbdFrame()))
        period = 1.0 / camera.fps
        self.DeclarePeriodicPublishEvent(period, 0.5 * period, self._write)

    def _write(self, context) -> None:
        if self._writer is None:
            return
        frame: RgbdFrame = self._in.Eval(context)
        image = frame.color
        if self.depth:
            image = np.hstack([image, depth_to_color(frame.depth, *self.z_range)])
        if image.shape[1::-1] != self.size:
            return  # not sampled yet
        self._writer.write(cv2.cvtColor(image, cv2.COLOR_RGB2BGR))
        self.frames += 1

    def close(self) -> None:
        """Finish the file (idempotent)."""
        if self._writer is not None:
            self._writer.release()
            self._writer = None


def add_camera_recorder(builder: DiagramBuilder, testbed, path: str | Path,
                        depth: bool = False) -> CameraRecorder:
    """Add a :class:`CameraRecorder` fed by ``testbed``'s ``rgbd`` port (the camera must be on)."""
    if not testbed.camera.enabled:
        raise ValueError("--record-camera needs the head camera: use --camera on")
    # A video wants every sample: the camera ignores an agent's ``camera_capture``.
    testbed.GetSubsystemByName("head_camera_sampler").capture_always = True
    recorder = builder.AddNamedSystem("camera_recorder",
                                      CameraRecorder(path, testbed.camera, depth))
    builder.Connect(testbed.GetOutputPort("rgbd"), recorder.get_input_port())
    return recorder

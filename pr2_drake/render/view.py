"""What a render asks for (:class:`RenderRequest`) and where it looks from (:class:`CameraView`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


ENGINES = ("cycles", "vtk")
VIEWS = ("follow", "head")


@dataclass
class RenderRequest:
    """What to render.

    Attributes:
        view: ``follow`` (a third-person camera that frames the robot) or ``head`` (the head
            camera, with the episode's field of view).
        width, height: image size [pixels].
        engine: ``cycles`` (the path tracer, the ``[photoreal]`` extra) or ``vtk`` (Drake's
            raster, for comparison; the same framing).
        samples: path-traced samples per pixel; denoise: OpenImageDenoise on the result.
        quality: the raster preset (``low``, ``medium``, ``high``) of ``vtk``.
        f_stop: depth of field with this aperture, focused on the follow camera's aim or
            the head camera's centre pixel; None (the default): none.
    """

    view: str = "follow"
    width: int = 640
    height: int = 480
    engine: str = "cycles"
    samples: int = 64
    denoise: bool = True
    quality: str = "high"
    f_stop: float | None = None

    def validate(self) -> None:
        """Raise ValueError naming the first bad field."""
        if self.view not in VIEWS:
            raise ValueError(f"view must be one of {VIEWS}, got {self.view!r}")
        if self.engine not in ENGINES:
            raise ValueError(f"engine must be one of {ENGINES}, got {self.engine!r}")
        from pr2_drake.camera import CameraSettings

        CameraSettings(width=self.width, height=self.height, quality=self.quality).validate()
        if isinstance(self.samples, bool) or not isinstance(self.samples, int) \
                or not 1 <= self.samples <= 65536:
            raise ValueError(f"samples must be an integer in [1, 65536], got {self.samples!r}")
        if self.f_stop is not None and not (np.isfinite(self.f_stop) and self.f_stop > 0):
            raise ValueError(f"f-stop must be a positive number, got {self.f_stop!r}")


@dataclass(frozen=True)
class CameraView:
    """A pinhole camera.

    Attributes:
        X_WC: 4x4 pose of the camera in the world, Drake's camera convention (+z along the
            optical axis, +x right and +y down in the image).
        width, height: image size [pixels].
        fov_y_deg: vertical field of view [deg].
        focus_distance: [m] where depth of field is sharp (None: no depth of field).
        f_stop: aperture of the depth of field (with ``focus_distance``).
    """

    X_WC: np.ndarray
    width: int
    height: int
    fov_y_deg: float
    focus_distance: float | None = None
    f_stop: float = 2.8


def look_at_matrix(p_WEye, p_WTarget) -> np.ndarray:
    """X_WC (4x4) of a camera at ``p_WEye`` looking at ``p_WTarget``, world +z up in the
    image (see :func:`pr2_drake.viz.look_at`)."""
    from pr2_drake.viz import look_at

    return look_at(np.asarray(p_WEye, float), np.asarray(p_WTarget, float)).GetAsMatrix4()

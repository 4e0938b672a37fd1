"""Rendering recorded states: the views, the engines and the files they write.

A :class:`RenderRequest` says what to draw (view, size, engine, samples); :func:`render_frames`
poses the :class:`RenderRig` at each :class:`RecordedState` and hands each frame to a
:class:`FrameWriter` (PNG stills, the dataset's depth and masks, a video).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Callable, Iterable, Sequence

import cv2
import numpy as np

from pr2_drake.render.resim import RecordedState
from pr2_drake.render.rig import RasterImages, RenderRig
from pr2_drake.render.view import CameraView, RenderRequest

FOLLOW_SMOOTHING = 1.0  # [s] moving-average window of the follow camera's aim in a video


class Engine:
    """Colour images of a posed rig: the path tracer or the raster."""

    def __init__(self, rig: RenderRig, request: RenderRequest):
        self.rig, self.request = rig, request
        self._cycles = None
        if request.engine == "cycles":
            from pr2_drake.render.cycles import CyclesRenderer
            from pr2_drake.render.light import testbed_lighting
            from pr2_drake.render.scene import export_scene
            from pr2_drake.render.settings import path_tracing_settings

            settings = path_tracing_settings()
            scene = export_scene(rig.scene_graph, rig.sg_context, settings)
            self._cycles = CyclesRenderer(scene, settings, testbed_lighting(settings))

    def color(self, view: CameraView, raster: RasterImages | None = None) -> np.ndarray:
        """(H, W, 3) uint8 RGB of ``view`` at the rig's current state (``raster``: the
        rig's raster of it, if already made)."""
        if self._cycles is None:
            return (raster or self.rig.raster(view)).color
        from pr2_drake.render.scene import geometry_poses

        self._cycles.set_poses(geometry_poses(self.rig.scene_graph, self.rig.sg_context))
        return self._cycles.render(view, self.request.samples, self.request.denoise)


def follow_targets(rig: RenderRig, states: Sequence[RecordedState], window: float
                   ) -> list[np.ndarray]:
    """The follow camera's aim at each state, averaged over ``window`` [s] centred on it
    (0: as it is), so a video's camera does not sway with each step."""
    raw = []
    for s in states:
        rig.set_state(s.x)
        raw.append(rig.follow_target())
    raw = np.array(raw)
    if window <= 0 or len(states) < 2:
        return list(raw)
    t = np.array([s.time for s in states])
    return [raw[np.abs(t - ti) <= window / 2].mean(axis=0) for ti in t]


def views(rig: RenderRig, states: Sequence[RecordedState], request: RenderRequest,
          smoothing: float = 0.0) -> Iterable[tuple[RecordedState, CameraView]]:
    """Pose the rig at each state and yield (state, its camera view)."""
    targets = follow_targets(rig, states, smoothing) if request.view == "follow" else None
    for k, s in enumerate(states):
        rig.set_state(s.x)
        if request.view == "follow":
            view = rig.follow_view(request.width, request.height, targets[k])
            focus = float(np.linalg.norm(view.X_WC[:3, 3] - targets[k]))
        else:
            view = rig.head_view(request.width, request.height)
            focus = None
        if request.f_stop is not None:
            if focus is None:
                depth = rig.raster(view).depth
                centre = depth[request.height // 2, request.width // 2]
                focus = float(centre) if np.isfinite(centre) and centre > 0 else 2.0
            view = CameraView(view.X_WC, view.width, view.height, view.fov_y_deg, focus,
                              request.f_stop)
        yield s, view


class FrameWriter:
    """Writes frames into ``out``: ``color_NNNNN.png``; with ``dataset`` also
    ``depth_NNNNN.npy`` (float32 [m], the simulator's exact depth: inf where nothing is within
    range) and ``mask_NNNNN.png`` (uint8: 0 background, k the k-th object of ``objects``,
    from Drake's label image); and ``frames.json`` (time, camera pose X_WC, intrinsics, the
    objects, the episode's report)."""

    def __init__(self, out: Path, dataset: bool, objects: dict[str, int]):
        self.out, self.dataset = Path(out), dataset
        self.out.mkdir(parents=True, exist_ok=True)
        self.objects = objects  # name -> RenderLabel value
        self.index: list[dict] = []

    def write(self, state: RecordedState, view: CameraView, color: np.ndarray,
              raster: RasterImages | None) -> None:
        k = len(self.index)
        entry = {"index": k, "time": round(state.time, 6), "requested": state.requested,
                 "color": f"color_{k:05d}.png", "X_WC": np.round(view.X_WC, 9).tolist()}
        cv2.imwrite(str(self.out / entry["color"]), color[..., ::-1])
        if self.dataset and raster is not None:
            entry["depth"] = f"depth_{k:05d}.npy"
            np.save(self.out / entry["depth"], raster.depth.astype(np.float32))
            if self.objects:
                entry["mask"] = f"mask_{k:05d}.png"
                cv2.imwrite(str(self.out / entry["mask"]), object_mask(raster.label,
                                                                        self.objects))
        self.index.append(entry)

    def close(self, view: CameraView | None, report: dict) -> None:
        meta = {"frames": self.index, "report": report,
                "objects": {str(i + 1): name for i, name in enumerate(self.objects)}}
        if view is not None:
            meta["intrinsics"] = intrinsics(view)
        (self.out / "frames.json").write_text(json.dumps(meta, indent=1))


def object_mask(label: np.ndarray, objects: dict[str, int]) -> np.ndarray:
    """(H, W) uint8: k where Drake's label image shows the k-th object of ``objects`` (in
    its order, from 1), 0 elsewhere."""
    mask = np.zeros(label.shape, np.uint8)
    for k, value in enumerate(objects.values(), start=1):
        mask[label == value] = k
    return mask


def intrinsics(view: CameraView) -> dict:
    """The pinhole intrinsics of a view (Drake's CameraInfo): K (3x3), width, height."""
    from pydrake.systems.sensors import CameraInfo

    info = CameraInfo(view.width, view.height, np.radians(view.fov_y_deg))
    return {"width": view.width, "height": view.height, "fov_y_deg": view.fov_y_deg,
            "K": np.round(info.intrinsic_matrix(), 9).tolist()}


def render_frames(rig: RenderRig, states: Sequence[RecordedState], request: RenderRequest,
                  sinks: Sequence[Callable], dataset: bool = False, smoothing: float = 0.0,
                  progress=None) -> CameraView | None:
    """Render every state and pass (state, view, colour, raster or None) to each sink;
    the raster (depth, labels) is made only for a ``dataset``. Returns the last view."""
    engine = Engine(rig, request)
    view = None
    for n, (state, view) in enumerate(views(rig, states, request, smoothing), start=1):
        raster = rig.raster(view) if dataset or request.engine == "vtk" else None
        color = engine.color(view, raster)
        for sink in sinks:
            sink(state, view, color, raster)
        if progress is not None:
            print(f"  frame {n}/{len(states)}  t = {state.time:.3f} s", file=progress,
                  flush=True)
    return view

"""Find the task-6 objects in the head camera's colour + depth, and place them in world.

Pipeline (:class:`ObjectDetector`), all from one RGB-D frame and the camera pose X_WC:

1. back-project every pixel to a world point p_W (pinhole intrinsics of the head camera; the
   depth image holds the distance to the image plane, z in the camera frame C);
2. support planes: surface normals from the organised point cloud; horizontal pixels are
   histogrammed by height; peaks that are large in pixels and in world extent are planes (the
   floor, table tops); their pixels are removed;
3. clusters: connected components of what remains, split at depth edges; a cluster must stand
   on a plane (lowest point near the plane, plane pixels around it), rise a little above it and
   be small (walls, legs, table edges and large furniture are rejected);
4. features: height above the plane, top-down extents (minimum-area rectangle), a hue
   histogram (saturated pixels) with the share of grey pixels; each is compared with the nine
   object models of the priors (extents from their OBJ meshes, colours from the materials'
   diffuse hues, by face area): score = colour similarity - size mismatch;
5. position: the centre of the cluster's top-down rectangle, at the plane height plus the
   matched model's half height (the objects' frames sit at their bounding-box centres).

Colours are compared as hue ranges and grey shares, never as exact pixel values, so shading,
shadows, exposure and textures on the surroundings change little.

The camera pose comes from the robot's own state: :class:`HeadCameraKinematics` runs forward
kinematics on a plant holding the robot alone (body_state + joint_state), never the simulator.

Other detectors (learned, VLM) plug in through :class:`ObjectFinder`.
"""

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar, Optional, Protocol

import cv2
import numpy as np
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.sensors import CameraInfo

from pr2_drake.params import Params
from pr2_drake.paths import resolve_user_path
from pr2_drake.ports import P_WB, Q_ARMS, Q_LEGS, QUAT_WB

HUE_BINS = 18  # 20 deg each
SAT_MIN, VAL_MIN = 0.28, 0.12  # below: a grey pixel (no reliable hue)


# -- camera ------------------------------------------------------------------------------------
@dataclass(frozen=True)
class CameraIntrinsics:
    """Pinhole intrinsics [pixels] of an image ``width`` x ``height``."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float

    @staticmethod
    def from_fov(width: int, height: int, fov_y_deg: float) -> "CameraIntrinsics":
        """Drake's convention (CameraInfo from the vertical field of view)."""
        info = CameraInfo(int(width), int(height), math.radians(fov_y_deg))
        return CameraIntrinsics(int(width), int(height), info.focal_x(), info.focal_y(),
                                info.center_x(), info.center_y())

    @staticmethod
    def from_settings(settings) -> "CameraIntrinsics":
        """From a :class:`pr2_drake.camera.CameraSettings`."""
        return CameraIntrinsics.from_fov(settings.width, settings.height, settings.fov_y_deg)


class HeadCameraKinematics:
    """X_WC of the head camera from the robot's ``body_state`` and ``joint_state``, by forward
    kinematics on a plant that holds the robot alone (C: Drake camera frame, +z optical axis)."""

    def __init__(self, frame: str = "head_camera"):
        from pr2_drake.robot.model import KuavoMaps, add_kuavo

        plant = MultibodyPlant(0.0)
        robot = add_kuavo(plant)
        plant.Finalize()
        self._plant, self._robot = plant, robot
        self._maps = KuavoMaps.from_plant(plant, robot)
        self._frame = plant.GetFrameByName(frame, robot).index()
        self._context = plant.CreateDefaultContext()

    def camera_pose(self, body_state: np.ndarray, joint_state: np.ndarray) -> RigidTransform:
        """X_WC from body_state (13: p_WB, quat_WB w x y z, ...) and joint_state (54)."""
        body_state = np.asarray(body_state, float)
        joint_state = np.asarray(joint_state, float)
        q = np.zeros(self._maps.nq)
        quat = body_state[QUAT_WB]
        q[self._maps.q_base] = np.concatenate([quat / np.linalg.norm(quat), body_state[P_WB]])
        q[self._maps.q_joints] = np.concatenate([joint_state[Q_ARMS], joint_state[Q_LEGS]])
        self._plant.SetPositions(self._context, self._robot, q)
        return self._plant.get_frame(self._frame).CalcPoseInWorld(self._context)

    def camera_pose_from_obs(self, obs: dict) -> RigidTransform:
        """X_WC from a PR2 observation dictionary (``obs["agent"]``)."""
        from pr2_drake.observation import state_vectors

        joint_state, body_state = state_vectors(obs)
        return self.camera_pose(body_state, joint_state)


def points_in_world(depth: np.ndarray, K: CameraIntrinsics, X_WC: RigidTransform) -> np.ndarray:
    """H x W x 3 world points [m] of a depth image (distance to the image plane, m); NaN where
    the depth is not finite or not positive."""
    h, w = depth.shape
    z = np.where(np.isfinite(depth) & (depth > 0), depth, np.nan).astype(np.float64)
    u = np.arange(w)[None, :]
    v = np.arange(h)[:, None]
    p_C = np.stack([(u - K.cx) * z / K.fx, (v - K.cy) * z / K.fy, z], axis=-1)
    R = X_WC.rotation().matrix()
    return p_C @ R.T + X_WC.translation()


# -- object models -----------------------------------------------------------------------------
@dataclass(frozen=True)
class ObjectModel:
    """What the detector knows of an object: name, height and top-down extents (major,
    minor) [m] of its mesh, and its colour signature (hue histogram + grey share, by area)."""

    name: str
    height: float
    extents: tuple[float, float]
    colour: np.ndarray  # HUE_BINS + 1 shares summing to 1 (last: grey)
    widths: tuple[float, float] = (0.0, 0.0)  # horizontal width across a view, min/max over yaw
    flat_share: float = 0.0  # share of the seen area that faces up, viewed from 35 deg above


def colour_signature(rgb: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
    """Hue histogram (HUE_BINS bins) + grey share of N x 3 colours in [0, 1], normalised."""
    rgb = np.clip(np.asarray(rgb, np.float32).reshape(-1, 1, 3), 0, 1)
    hsv = cv2.cvtColor(rgb, cv2.COLOR_RGB2HSV).reshape(-1, 3)  # H in [0, 360), S, V in [0, 1]
    w = np.ones(len(hsv)) if weights is None else np.asarray(weights, float)
    grey = (hsv[:, 1] < SAT_MIN) | (hsv[:, 2] < VAL_MIN)
    bins = np.minimum((hsv[:, 0] / (360.0 / HUE_BINS)).astype(int), HUE_BINS - 1)
    sig = np.bincount(bins[~grey], w[~grey], minlength=HUE_BINS)
    sig = np.append(sig, w[grey].sum())
    total = sig.sum()
    return sig / total if total > 0 else sig


def _blur(sig: np.ndarray) -> np.ndarray:
    """Spread each hue bin over its neighbours (circular), keeping the grey share."""
    h = sig[:HUE_BINS]
    spread = 0.5 * h + 0.25 * (np.roll(h, 1) + np.roll(h, -1))
    return np.append(spread, sig[HUE_BINS])


def load_object_model(name: str, mesh: str | Path) -> ObjectModel:
    """An :class:`ObjectModel` from an OBJ mesh and its MTL file (diffuse colours ``Kd``);
    a relative ``mesh`` path (as the task's priors give it) may be relative to the data root."""
    mesh = resolve_user_path(mesh, f"object model mesh of {name!r}")
    verts, faces, mats, kd, current = [], [], [], {}, None
    for line in mesh.read_text().splitlines():
        t = line.split()
        if not t:
            continue
        if t[0] == "v":
            verts.append([float(x) for x in t[1:4]])
        elif t[0] == "usemtl":
            current = t[1]
        elif t[0] == "f":
            idx = [int(x.split("/")[0]) - 1 for x in t[1:]]
            for k in range(1, len(idx) - 1):  # fan triangulation
                faces.append((idx[0], idx[k], idx[k + 1]))
                mats.append(current)
        elif t[0] == "mtllib":
            for ml in (mesh.parent / t[1]).read_text().splitlines():
                m = ml.split()
                if m and m[0] == "newmtl":
                    mat = m[1]
                elif m and m[0] == "Kd":
                    kd[mat] = [float(x) for x in m[1:4]]
    v = np.asarray(verts)
    f = np.asarray(faces)
    area = 0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]),
                                axis=1)
    colours = np.array([kd.get(m, [0.5, 0.5, 0.5]) for m in mats])
    ext = np.sort(v[:, :2].max(0) - v[:, :2].min(0))[::-1]
    yaws = np.radians(np.arange(0, 180, 5))
    proj = v[:, :2] @ np.stack([np.cos(yaws), np.sin(yaws)])
    widths = proj.max(0) - proj.min(0)
    # Expected share of pixels on up-facing faces, seen from 35 deg elevation, any azimuth.
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    el = math.radians(35.0)
    seen = up = 0.0
    for az in np.radians(np.arange(0, 360, 45)):
        d = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
        proj_area = area * np.maximum(n @ d, 0.0)
        seen += proj_area.sum()
        up += proj_area[n[:, 2] > 0.93].sum()
    return ObjectModel(name, float(v[:, 2].max() - v[:, 2].min()),
                       (float(ext[0]), float(ext[1])), colour_signature(colours, area),
                       (float(widths.min()), float(widths.max())), float(up / seen))


def object_models_from_priors(priors: dict) -> dict[str, ObjectModel]:
    """The nine object models of task 6's ``object_models`` prior (name -> mesh path)."""
    return {name: load_object_model(name, m["mesh"])
            for name, m in priors["object_models"].items()}


# -- detector ----------------------------------------------------------------------------------
@dataclass
class DetectorParams(Params):
    """See params/agents/search_perception.yaml (lengths in m)."""

    FILE: ClassVar[str] = "params/agents/search_perception.yaml"
    max_range: float = 4.0
    min_range: float = 0.3
    horizontal_normal_z: float = 0.93
    plane_bin: float = 0.01
    plane_min_pixels: int = 400
    plane_min_extent: float = 0.35
    plane_tolerance: float = 0.012
    depth_edge: float = 0.015
    depth_edge_slope: float = 0.01
    edge_band: float = 0.05
    min_pixels: int = 25
    min_rise: float = 0.012
    max_rise: float = 0.30
    max_extent: float = 0.40
    support_gap: float = 0.03
    support_ring: float = 0.15
    foot_height: float = 0.03
    size_weight: float = 1.0
    flat_weight: float = 1.0
    min_score: float = 0.3



@dataclass
class Detection:
    """One object found in a frame.

    Attributes:
        label: best-matching object model.
        score: colour similarity minus size mismatch (higher is better; 1 at most).
        p_WO: object centre in world [m].
        support_height: height of the plane it stands on [m].
        height, extents: measured height and top-down extents (major, minor) [m].
        pixels: cluster size; bbox: (u0, v0, u1, v1) in pixels; scores: score per model.
    """

    label: str
    score: float
    p_WO: np.ndarray
    support_height: float
    height: float
    extents: tuple[float, float]
    pixels: int
    bbox: tuple[int, int, int, int]
    scores: dict[str, float] = field(default_factory=dict)


class ObjectFinder(Protocol):
    """The interface of a detector (rule-based, learned, VLM): all objects found in a frame,
    best first. ``rgb`` H x W x 3 uint8, ``depth`` H x W float32 [m, distance to the image
    plane], ``X_WC`` the camera pose in world."""

    def detect(self, rgb: np.ndarray, depth: np.ndarray, X_WC: RigidTransform) -> list[Detection]:
        ...


class ObjectDetector:
    """Plane removal + clustering + shape/size/hue matching (module docstring).

    Args:
        models: the objects to recognise (:func:`object_models_from_priors`).
        intrinsics: of the camera whose frames are given.
        params: thresholds (:class:`DetectorParams`).
    """

    def __init__(self, models: dict[str, ObjectModel], intrinsics: CameraIntrinsics,
                 params: DetectorParams | None = None):
        if not models:
            raise ValueError("ObjectDetector needs at least one object model")
        self.models = models
        self.K = intrinsics
        self.params = params or DetectorParams.load()
        #: (bbox, reason) of the clusters the last ``detect`` rejected, for debugging.
        self.rejected: list = []

    def find(self, rgb, depth, X_WC: RigidTransform, target: str) -> Optional[Detection]:
        """The best detection labelled ``target``, or None."""
        if target not in self.models:
            raise ValueError(f"unknown target {target!r}; known: {sorted(self.models)}")
        hits = [d for d in self.detect(rgb, depth, X_WC) if d.label == target]
        return hits[0] if hits else None

    def detect(self, rgb: np.ndarray, depth: np.ndarray, X_WC: RigidTransform) -> list[Detection]:
        """Every object found in the frame, best score first."""
        P = self.params
        self.rejected = []
        rgb = np.asarray(rgb)[:, :, :3]
        depth = np.asarray(depth, np.float32)
        if depth.shape != (self.K.height, self.K.width) or rgb.shape[:2] != depth.shape:
            raise ValueError(f"frame {rgb.shape} / {depth.shape} does not match the camera "
                             f"{self.K.width}x{self.K.height}")
        self._camera_xy = X_WC.translation()[:2]
        valid = np.isfinite(depth) & (depth > P.min_range) & (depth < P.max_range)
        pts = points_in_world(np.where(valid, depth, np.nan), self.K, X_WC)
        z = pts[:, :, 2]
        horizontal = self._horizontal(pts)
        levels = self._planes(pts, horizontal)
        on_plane = np.zeros_like(valid)
        plane_id = np.full(depth.shape, -1)
        for k, level in enumerate(levels):
            m = horizontal & (np.abs(z - level) < P.plane_tolerance)
            on_plane |= m
            plane_id[m] = k
        candidate = valid & ~on_plane
        for level in levels:  # cut the band of each support's edge (table top thickness)
            candidate &= ~((z > level - P.edge_band) & (z < level + P.plane_tolerance))
        candidate &= ~self._depth_edges(depth)
        self.candidate = candidate  # for debugging
        n, labels, stats, _ = cv2.connectedComponentsWithStats(candidate.astype(np.uint8), 4)
        hsv_rgb = rgb.astype(np.float32) / 255.0
        out = []
        for i in range(1, n):
            if stats[i, cv2.CC_STAT_AREA] < P.min_pixels:
                continue
            x0, y0, w, h = (int(stats[i, k]) for k in (cv2.CC_STAT_LEFT, cv2.CC_STAT_TOP,
                                                        cv2.CC_STAT_WIDTH, cv2.CC_STAT_HEIGHT))
            sub = labels[y0:y0 + h, x0:x0 + w] == i
            det = self._cluster(sub, (x0, y0, w, h), pts, plane_id, levels, hsv_rgb, horizontal)
            if det is not None:
                out.append(det)
        out.sort(key=lambda d: -d.score)
        return out

    # -- steps -------------------------------------------------------------------------------
    def _horizontal(self, pts: np.ndarray) -> np.ndarray:
        """Pixels whose surface normal is within acos(horizontal_normal_z) of vertical."""
        dx = np.zeros_like(pts)
        dy = np.zeros_like(pts)
        dx[:, 1:-1] = pts[:, 2:] - pts[:, :-2]
        dy[1:-1] = pts[2:] - pts[:-2]
        n = np.cross(dx, dy)
        norm = np.linalg.norm(n, axis=-1)
        with np.errstate(invalid="ignore", divide="ignore"):
            nz = np.abs(n[:, :, 2]) / norm
        return np.nan_to_num(nz) > self.params.horizontal_normal_z

    def _planes(self, pts: np.ndarray, horizontal: np.ndarray) -> list[float]:
        """Heights [m] of the large horizontal surfaces in view (floor, table tops)."""
        P = self.params
        h = pts[horizontal & np.isfinite(pts[:, :, 2])]  # no depth: inf (or nan) points
        if len(h) == 0:
            return []
        z = h[:, 2]
        edges = np.arange(np.floor(z.min() / P.plane_bin) - 1, np.ceil(z.max() / P.plane_bin) + 2
                          ) * P.plane_bin
        counts, _ = np.histogram(z, edges)
        levels = []
        for k in np.argsort(-counts):
            if counts[k] < P.plane_min_pixels:
                break
            center = 0.5 * (edges[k] + edges[k + 1])
            if any(abs(center - lv) < 2 * P.plane_bin for lv in levels):
                continue
            # The largest connected patch at that height must be large (in pixels and in
            # world): object tops at a common height are not a support.
            mask = horizontal & (np.abs(pts[:, :, 2] - center) < P.plane_tolerance)
            n, labels, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), 8)
            if n < 2:
                continue
            big = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
            if stats[big, cv2.CC_STAT_AREA] < P.plane_min_pixels:
                continue
            near = pts[labels == big]
            span = np.percentile(near[:, :2], 98, axis=0) - np.percentile(near[:, :2], 2, axis=0)
            if span.max() < P.plane_min_extent:
                continue  # a large object's top, not a support
            levels.append(float(np.median(near[:, 2])))
        return sorted(levels)

    def _depth_edges(self, depth: np.ndarray) -> np.ndarray:
        d = np.nan_to_num(depth, nan=0.0, posinf=0.0)
        thr = self.params.depth_edge + self.params.depth_edge_slope * d
        jx = np.abs(d[:, 1:] - d[:, :-1]) > np.minimum(thr[:, 1:], thr[:, :-1])
        jy = np.abs(d[1:] - d[:-1]) > np.minimum(thr[1:], thr[:-1])
        edge = np.zeros(d.shape, bool)
        edge[:, 1:] |= jx  # both pixels of every jump
        edge[:, :-1] |= jx
        edge[1:] |= jy
        edge[:-1] |= jy
        return edge

    def _cluster(self, mask, box, pts, plane_id, levels, rgb, horizontal) -> Optional[Detection]:
        P = self.params
        x0, y0, w, h = box
        p = pts[y0:y0 + h, x0:x0 + w][mask]
        p = p[np.isfinite(p).all(axis=1)]
        why = self.rejected
        if len(p) < P.min_pixels or not levels:
            return why.append((box, "few points")) or None
        bottom, top = np.percentile(p[:, 2], 1), np.percentile(p[:, 2], 99)
        below = [lv for lv in levels if lv <= bottom + P.support_gap]
        if not below:
            return why.append((box, f"no plane under z={bottom:.3f}")) or None
        level = below[-1]
        if bottom - level > P.support_gap:
            return why.append((box, f"floats {bottom - level:.3f} above {level:.3f}")) or None
        rise = top - level
        if not P.min_rise <= rise <= P.max_rise:
            return why.append((box, f"rise {rise:.3f}")) or None
        # Plane pixels of that level around the cluster (it stands on the plane).
        pad = 4
        Y0, X0 = max(0, y0 - pad), max(0, x0 - pad)
        Y1, X1 = min(plane_id.shape[0], y0 + h + pad), min(plane_id.shape[1], x0 + w + pad)
        full = np.zeros((Y1 - Y0, X1 - X0), np.uint8)
        full[y0 - Y0:y0 - Y0 + h, x0 - X0:x0 - X0 + w] = mask
        ring = cv2.dilate(full, np.ones((2 * pad + 1, 2 * pad + 1), np.uint8)) > full
        k = levels.index(level)
        plane_k = plane_id[Y0:Y1, X0:X1] == k
        share = plane_k[ring].mean() if ring.any() else 0.0
        if share < P.support_ring and P.foot_height > 0.0:
            # A tall object seen against a wall: most of its outline is the wall; around its
            # foot (its pixels up to foot_height above its lowest point) the plane shows.
            z_box = np.full(full.shape, np.inf)
            z_box[y0 - Y0:y0 - Y0 + h, x0 - X0:x0 - X0 + w][mask] = (
                pts[y0:y0 + h, x0:x0 + w, 2][mask])
            foot = (full > 0) & (z_box < bottom + P.foot_height)
            ring = cv2.dilate(foot.astype(np.uint8), np.ones((2 * pad + 1, 2 * pad + 1),
                                                                np.uint8)) > full
            share = max(share, plane_k[ring].mean() if ring.any() else 0.0)
        if share < P.support_ring:
            return why.append((box, f"plane share {share:.2f}")) or None
        xy = p[:, :2].astype(np.float32)
        (cx, cy), (a, b), _ = cv2.minAreaRect(xy)
        a, b = max(a, b), min(a, b)
        if a > P.max_extent:
            return why.append((box, f"extent {a:.2f}")) or None
        colour = colour_signature(rgb[y0:y0 + h, x0:x0 + w][mask])
        # Width across the line of sight: fully visible whatever hides the back.
        view = p[:, :2].mean(0) - self._camera_xy
        across = np.array([-view[1], view[0]]) / max(np.linalg.norm(view), 1e-9)
        s_across = p[:, :2] @ across
        width = float(np.percentile(s_across, 99) - np.percentile(s_across, 1))
        flat = float(horizontal[y0:y0 + h, x0:x0 + w][mask].mean())
        scores = {}
        for name, m in self.models.items():
            similarity = float(np.minimum(_blur(colour), _blur(m.colour)).sum())
            w_lo, w_hi = m.widths
            mismatch = (abs(math.log(max(rise, 1e-3) / m.height))
                        + abs(math.log(min(max(width, w_lo), w_hi) / max(width, 1e-3)))
                        + max(0.0, math.log(a / m.extents[0]))  # never longer than the model
                        + P.flat_weight * abs(flat - m.flat_share))
            scores[name] = similarity - P.size_weight * mismatch
        label = max(scores, key=scores.get)
        if scores[label] < P.min_score:
            return why.append((box, f"score {label} {scores[label]:.2f}")) or None
        model = self.models[label]
        p_WO = np.array([cx, cy, level + 0.5 * model.height])
        return Detection(label, scores[label], p_WO, level, float(rise), (float(a), float(b)),
                         int(mask.sum()), (x0, y0, x0 + w, y0 + h), scores)

"""2D and 3D box ground truth with FogDrive's visibility rule (or the cameras' own), without its artefacts.

Pure functions over the scene's vehicle arrays, camera/LiDAR poses and sensor buffers; nothing here imports
the environment.

* 3D boxes: eight corners per vehicle in the LiDAR frame (order :data:`fog_gym.geometry.BOX_CORNER_SIGNS`:
  0 front-right-bottom, 1 front-left-bottom, 2 rear-left-bottom, 3 rear-right-bottom, then 4–7 the same on top),
  plus centre, size (l, w, h), yaw and velocity in the LiDAR frame.
* 2D boxes: the box is clipped against each camera's near plane *before* the perspective divide, projected,
  intersected with the image, and its extent taken: a vehicle straddling the camera plane gets the tight box of
  what the camera can see, never FogDrive's image-spanning artefact.
* Visibility, per camera: ``"lidar"`` (FogDrive: ≥ ``min_detect`` semantic-LiDAR points on the vehicle and
  within ``max_dist`` of the camera) or ``"camera"`` (≥ ``min_pixels`` of its id in the camera's instance
  buffer, ≥ ``min_box_fill`` of its 2D box showing vehicle pixels, within ``max_dist``). A 3D box is annotated
  when its vehicle is annotated in at least one camera.

Example:
    >>> cfg = LabelConfig(visibility="camera", min_pixels=10)
    >>> cfg.visibility, cfg.min_detect, cfg.max_dist
    ('camera', 5, 100.0)
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass

import numpy as np
from numba import njit

from fog_gym import geometry
from fog_gym.geometry import polygon_area as _area
from fog_gym.checks import finite as _finite

VISIBILITY_RULES = ("lidar", "camera")
NEAR_PLANE = 0.05  # metres, as the renderer's near plane
_EDGES = np.array([[0, 1], [1, 2], [2, 3], [3, 0], [4, 5], [5, 6], [6, 7], [7, 4], [0, 4], [1, 5], [2, 6], [3, 7]])
#: FogDrive's extrinsic keys per camera.
EXTRINSIC_KEYS = {"CAM_FRONT": "extrinsic_front", "CAM_RIGHT": "extrinsic_right", "CAM_LEFT": "extrinsic_left",
                  "CAM_BACK": "extrinsic_back"}  # fmt: skip


class Annotations(Mapping):
    """Read-only mapping of one box set's arrays (``bboxes``, ``vehicle_ids``, …).

    Not a ``dict`` on purpose: Gymnasium's vector envs stack ``dict`` infos into fixed-shape arrays, which
    variable-length box lists cannot be; an ``Annotations`` becomes one object per sub-env instead.

    >>> a = Annotations({"vehicle_ids": np.array([3, 7])})
    >>> a["vehicle_ids"].tolist(), list(a), a.with_fields(extra=1)["extra"]
    ([3, 7], ['vehicle_ids'], 1)
    """

    __slots__ = ("_data",)

    def __init__(self, data: Mapping[str, np.ndarray]) -> None:
        self._data = dict(data)

    def __getitem__(self, key: str) -> np.ndarray:
        return self._data[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._data)

    def __len__(self) -> int:
        return len(self._data)

    def __repr__(self) -> str:
        n = len(next(iter(self._data.values()))) if self._data else 0
        return f"Annotations({n} boxes: {', '.join(self._data)})"

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Mapping) or set(other) != set(self._data):
            return False
        return all(np.array_equal(np.asarray(v), np.asarray(other[k])) for k, v in self._data.items())

    __hash__ = None  # type: ignore[assignment]

    def with_fields(self, **fields: np.ndarray) -> Annotations:
        return Annotations({**self._data, **fields})


@dataclass(frozen=True)
class LabelConfig:
    """Which vehicles get boxes. Defaults are FogDrive's rule (paper §3.3).

    >>> LabelConfig(min_detect=0)
    Traceback (most recent call last):
    ...
    ValueError: min_detect must be an integer >= 1, got 0
    """

    visibility: str = "lidar"
    min_detect: int = 5  # semantic-LiDAR points on the vehicle ("lidar" rule)
    max_dist: float = 100.0  # metres from the camera (both rules)
    min_pixels: int = 20  # instance-buffer pixels ("camera" rule)
    min_box_fill: float = 0.1  # share of the 2D box showing vehicle pixels ("camera" rule; the paper's precision test)

    def __post_init__(self) -> None:
        if self.visibility not in VISIBILITY_RULES:
            raise ValueError(f"visibility must be one of {VISIBILITY_RULES}, got {self.visibility!r}")
        for name in ("min_detect", "min_pixels"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
                raise ValueError(f"{name} must be an integer >= 1, got {v!r}")
        if _finite("max_dist", self.max_dist) <= 0:
            raise ValueError(f"max_dist must be > 0 metres, got {self.max_dist!r}")
        if not 0.0 <= _finite("min_box_fill", self.min_box_fill) <= 1.0:
            raise ValueError(f"min_box_fill must lie in [0, 1], got {self.min_box_fill!r}")


@njit(cache=True, nogil=True)
def _clip_polygon(poly, n, x0, y0, x1, y1):
    """Sutherland–Hodgman of a polygon (n points) against the rectangle [x0, x1] × [y0, y1]."""
    for side in range(4):
        out = np.empty((n + 4, 2))
        m = 0
        for k in range(n):
            a = poly[k]
            b = poly[(k + 1) % n]
            if side == 0:
                da, db = a[0] - x0, b[0] - x0
            elif side == 1:
                da, db = x1 - a[0], x1 - b[0]
            elif side == 2:
                da, db = a[1] - y0, b[1] - y0
            else:
                da, db = y1 - a[1], y1 - b[1]
            if da >= 0:
                out[m] = a
                m += 1
            if (da >= 0) != (db >= 0):
                s = da / (da - db)
                out[m, 0] = a[0] + s * (b[0] - a[0])
                out[m, 1] = a[1] + s * (b[1] - a[1])
                m += 1
        poly = out
        n = m
        if n == 0:
            break
    return poly, n


@njit(cache=True, nogil=True)
def _hull(pts, n):
    """Convex hull (monotone chain) of n 2D points, counter-clockwise."""
    order = np.argsort(pts[:n, 0] + 1e-9 * pts[:n, 1])
    p = pts[order]
    hull = np.empty((2 * n + 1, 2))
    m = 0
    for k in range(n):
        while m >= 2 and (hull[m - 1, 0] - hull[m - 2, 0]) * (p[k, 1] - hull[m - 2, 1]) - (hull[m - 1, 1] - hull[m - 2, 1]) * (p[k, 0] - hull[m - 2, 0]) <= 0:
            m -= 1
        hull[m] = p[k]
        m += 1
    lower = m + 1
    for k in range(n - 2, -1, -1):
        while m >= lower and (hull[m - 1, 0] - hull[m - 2, 0]) * (p[k, 1] - hull[m - 2, 1]) - (hull[m - 1, 1] - hull[m - 2, 1]) * (p[k, 0] - hull[m - 2, 0]) <= 0:
            m -= 1
        hull[m] = p[k]
        m += 1
    return hull, max(m - 1, 1)


@njit(cache=True, nogil=True)
def _project_boxes(corners_cam, fx, fy, cx, cy, width, height, near, edges):
    """Per box: (u0, v0, u1, v1) of (projection of the near-clipped box) ∩ image, its area and the full hull area."""
    n_box = corners_cam.shape[0]
    rect = np.full((n_box, 4), np.nan)
    inside = np.zeros(n_box)
    total = np.zeros(n_box)
    pts = np.empty((20, 2))
    for b in range(n_box):
        c = corners_cam[b]
        n = 0
        for k in range(8):
            if c[k, 2] >= near:
                pts[n, 0] = fx * c[k, 0] / c[k, 2] + cx
                pts[n, 1] = fy * c[k, 1] / c[k, 2] + cy
                n += 1
        for e in range(12):
            a, d = c[edges[e, 0]], c[edges[e, 1]]
            if (a[2] >= near) != (d[2] >= near):
                s = (near - a[2]) / (d[2] - a[2])
                x = a[0] + s * (d[0] - a[0])
                y = a[1] + s * (d[1] - a[1])
                pts[n, 0] = fx * x / near + cx
                pts[n, 1] = fy * y / near + cy
                n += 1
        if n < 3:
            continue
        hull, m = _hull(pts, n)
        total[b] = _area(hull, m)
        clipped, k = _clip_polygon(hull[:m].copy(), m, 0.0, 0.0, float(width), float(height))
        if k < 3:
            continue
        area = _area(clipped, k)
        if area <= 0.0:
            continue
        inside[b] = area
        rect[b, 0] = clipped[:k, 0].min()
        rect[b, 1] = clipped[:k, 1].min()
        rect[b, 2] = clipped[:k, 0].max()
        rect[b, 3] = clipped[:k, 1].max()
    return rect, inside, total


@njit(cache=True, nogil=True)
def _pixel_counts(instance, rects, ids):
    """Per box: pixels of its own id and pixels of any vehicle (id > 0) inside its integer rectangle."""
    n = rects.shape[0]
    own = np.zeros(n, np.int64)
    any_vehicle = np.zeros(n, np.int64)
    for b in range(n):
        vid = ids[b]
        o = 0
        a = 0
        for i in range(rects[b, 1], rects[b, 3] + 1):
            row = instance[i, rects[b, 0] : rects[b, 2] + 1]
            for j in range(row.shape[0]):  # branch-free so it vectorises
                v = row[j]
                a += v != 0
                o += v == vid
        own[b] = o
        any_vehicle[b] = a
    return own, any_vehicle


def boxes_3d(centers: np.ndarray, sizes: np.ndarray, yaws: np.ndarray, velocities: np.ndarray,
             world_to_lidar: np.ndarray) -> dict[str, np.ndarray]:  # fmt: skip
    """All boxes in the LiDAR frame: ``corners`` (N, 8, 3), ``center`` (N, 3), ``size`` (N, 3), ``yaw`` (N,),
    ``velocity`` (N, 3) (world velocity expressed in the LiDAR frame), ``distance`` (N,) from the LiDAR."""
    rot = world_to_lidar[:3, :3]
    center = geometry.transform_points(world_to_lidar, centers)
    lidar_yaw = math.atan2(rot[1, 0], rot[0, 0])  # yaw of the world x axis seen from the LiDAR
    yaw = np.angle(np.exp(1j * (np.asarray(yaws, np.float64) + lidar_yaw)))
    return {
        "corners": geometry.box_corners(center, sizes, yaw).reshape(-1, 8, 3),
        "center": center.reshape(-1, 3),
        "size": np.asarray(sizes, np.float64).reshape(-1, 3),
        "yaw": yaw.reshape(-1),
        "velocity": (np.asarray(velocities, np.float64).reshape(-1, 3) @ rot.T),
        "distance": np.linalg.norm(center.reshape(-1, 3), axis=1),
    }


def boxes_2d(corners_lidar: np.ndarray, extrinsic: np.ndarray, K: np.ndarray, width: int, height: int,
             near: float = NEAR_PLANE) -> dict[str, np.ndarray]:  # fmt: skip
    """Project LiDAR-frame corners (N, 8, 3) into a camera with near-plane clipping.

    Returns ``rect`` (N, 4) float u0, v0, u1, v1 of the visible part (NaN where none), ``bboxes`` (N, 2, 2) int
    ``[[xmin, ymin], [xmax, ymax]]`` (rounded, inside the image), ``in_view`` (N,) bool, ``truncation`` (N,)
    (share of the projected box outside the image), ``area`` (N,) of its visible projection (px²) and
    ``distance`` (N,) camera → box centre.
    """
    corners_lidar = np.asarray(corners_lidar, np.float64)
    if corners_lidar.ndim != 3 or corners_lidar.shape[1:] != (8, 3) or not np.isfinite(corners_lidar).all():
        raise ValueError(f"corners must be finite (N, 8, 3) LiDAR-frame points, got shape {corners_lidar.shape}")
    if int(width) <= 0 or int(height) <= 0:
        raise ValueError(f"width and height must be positive pixels, got {width}×{height}")
    corners_cam = geometry.transform_points(extrinsic, corners_lidar.reshape(-1, 3)).reshape(-1, 8, 3)
    rect, inside, total = _project_boxes(np.ascontiguousarray(corners_cam), K[0, 0], K[1, 1], K[0, 2], K[1, 2],
                                         int(width), int(height), float(near), _EDGES)  # fmt: skip
    in_view = inside > 0
    bboxes = np.zeros((len(rect), 2, 2), np.int64)
    if in_view.any():
        limits = np.array([width - 1, height - 1, width - 1, height - 1], np.float64)
        bboxes[in_view] = np.minimum(np.maximum(np.round(rect[in_view]), 0.0), limits).reshape(-1, 2, 2)
    truncation = np.where(total > 0, 1.0 - inside / np.maximum(total, 1e-12), 1.0)
    return {
        "rect": rect, "bboxes": bboxes, "in_view": in_view, "truncation": np.clip(truncation, 0.0, 1.0), "area": inside,
        "distance": np.linalg.norm(corners_cam.mean(axis=1), axis=1),
    }  # fmt: skip


def pixel_counts(instance: np.ndarray, bboxes: np.ndarray, ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per 2D box: instance pixels of its own id, and of any vehicle, inside the (inclusive) box."""
    rects = np.ascontiguousarray(bboxes.reshape(-1, 4).astype(np.int64))
    return _pixel_counts(instance, rects, np.asarray(ids, np.int64))


def semantic_lidar_counts(semantic_points: np.ndarray | None, ids: np.ndarray) -> np.ndarray:
    """Semantic-LiDAR points on each vehicle id (object id column 4)."""
    ids = np.asarray(ids, np.int64)
    if semantic_points is None or len(semantic_points) == 0 or len(ids) == 0:
        return np.zeros(len(ids), np.int64)
    obj = semantic_points[:, 4].astype(np.int64)
    counts = np.bincount(obj, minlength=int(max(ids.max(), obj.max())) + 1)
    return counts[ids]


def empty_2d() -> Annotations:
    """A camera's annotations when nothing is annotated (correctly shaped)."""
    return Annotations({
        "bboxes": np.zeros((0, 2, 2), np.int64), "vehicle_ids": np.zeros(0, np.int64),
        "vehicle_class": np.zeros(0, np.int64), "truncation": np.zeros(0), "visible_fraction": np.zeros(0),
        "distance": np.zeros(0),
    })  # fmt: skip


@dataclass(frozen=True)
class CameraView:
    """What labelling needs of one camera: LiDAR→camera extrinsic, intrinsic, size and its instance buffer."""

    name: str
    extrinsic: np.ndarray
    K: np.ndarray
    width: int
    height: int
    instance: np.ndarray | None


def annotate(
    ids: np.ndarray, classes: np.ndarray, centers: np.ndarray, sizes: np.ndarray, yaws: np.ndarray,
    velocities: np.ndarray, world_to_lidar: np.ndarray, cameras: list[CameraView],
    semantic_points: np.ndarray | None, cfg: LabelConfig,
) -> tuple[Annotations, dict[str, Annotations]]:  # fmt: skip
    """``(boxes_3d, boxes_2d)`` for the vehicles given (leave the ego out).

    ``boxes_2d[camera]`` has ``bboxes`` (M, 2, 2) int, ``vehicle_ids``, ``vehicle_class``, ``truncation``,
    ``visible_fraction`` (own instance pixels / area of the visible projected box) and ``distance`` (camera →
    centre, metres). ``boxes_3d`` has ``corners`` (N, 8, 3), ``vehicle_ids``, ``vehicle_class``, ``center``,
    ``size``, ``yaw``, ``velocity``, ``distance`` (LiDAR → centre) for every vehicle annotated in some camera.
    """
    ids = np.asarray(ids, np.int64)
    classes = np.asarray(classes, np.int64)
    b3 = boxes_3d(centers, sizes, yaws, velocities, world_to_lidar)
    lidar_hits = semantic_lidar_counts(semantic_points, ids) if cfg.visibility == "lidar" else None
    annotated_any = np.zeros(len(ids), bool)
    out_2d: dict[str, Annotations] = {}
    for cam in cameras:
        if len(ids) == 0:
            out_2d[cam.name] = empty_2d()
            continue
        p = boxes_2d(b3["corners"], cam.extrinsic, cam.K, cam.width, cam.height)
        candidate = p["in_view"] & (p["distance"] <= cfg.max_dist)
        own = np.zeros(len(ids), np.int64)
        any_vehicle = np.zeros(len(ids), np.int64)
        if cam.instance is not None and candidate.any():
            own[candidate], any_vehicle[candidate] = pixel_counts(cam.instance, p["bboxes"][candidate], ids[candidate])
        box_area = (p["bboxes"][:, 1, 0] - p["bboxes"][:, 0, 0] + 1) * (p["bboxes"][:, 1, 1] - p["bboxes"][:, 0, 1] + 1)
        if cfg.visibility == "lidar":
            keep = candidate & (lidar_hits >= cfg.min_detect)
        else:
            keep = candidate & (own >= cfg.min_pixels) & (any_vehicle >= cfg.min_box_fill * box_area)
        annotated_any |= keep
        visible_area = np.maximum(p["area"][keep], 1e-9)
        out_2d[cam.name] = Annotations({
            "bboxes": p["bboxes"][keep], "vehicle_ids": ids[keep], "vehicle_class": classes[keep],
            "truncation": p["truncation"][keep], "visible_fraction": np.clip(own[keep] / visible_area, 0.0, 1.0),
            "distance": p["distance"][keep],
        })  # fmt: skip
    b3_out = {k: v[annotated_any] for k, v in b3.items()}
    b3_out["vehicle_ids"] = ids[annotated_any]
    b3_out["vehicle_class"] = classes[annotated_any]
    return Annotations(b3_out), out_2d

"""Frames, poses, class mappings and per-box measurements shared by the exporters (pure numpy, no I/O).

FogDrive (and CARLA, and highway-env) use a **left-handed** frame for the world, the ego and the LiDAR: +x forward,
+y right, +z up, yaw positive turning right. nuScenes and KITTI's LiDAR frames are **right-handed**: +x forward,
+y left, +z up, yaw positive turning left. The change is one reflection, ``F = diag(1, −1, 1)``: a point
``(x, y, z)`` becomes ``(x, −y, z)``, a yaw ``ψ`` becomes ``−ψ``, a rigid transform ``T`` becomes ``F·T·F``. Box sizes
are unchanged. The camera frame (+x right, +y down, +z forward) is already right-handed: a FogDrive extrinsic
``E`` (LiDAR → camera) becomes ``E·F`` (right-handed LiDAR → camera), a proper rotation.

Example:
    >>> T = reflect_transform(np.array([[1, 0, 0, 1], [0, 1, 0, 2], [0, 0, 1, 3], [0, 0, 0, 1.0]]))
    >>> T[:3, 3].tolist(), yaw_quaternion(np.pi / 2).round(6).tolist()
    ([1.0, -2.0, 3.0], [0.707107, 0.0, 0.0, 0.707107])
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from fog_gym.labels.visibility import points_in_boxes  # noqa: F401  (re-exported: the exports count points in boxes)

from fog_gym import geometry

#: The reflection between FogDrive's left-handed frames and the right-handed ones of nuScenes and KITTI.
FLIP = np.diag([1.0, -1.0, 1.0, 1.0])

#: FogDrive's vehicle classes (supplementary D1; 2 and 3 are never spawned) and their names in each export.
FOGDRIVE_CLASSES = {0: "passenger car", 1: "truck", 4: "bigger car (vans, large SUVs, ambulances, buses)"}
NUSCENES_CATEGORIES = {0: "vehicle.car", 1: "vehicle.truck", 4: "vehicle.bus.rigid"}
KITTI_TYPES = {0: "Car", 1: "Truck", 4: "Van"}
COCO_CATEGORIES = ({"id": 1, "name": "car", "supercategory": "vehicle", "fogdrive_class": 0},
                   {"id": 2, "name": "truck", "supercategory": "vehicle", "fogdrive_class": 1},
                   {"id": 3, "name": "large_vehicle", "supercategory": "vehicle", "fogdrive_class": 4})  # fmt: skip
COCO_CATEGORY_ID = {c["fogdrive_class"]: c["id"] for c in COCO_CATEGORIES}

#: FogDrive's camera field of view (degrees): the layout stores no intrinsics, ``K`` follows from it and the size.
CAMERA_FOV_DEG = 100.0
#: FogDrive's LiDAR beams: ``channels`` evenly spaced from ``upper_fov`` down to ``lower_fov`` (degrees).
LIDAR_BEAMS = {"channels": 64, "upper_fov": 5.0, "lower_fov": -20.0}


def reflect_transform(T: np.ndarray) -> np.ndarray:
    """A 4×4 rigid transform between left-handed frames, expressed between the reflected right-handed frames."""
    return FLIP @ np.asarray(T, np.float64) @ FLIP


def reflect_points(points: np.ndarray) -> np.ndarray:
    """``(N, ≥3)`` points with y negated (a copy)."""
    out = np.array(points, copy=True)
    out[:, 1] *= -1
    return out


def yaw_quaternion(yaw: float) -> np.ndarray:
    """``[w, x, y, z]`` of a rotation by ``yaw`` about +z."""
    return np.array([math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)])


def matrix_quaternion(R: np.ndarray) -> np.ndarray:
    """``[w, x, y, z]`` (w ≥ 0) of a proper 3×3 rotation matrix; ``ValueError`` for a reflection.

    >>> matrix_quaternion(np.diag([1.0, -1.0, -1.0])).round(6).tolist()
    [0.0, 1.0, 0.0, 0.0]
    """
    R = np.asarray(R, np.float64)[:3, :3]
    if abs(np.linalg.det(R) - 1.0) > 1e-6:
        raise ValueError(f"not a proper rotation (determinant {np.linalg.det(R):.3f}): a frame is of the wrong handedness")
    t = np.trace(R)
    if t > 0:
        s = 2.0 * math.sqrt(1.0 + t)
        q = [0.25 * s, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s]
    else:
        i = int(np.argmax(np.diag(R)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * math.sqrt(1.0 + R[i, i] - R[j, j] - R[k, k])
        q = [0.0] * 4
        q[0] = (R[k, j] - R[j, k]) / s
        q[1 + i] = 0.25 * s
        q[1 + j] = (R[j, i] + R[i, j]) / s
        q[1 + k] = (R[k, i] + R[i, k]) / s
    q = np.asarray(q)
    q /= np.linalg.norm(q)
    return -q if q[0] < 0 else q


def yaw_matrix(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def boxes_from_corners(corners: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """FogDrive corners ``(N, 8, 3)`` (LiDAR frame, left-handed) → right-handed centres ``(N, 3)``, sizes
    ``(N, 3)`` = (length, width, height) and yaws ``(N,)``."""
    b = geometry.corners_to_boxes(np.asarray(corners, np.float64).reshape(-1, 8, 3))
    centers = b[:, :3] * [1.0, -1.0, 1.0]
    return centers, b[:, 3:6], -b[:, 6]


def camera_intrinsic(width: int, height: int, fov_deg: float = CAMERA_FOV_DEG) -> np.ndarray:
    """The pinhole ``K`` of a FogDrive camera image of this size (CARLA's: f = W / (2 tan(FOV/2)), centre W/2, H/2)."""
    return geometry.intrinsic_matrix(int(width), int(height), fov_deg)


def class_from_height(heights: np.ndarray) -> np.ndarray:
    """FogDrive classes from box heights, for sets without 2D boxes (LiDAR-only): fog-gym's class size ranges
    are disjoint in height (car 1.40–1.60 m, bigger car 1.85–2.50 m, truck 3.00–3.80 m).

    >>> class_from_height(np.array([1.5, 2.2, 3.4])).tolist()
    [0, 4, 1]
    """
    h = np.asarray(heights, np.float64)
    return np.where(h < 1.725, 0, np.where(h < 2.75, 4, 1)).astype(np.int64)


def ring_index(points_rh: np.ndarray, beams: dict | None = None) -> np.ndarray:
    """The beam of each LiDAR point from its elevation (0 = the top beam, as the LiDAR fires them), for FogDrive's
    64-beam LiDAR by default; fog returns lie on their beam, so they get its index too."""
    beams = LIDAR_BEAMS if beams is None else beams
    p = np.asarray(points_rh, np.float64)
    elevation = np.degrees(np.arctan2(p[:, 2], np.hypot(p[:, 0], p[:, 1])))
    step = (beams["upper_fov"] - beams["lower_fov"]) / max(beams["channels"] - 1, 1)
    return np.clip(np.rint((beams["upper_fov"] - elevation) / step), 0, beams["channels"] - 1)


#: A pixel inside a box's image region whose depth is this much nearer than the box's nearest corner is occluded.
OCCLUSION_MARGIN_M = 0.5


def occlusion(depth: np.ndarray, corners_cam: np.ndarray, K: np.ndarray) -> tuple[float, float]:
    """``(occluded, visible)`` shares of one box in one camera, from the camera's planar depth image.

    The box's image region is the convex hull of its projected corners (those in front of the camera). A pixel of
    it is *occluded* when something is nearer than the box's nearest corner by :data:`OCCLUSION_MARGIN_M`.
    ``occluded`` is the share of the region's in-image pixels that are occluded; ``visible`` the share of the whole
    region (out-of-image parts included) that is in the image and not occluded. A box wholly outside the image or
    behind the camera gives ``(1.0, 0.0)``.
    """
    c = np.asarray(corners_cam, np.float64)
    front = c[c[:, 2] > 0.05]
    if len(front) < 3:
        return 1.0, 0.0
    uv = front[:, :2] / front[:, 2:3] * [K[0, 0], K[1, 1]] + [K[0, 2], K[1, 2]]
    hull = cv2.convexHull(uv.astype(np.float32)).reshape(-1, 2)
    total = float(cv2.contourArea(hull))
    h, w = depth.shape
    lo = np.maximum(np.floor(hull.min(axis=0)).astype(int), 0)
    hi = np.minimum(np.ceil(hull.max(axis=0)).astype(int) + 1, [w, h])
    if total <= 0 or (hi <= lo).any():
        return 1.0, 0.0
    mask = np.zeros((hi[1] - lo[1], hi[0] - lo[0]), np.uint8)
    cv2.fillConvexPoly(mask, np.rint((hull - lo - 0.5) * 16).astype(np.int32), 1, lineType=cv2.LINE_8, shift=4)
    inside = mask.astype(bool)
    n = int(inside.sum())
    if n == 0:
        return 1.0, 0.0
    occluded = int((depth[lo[1] : hi[1], lo[0] : hi[0]][inside] < front[:, 2].min() - OCCLUSION_MARGIN_M).sum())
    return occluded / n, float(np.clip((n - occluded) / max(total, n), 0.0, 1.0))


def kitti_occlusion(occluded_share: float) -> int:
    """KITTI's occlusion state from the occluded share: 0 fully visible (< 10 %), 1 partly (< 50 %), 2 largely.

    >>> [kitti_occlusion(s) for s in (0.0, 0.3, 0.8)]
    [0, 1, 2]
    """
    return 0 if occluded_share < 0.1 else 1 if occluded_share < 0.5 else 2


def nuscenes_visibility(visible_share: float) -> str:
    """nuScenes' visibility token (1: 0–40 %, 2: 40–60 %, 3: 60–80 %, 4: 80–100 % visible).

    >>> [nuscenes_visibility(v) for v in (0.1, 0.5, 0.7, 0.95)]
    ['1', '2', '3', '4']
    """
    return "1" if visible_share <= 0.4 else "2" if visible_share <= 0.6 else "3" if visible_share <= 0.8 else "4"


def wrap_angle(a: float) -> float:
    """``a`` wrapped to [−π, π)."""
    return (a + math.pi) % (2 * math.pi) - math.pi

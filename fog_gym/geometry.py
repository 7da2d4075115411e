"""Frames, sensor poses, rotations, intrinsics and projection (pure numpy, imports nothing from the environment).

Frames (docs/design.md §2):

* world, vehicle, sensor and LiDAR frames follow CARLA: left-handed, +x forward, +y right, +z up,
  yaw positive turning right (towards +y). highway-env's (x, y, heading) carry over unchanged.
* camera frame is the computer-vision frame: +x right, +y down, +z forward.

Pixel convention: pixel column ``j`` covers ``u in [j, j + 1)``; its centre is ``u = j + 0.5``.
A point that projects to ``(u, v)`` therefore lies in pixel ``(floor(v), floor(u))``.

Example:
    >>> import numpy as np
    >>> K = intrinsic_matrix(1280, 960, 100.0)
    >>> round(float(K[0, 0]), 2)
    537.02
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numba import njit

from fog_gym.checks import finite

#: Maps sensor-local CARLA axes (x fwd, y right, z up) to camera axes (x right, y down, z fwd).
SENSOR_TO_CAMERA = np.array(
    [[0.0, 1.0, 0.0, 0.0], [0.0, 0.0, -1.0, 0.0], [1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]]
)


@dataclass(frozen=True)
class Pose:
    """A sensor pose relative to the ego origin (ground under the vehicle centre), CARLA convention.

    Location in metres (+x forward, +y right, +z up), rotation in degrees (pitch, roll, yaw).

    >>> Pose(1.8, 0.0, 1.2).location
    (1.8, 0.0, 1.2)
    """

    x: float = 0.0
    y: float = 0.0
    z: float = 0.0
    pitch: float = 0.0
    roll: float = 0.0
    yaw: float = 0.0

    def __post_init__(self) -> None:
        for name in ("x", "y", "z", "pitch", "roll", "yaw"):
            object.__setattr__(self, name, finite(f"pose.{name}", getattr(self, name)))

    @property
    def location(self) -> tuple[float, float, float]:
        return (self.x, self.y, self.z)

    @property
    def rotation(self) -> tuple[float, float, float]:
        return (self.pitch, self.roll, self.yaw)

    @classmethod
    def coerce(cls, value: Pose | Sequence[float] | Mapping[str, float]) -> Pose:
        """Accept a Pose, a mapping of its fields, or a 3- or 6-sequence (x, y, z[, pitch, roll, yaw])."""
        if isinstance(value, Pose):
            return value
        if isinstance(value, Mapping):
            return cls(**value)
        values = list(value)
        if len(values) not in (3, 6):
            raise ValueError(f"pose must have 3 or 6 numbers (x, y, z[, pitch, roll, yaw]), got {value!r}")
        return cls(*values)


def rotation_matrix(pitch_deg: float, roll_deg: float, yaw_deg: float) -> np.ndarray:
    """3×3 rotation of CARLA's ``Transform`` (angles in degrees, left-handed frame).

    Columns are the sensor's x, y, z axes expressed in the parent frame. Yaw turns +x towards +y,
    positive pitch lifts the nose, as in CARLA.

    >>> np.round(rotation_matrix(0, 0, 90) @ [1, 0, 0], 6).tolist()
    [0.0, 1.0, 0.0]
    """
    p, r, y = np.radians([pitch_deg, roll_deg, yaw_deg])
    cp, sp, cr, sr, cy, sy = math.cos(p), math.sin(p), math.cos(r), math.sin(r), math.cos(y), math.sin(y)
    return np.array(
        [
            [cp * cy, cy * sp * sr - sy * cr, -cy * sp * cr - sy * sr],
            [cp * sy, sy * sp * sr + cy * cr, -sy * sp * cr + cy * sr],
            [sp, -cp * sr, cp * cr],
        ]
    )


def transform_matrix(location: tuple[float, float, float], rotation: tuple[float, float, float]) -> np.ndarray:
    """4×4 sensor→parent transform from ``(x, y, z)`` metres and ``(pitch, roll, yaw)`` degrees (a new array)."""
    return _mount(*(float(v) for v in location), *(float(v) for v in rotation)).copy()


@functools.lru_cache(maxsize=256)
def _mount(x: float, y: float, z: float, pitch: float, roll: float, yaw: float) -> np.ndarray:
    # transform_matrix's array, built once per mount (a rig's sensors ask for theirs every frame)
    m = np.eye(4)
    m[:3, :3] = rotation_matrix(pitch, roll, yaw)
    m[:3, 3] = (x, y, z)
    return m


def yaw_transform(x: float, y: float, yaw_rad: float, z: float = 0.0) -> np.ndarray:
    """4×4 transform of a frame at ``(x, y, z)`` turned by ``yaw_rad`` (radians) about +z."""
    c, s = math.cos(yaw_rad), math.sin(yaw_rad)
    return np.array([[c, -s, 0.0, x], [s, c, 0.0, y], [0.0, 0.0, 1.0, z], [0.0, 0.0, 0.0, 1.0]])


def intrinsic_matrix(width: int, height: int, fov_deg: float) -> np.ndarray:
    """CARLA's pinhole intrinsic: ``f = W / (2 tan(FOV/2))`` for both axes, principal point at the centre."""
    f = width / (2.0 * math.tan(math.radians(fov_deg) / 2.0))
    return np.array([[f, 0.0, width / 2.0], [0.0, f, height / 2.0], [0.0, 0.0, 1.0]])


def world_to_camera(vehicle_to_world: np.ndarray, sensor_to_vehicle: np.ndarray) -> np.ndarray:
    """4×4 matrix taking world points (CARLA frame) to camera-frame points (CV frame)."""
    return SENSOR_TO_CAMERA @ np.linalg.inv(vehicle_to_world @ sensor_to_vehicle)


def lidar_to_camera(lidar_to_vehicle: np.ndarray, camera_to_vehicle: np.ndarray) -> np.ndarray:
    """FogDrive's extrinsic ``E``: LiDAR-frame points to camera-frame (CV) points."""
    return SENSOR_TO_CAMERA @ np.linalg.inv(camera_to_vehicle) @ lidar_to_vehicle


def transform_points(matrix: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Apply a 4×4 transform to ``(..., 3)`` points."""
    points = np.asarray(points, dtype=np.float64)
    return points @ matrix[:3, :3].T + matrix[:3, 3]


def project_points(K: np.ndarray, camera_points: np.ndarray) -> np.ndarray:
    """Pinhole projection of camera-frame points ``(..., 3)`` (z > 0) to pixel coordinates ``(..., 2)``."""
    p = np.asarray(camera_points, dtype=np.float64)
    uv = p @ K.T
    return uv[..., :2] / uv[..., 2:3]


#: Corner order of :func:`box_corners` in the box's own frame (signs of x, y, z half extents).
#: Bottom face first (z−), counter-clockwise seen from above in a right-handed view, then the top face:
#: 0 (+,+,−) front-right-bottom, 1 (+,−,−) front-left-bottom, 2 (−,−,−) rear-left-bottom,
#: 3 (−,+,−) rear-right-bottom, 4–7 the same with z+.
BOX_CORNER_SIGNS = np.array(
    [[1, 1, -1], [1, -1, -1], [-1, -1, -1], [-1, 1, -1], [1, 1, 1], [1, -1, 1], [-1, -1, 1], [-1, 1, 1]],
    dtype=np.float64,
)


def corners_to_boxes(corners: np.ndarray) -> np.ndarray:
    """``(N, 7)`` boxes ``[x, y, z, l, w, h, yaw]`` from corners ``(N, 8, 3)`` in :data:`BOX_CORNER_SIGNS` order
    (the inverse of :func:`box_corners`).

    >>> corners_to_boxes(box_corners([[1.0, 2.0, 0.75]], [[4.0, 2.0, 1.5]], [0.5])).round(6).tolist()
    [[1.0, 2.0, 0.75, 4.0, 2.0, 1.5, 0.5]]
    """
    c = np.asarray(corners, np.float64).reshape(-1, 8, 3)
    length_vec = (c[:, 0] - c[:, 3]) / 2.0  # +x corner minus −x corner, same y and z
    width_vec = (c[:, 0] - c[:, 1]) / 2.0
    out = np.empty((len(c), 7))
    out[:, :3] = c.mean(axis=1)
    out[:, 3] = 2.0 * np.linalg.norm(length_vec, axis=1)
    out[:, 4] = 2.0 * np.linalg.norm(width_vec, axis=1)
    out[:, 5] = c[:, 4, 2] - c[:, 0, 2]
    out[:, 6] = np.arctan2(length_vec[:, 1], length_vec[:, 0])
    return out


def box_corners(centers: np.ndarray, sizes: np.ndarray, yaws: np.ndarray) -> np.ndarray:
    """Corners ``(N, 8, 3)`` of upright boxes from centres ``(N, 3)``, sizes ``(N, 3)`` = (l, w, h), yaws ``(N,)`` rad.

    Corner order is :data:`BOX_CORNER_SIGNS`.
    """
    centers = np.asarray(centers, dtype=np.float64).reshape(-1, 3)
    sizes = np.asarray(sizes, dtype=np.float64).reshape(-1, 3)
    yaws = np.asarray(yaws, dtype=np.float64).reshape(-1)
    local = BOX_CORNER_SIGNS[None] * (sizes[:, None, :] / 2.0)
    c, s = np.cos(yaws)[:, None], np.sin(yaws)[:, None]
    x = local[..., 0] * c - local[..., 1] * s
    y = local[..., 0] * s + local[..., 1] * c
    return np.stack([x, y, local[..., 2]], axis=-1) + centers[:, None, :]


def sensor_to_world(pose: Pose, ego_pose: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> np.ndarray:
    """4×4 sensor→world transform of a sensor mounted at ``pose`` on an ego at ``(x, y, yaw_rad)`` (ground origin).

    >>> sensor_to_world(Pose(0, 0, 2), (10.0, 5.0, 0.0))[:3, 3].tolist()
    [10.0, 5.0, 2.0]
    """
    pose = Pose.coerce(pose)
    return yaw_transform(*ego_pose) @ transform_matrix(pose.location, pose.rotation)


@njit(cache=True, nogil=True)
def polygon_area(poly, n):
    """Area of the first ``n`` vertices of ``poly`` (shoelace; either orientation)."""
    s = 0.0
    for k in range(n):
        k1 = (k + 1) % n
        s += poly[k, 0] * poly[k1, 1] - poly[k1, 0] * poly[k, 1]
    return abs(s) / 2.0

"""The environments' ``render_mode="rgb_array"`` frame: a bird's-eye view of a :class:`~fog_gym.world.scene.Scene`
(road surface, markings, vehicles as boxes) beside the front camera.

:func:`lidar_bev` is the RL presets' LiDAR image (:class:`~fog_gym.wrappers.LidarBEV`).

Example:
    >>> composite(np.zeros((48, 64, 3), np.uint8), np.zeros((96, 96, 3), np.uint8), height=48).shape
    (48, 112, 3)
"""

from __future__ import annotations

import cv2
import numpy as np
from numba import njit

from fog_gym._numba import defer  # (numba's fork-safe threading layer, before any kernel runs)

from fog_gym.geometry import box_corners
from fog_gym.world.scene import Scene
from fog_gym.world.scenery import MARKING, SURFACE_RGB


_BEV_COLORS = np.clip(SURFACE_RGB * 1.0, 0, 255).astype(np.uint8)


def birds_eye_view(scene: Scene, size_px: int = 480, metres: float = 100.0) -> np.ndarray:
    """Top-down RGB view centred on the ego, ego heading up; vehicles as boxes (ego red)."""
    x, y, yaw = scene.ego_pose
    scale = size_px / metres
    # pixel (col, row) -> world: ego heading points up (−row), +y (right of ego) to the right
    c, s = np.cos(yaw), np.sin(yaw)
    cols, rows = np.meshgrid(np.arange(size_px) + 0.5 - size_px / 2, np.arange(size_px) + 0.5 - size_px / 2)
    fwd, right = -rows / scale, cols / scale
    img = _BEV_COLORS[_surface_classes(scene.static.surface, x, y, c, s, fwd, right, metres / size_px)].copy()

    def to_px(pts: np.ndarray) -> np.ndarray:
        d = pts[..., :2] - np.array([x, y])
        f = d[..., 0] * c + d[..., 1] * s
        r = -d[..., 0] * s + d[..., 1] * c
        return np.stack([r * scale + size_px / 2, -f * scale + size_px / 2], -1)

    props = scene.static.props
    if len(props):
        corners = box_corners(props.centers, props.sizes, props.yaws)[:, :4]
        near = np.hypot(props.centers[:, 0] - x, props.centers[:, 1] - y) < metres
        for poly, col in zip(to_px(corners[near]), (props.colors[near] * 255).astype(int)):
            cv2.fillConvexPoly(img, np.round(poly * 16).astype(np.int32), tuple(int(v) for v in col), cv2.LINE_AA, 4)
    v = scene.vehicles
    corners = box_corners(v.centers, v.sizes, v.yaws)[:, :4]
    for i, poly in enumerate(to_px(corners)):
        col = (220, 30, 30) if v.ids[i] == scene.ego_id else (40, 90, 220)
        cv2.fillConvexPoly(img, np.round(poly * 16).astype(np.int32), col, cv2.LINE_AA, 4)
    return img


def _surface_classes(surface, x, y, c, s, fwd, right, px_metres: float) -> np.ndarray:
    """Surface class per BEV pixel; a pixel shows a lane marking if any point of it does.

    A marking (0.15 m) is narrower than a BEV pixel (0.21 m at the default 100 m / 480 px), so sampling pixel
    centres alone loses most of it: each pixel is also sampled on a sub-grid finer than the surface map.
    """
    classes = surface.class_at(x + fwd * c - right * s, y + fwd * s + right * c)
    k = int(np.ceil(px_metres / surface.resolution))
    if k > 1:
        for off in (np.arange(k) + 0.5) / k - 0.5:
            for off2 in (np.arange(k) + 0.5) / k - 0.5:
                f, r = fwd + off * px_metres, right + off2 * px_metres
                hit = surface.class_at(x + f * c - r * s, y + f * s + r * c) == MARKING
                classes[hit] = MARKING
    return classes


def fit_width(img: np.ndarray, width: int) -> np.ndarray:
    h, w = img.shape[:2]
    height = max(1, int(round(h * width / w)))
    return cv2.resize(img, (width, height), interpolation=cv2.INTER_AREA if w > width else cv2.INTER_NEAREST)


def composite(front_rgb: np.ndarray | None, bev: np.ndarray, height: int = 480) -> np.ndarray:
    """Front camera and bird's-eye view side by side, both ``height`` pixels tall."""
    bev = cv2.resize(bev, (height, height), interpolation=cv2.INTER_AREA)
    if front_rgb is None:
        return bev
    h, w = front_rgb.shape[:2]
    front = cv2.resize(front_rgb, (max(1, int(round(w * height / h))), height), interpolation=cv2.INTER_AREA)
    return np.concatenate([front, bev], axis=1)


def lidar_bev(points: np.ndarray, size: int, metres: float, ahead: float = 0.0, sensor_height: float = 2.0) -> np.ndarray:
    """LiDAR points ``(N, ≥3)`` float32 in the sensor frame → ``(2, size, size)`` uint8 bird's-eye image: occupancy
    (255) of the points 0.3–4 m above the road (``z + sensor_height``) and the highest of them (0–255 over 0–4 m).

    The image spans ``metres`` on each side, centred ``ahead`` metres in front of the sensor: a point at (x, y) falls
    in row ``floor((ahead − x)·size/metres + size/2)`` and column ``floor(y·size/metres + size/2)`` (float32 maths).

    >>> img = lidar_bev(np.array([[1.5, -2.5, -1.0], [1.5, -2.5, 0.0], [0.0, 0.0, -1.9]], np.float32), 8, 8.0)
    >>> int(img[0, 2, 1]), int(img[1, 2, 1]), int(img[0].sum() // 255)  # one cell, its highest point 2 m up; the road point left out
    (255, 127, 1)
    """
    pts = np.ascontiguousarray(points, np.float32)
    if pts.ndim != 2 or pts.shape[1] < 3:
        raise ValueError(f"expected LiDAR points of shape (N, >=3), got {pts.shape}")
    img = np.empty((2, int(size), int(size)), np.uint8)  # (zeroed by _bev: numpy's zeros release the GIL)
    f = np.float32
    defer(_bev)(pts, img, f(size / metres), f(size / 2), f(ahead), f(sensor_height))
    return img


@njit(cache=True, nogil=True)
def _bev(pts, img, scale, half, ahead, sensor_height):
    img[:] = 0
    size = img.shape[1]
    lo, hi, four, full = np.float32(0.3), np.float32(4.0), np.float32(4.0), np.float32(255.0)
    for n in range(pts.shape[0]):
        height = pts[n, 2] + sensor_height
        if not (height > lo and height < hi):
            continue
        col = np.int64(np.floor(pts[n, 1] * scale + half))
        row = np.int64(np.floor((ahead - pts[n, 0]) * scale + half))
        if col < 0 or col >= size or row < 0 or row >= size:
            continue
        img[0, row, col] = 255
        h = min(max(height / four * full, np.float32(0.0)), full)
        v = np.uint8(h)
        if v > img[1, row, col]:
            img[1, row, col] = v

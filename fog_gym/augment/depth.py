"""Dense depth for real images: LiDAR points projected with the calibration, completed by a classical CPU method.

**Projection** (:func:`project_points`): points in the LiDAR frame → camera frame with ``T_cam_lidar`` (4 × 4),
kept in front of the camera (z > 0.1 m), projected with ``K``; where several land on one pixel the nearest wins.
The result is a sparse planar-depth map (0 = no return).

**Completion** (:func:`complete_depth`): the "fast" method of Ku, Harakeh and Waslander, "In Defense of Classical
Image Processing: Fast Depth Completion on the CPU" (CRV 2018), written from the paper: depths are inverted
(``D' = D_max − D`` for valid pixels, so that dilation prefers near surfaces), then dilated with a 5 × 5 diamond,
closed with a 5 × 5 full kernel, small holes filled by a 7 × 7 dilation into empty pixels only, large holes by a
31 × 31 one, a 5 × 5 median and a 5 × 5 Gaussian blur on valid pixels, and re-inverted. The paper's optional
extension of each column's top value to the image's top edge is replaced by the sky rule: pixels whose ray points
above the horizon (``sky`` mask: e.g. from :func:`above_horizon`) and that no LiDAR return reaches are sky, at
:data:`SKY_M` (CARLA's far plane, which fog-gym's fog treats as sky).

Example:
    >>> sparse = np.zeros((40, 60), np.float32); sparse[::4, ::4] = 12.0
    >>> dense = complete_depth(sparse)
    >>> bool(np.allclose(dense[4:36, 4:56], 12.0, atol=1e-3))
    True
"""

from __future__ import annotations

import cv2
import numpy as np

#: The depth given to sky pixels [m] (CARLA's far plane; fog-gym's fog treats ≥ 1000 m as sky).
SKY_M = 1000.0
#: The inversion constant of the completion: depths above it are clipped (the paper: 100 m for KITTI's ≤ 80 m).
MAX_DEPTH = 150.0

_DIAMOND_5 = np.array([[0, 0, 1, 0, 0], [0, 1, 1, 1, 0], [1, 1, 1, 1, 1], [0, 1, 1, 1, 0], [0, 0, 1, 0, 0]], np.uint8)
_FULL_5 = np.ones((5, 5), np.uint8)
_FULL_7 = np.ones((7, 7), np.uint8)
_FULL_31 = np.ones((31, 31), np.uint8)


def _check_calibration(K: np.ndarray, T: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None]:
    k = np.asarray(K, np.float64)
    if k.shape != (3, 3) or not np.isfinite(k).all() or k[0, 0] <= 0 or k[1, 1] <= 0:
        raise ValueError(f"K must be a finite 3 × 3 intrinsic matrix with positive focal lengths, got {k.tolist()}")
    if T is None:
        return k, None
    t = np.asarray(T, np.float64)
    if t.shape == (3, 4):
        t = np.vstack([t, [0, 0, 0, 1]])
    if t.shape != (4, 4) or not np.isfinite(t).all():
        raise ValueError(f"T_cam_lidar must be a finite 4 × 4 (or 3 × 4) transform, got shape {t.shape}")
    return k, t


def project_points(points: np.ndarray, K: np.ndarray, T_cam_lidar: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """Sparse planar depth ``(H, W)`` float32 of the LiDAR ``points`` (N, ≥3) in a ``size`` = (W, H) image; 0 where
    no point lands, the nearest where several do."""
    k, t = _check_calibration(K, T_cam_lidar)
    w, h = size
    p = np.asarray(points, np.float64)[:, :3]
    cam = p @ t[:3, :3].T + t[:3, 3]
    z = cam[:, 2]
    front = z > 0.1
    cam, z = cam[front], z[front]
    u = np.floor(k[0, 0] * cam[:, 0] / z + k[0, 2]).astype(np.int64)
    v = np.floor(k[1, 1] * cam[:, 1] / z + k[1, 2]).astype(np.int64)
    inside = (u >= 0) & (u < w) & (v >= 0) & (v < h)
    u, v, z = u[inside], v[inside], z[inside]
    depth = np.full(h * w, np.inf)
    np.minimum.at(depth, v * w + u, z)
    depth[~np.isfinite(depth)] = 0.0
    return depth.reshape(h, w).astype(np.float32)


def above_horizon(K: np.ndarray, T_cam_lidar: np.ndarray, size: tuple[int, int], up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """``(H, W)`` mask of the pixels whose ray points above the horizontal plane of the LiDAR frame (``up`` its
    vertical)."""
    k, t = _check_calibration(K, T_cam_lidar)
    w, h = size
    up_cam = t[:3, :3] @ np.asarray(up, np.float64)  # the LiDAR's up in the camera frame
    xs = (np.arange(w) + 0.5 - k[0, 2]) / k[0, 0]
    ys = (np.arange(h) + 0.5 - k[1, 2]) / k[1, 1]
    return (xs[None, :] * up_cam[0] + ys[:, None] * up_cam[1] + up_cam[2]) > 0


def ground_depth(K: np.ndarray, T_cam_lidar: np.ndarray, size: tuple[int, int], ground_z: float,
                 up=(0.0, 0.0, 1.0)) -> np.ndarray:  # fmt: skip
    """``(H, W)`` planar depth at which each pixel's ray meets the flat ground ``up · p = ground_z`` of the LiDAR
    frame (``inf`` for rays that never do: at or above the horizon)."""
    k, t = _check_calibration(K, T_cam_lidar)
    w, h = size
    inv = np.linalg.inv(t)
    up_l = np.asarray(up, np.float64)
    origin = up_l @ inv[:3, 3]  # the camera's height in the LiDAR frame
    r = inv[:3, :3].T @ up_l  # the ground's normal in the camera frame
    xs = (np.arange(w) + 0.5 - k[0, 2]) / k[0, 0]
    ys = (np.arange(h) + 0.5 - k[1, 2]) / k[1, 1]
    along = xs[None, :] * r[0] + ys[:, None] * r[1] + r[2]  # the ray (x, y, 1)'s rise per metre of planar depth
    with np.errstate(divide="ignore", invalid="ignore"):
        z = (ground_z - origin) / along
    return np.where((along < 0) & (z > 0), z, np.inf).astype(np.float32)


def complete_depth(sparse: np.ndarray, sky: np.ndarray | None = None, max_depth: float = MAX_DEPTH,
                   ground: np.ndarray | None = None) -> np.ndarray:  # fmt: skip
    """Dense planar depth from a sparse map (0 = empty) by Ku et al.'s fast method (module docstring); pixels the
    completion does not reach (no return within its 31-pixel fill) are sky (:data:`SKY_M`) where ``sky`` is set,
    the flat ground's depth where ``ground`` (:func:`ground_depth`) is finite, and otherwise the farthest completed
    depth. Float32, same shape."""
    d0 = np.asarray(sparse, np.float32)
    if d0.ndim != 2 or not np.isfinite(d0).all() or (d0 < 0).any():
        raise ValueError(f"sparse must be a finite (H, W) depth map >= 0 (0 = empty), got shape {d0.shape}")
    for name, m in (("sky", sky), ("ground", ground)):
        if m is not None and np.shape(m) != d0.shape:
            raise ValueError(f"{name} must be a map of the depth map's shape {d0.shape}, got {np.shape(m)}")
    seen = d0 > 0.1
    d = np.where(seen, max_depth - np.minimum(d0, max_depth - 0.5), 0.0).astype(np.float32)
    d = cv2.dilate(d, _DIAMOND_5)
    d = cv2.morphologyEx(d, cv2.MORPH_CLOSE, _FULL_5)
    for kernel in (_FULL_7, _FULL_31):
        empty = d < 0.1
        if not empty.any():
            break
        d = np.where(empty, cv2.dilate(d, kernel), d)
    d = cv2.medianBlur(d, 5)
    valid = d > 0.1
    d = np.where(valid, cv2.GaussianBlur(d, (5, 5), 0), d)
    out = np.where(d > 0.1, max_depth - d, 0.0).astype(np.float32)
    reached = cv2.dilate(seen.astype(np.uint8), _FULL_7) > 0  # within reach of a return: the completion stands
    open_ = ~reached if sky is not None or ground is not None else out < 0.1
    if sky is not None:
        s = np.asarray(sky, bool) & open_
        out = np.where(s, SKY_M, out)
        open_ &= ~s
    if ground is not None:
        g = np.asarray(ground, np.float32)
        use = open_ & np.isfinite(g)
        out = np.where(use, np.minimum(g, SKY_M), out)
        open_ &= ~use
    empty = (out < 0.1) & open_
    if empty.any():
        done = (out > 0.1) & (out < SKY_M)
        out = np.where(empty, out[done].max() if done.any() else SKY_M, out)
    return out.astype(np.float32)

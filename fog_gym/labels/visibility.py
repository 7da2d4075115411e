"""Visibility labels a perception study filters on under fog: how many LiDAR and radar points fall in each 3D box
(nuScenes' ``num_lidar_pts`` / ``num_radar_pts``), and whether each 2D box stands out from its background by the
5 % contrast that defines visibility. Pure numpy; nothing here imports the environment.

* :func:`points_in_boxes`: points ``(N, ≥3)`` inside each upright box (centre, size l × w × h, yaw; one frame);
* :func:`radar_xyz`: a radar channel's detections (velocity, azimuth, altitude, depth) as points of its frame;
* :func:`box_contrast`: a 2D box's intrinsic Weber contrast in the clean image — the mean luminance of its vehicle's
  own pixels (the instance buffer) against the other pixels of the box grown by half its size, ``(L_o − L_b) / L_b``;
* :func:`perceivable`: Koschmieder's law for the box's apparent contrast at its range, ``C = C₀ · e^{−τ}`` (τ the
  fog's optical depth from the camera to the box: the camera's one-way transmittance), above
  :data:`CONTRAST_THRESHOLD` — the 5 % contrast on which the visibility of fog levels is defined.

Example:
    >>> pts = np.array([[10.0, 0.2, 0.5], [10.0, 3.0, 0.5], [30.0, 0.0, 0.0]])
    >>> points_in_boxes(pts, np.array([[10.0, 0.0, 0.75]]), np.array([[4.0, 2.0, 1.5]]), np.zeros(1)).tolist()
    [1]
    >>> perceivable(np.array([0.4, 0.4, -0.02]), np.array([0.2, 0.1, 1.0])).tolist()
    [True, False, False]
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: The apparent contrast below which a box is not perceivable (Koschmieder's 5 % threshold of visibility).
CONTRAST_THRESHOLD = 0.05
_LUMA = np.array([0.2126, 0.7152, 0.0722])


def points_in_boxes(points: np.ndarray, centers: np.ndarray, sizes: np.ndarray, yaws: np.ndarray,
                    margin: float = 0.0) -> np.ndarray:  # fmt: skip
    """How many of ``points`` (N, ≥3) lie in each upright box (centre (B, 3), size (B, 3) = l, w, h, yaw (B,); one
    frame for all), each box grown by ``margin`` metres on every side.

    >>> points_in_boxes(np.array([[0.0, 0, 0], [2.1, 0, 0], [0, 0.95, 0]]), np.zeros((1, 3)), np.array([[4.0, 2, 2]]),
    ...                 np.zeros(1)).tolist()
    [2]
    """
    p = np.asarray(points, np.float64).reshape(-1, max(3, np.shape(points)[-1] if np.ndim(points) == 2 else 3))[:, :3]
    centers = np.asarray(centers, np.float64).reshape(-1, 3)
    sizes = np.asarray(sizes, np.float64).reshape(-1, 3) + 2.0 * margin
    yaws = np.asarray(yaws, np.float64).reshape(-1)
    if len(centers) == 0 or len(p) == 0:
        return np.zeros(len(centers), np.int64)
    return _count_in_boxes(np.ascontiguousarray(p), centers, sizes, yaws)


@njit(cache=True, nogil=True)
def _count_in_boxes(p, centers, sizes, yaws):
    """Points per box: a box's bounding square rejects most points before its rotated test (the rule above)."""
    nb = centers.shape[0]
    counts = np.zeros(nb, np.int64)
    cs, sn, reach = np.cos(yaws), np.sin(yaws), np.empty(nb)
    for k in range(nb):
        reach[k] = 0.5 * math.hypot(sizes[k, 0], sizes[k, 1])
    lo_x, hi_x = (centers[:, 0] - reach).min(), (centers[:, 0] + reach).max()
    lo_y, hi_y = (centers[:, 1] - reach).min(), (centers[:, 1] + reach).max()
    for i in range(p.shape[0]):
        px, py, pz = p[i, 0], p[i, 1], p[i, 2]
        if px < lo_x or px > hi_x or py < lo_y or py > hi_y:
            continue
        for k in range(nb):
            dx, dy = px - centers[k, 0], py - centers[k, 1]
            if abs(dx) > reach[k] or abs(dy) > reach[k]:
                continue
            x = dx * cs[k] + dy * sn[k]
            y = -dx * sn[k] + dy * cs[k]
            if abs(x) <= sizes[k, 0] / 2 and abs(y) <= sizes[k, 1] / 2 and abs(pz - centers[k, 2]) <= sizes[k, 2] / 2:
                counts[k] += 1
    return counts


def radar_xyz(detections: np.ndarray) -> np.ndarray:
    """``(N, 3)`` points of radar detections ``(N, 4)`` — velocity, azimuth (positive to the right), altitude,
    depth — in the radar's frame (x forward, y right, z up)."""
    d = np.asarray(detections, np.float64).reshape(-1, 4)
    az, alt, r = d[:, 1], d[:, 2], d[:, 3]
    return np.c_[r * np.cos(alt) * np.cos(az), r * np.cos(alt) * np.sin(az), r * np.sin(alt)]


def box_contrast(rgb: np.ndarray, instance: np.ndarray, bboxes: np.ndarray, ids: np.ndarray) -> np.ndarray:
    """Each 2D box's intrinsic Weber contrast (module docstring); 0 where the box shows none of its vehicle or has
    no background around it. ``bboxes`` (M, 2, 2) inclusive pixel corners, ``ids`` the vehicles' instance ids."""
    img = np.asarray(rgb)
    inst = np.asarray(instance)
    h, w = inst.shape
    out = np.zeros(len(ids))
    for k, ((x0, y0), (x1, y1)) in enumerate(np.asarray(bboxes, np.int64).reshape(-1, 2, 2)):
        gx, gy = (x1 - x0 + 1) // 2, (y1 - y0 + 1) // 2
        a0, b0, a1, b1 = max(0, x0 - gx), max(0, y0 - gy), min(w - 1, x1 + gx), min(h - 1, y1 + gy)
        region = inst[b0 : b1 + 1, a0 : a1 + 1]
        luma = img[b0 : b1 + 1, a0 : a1 + 1].astype(np.float64) @ _LUMA
        own = region == ids[k]
        if not own.any() or own.all():
            continue
        l_o, l_b = luma[own].mean(), luma[~own].mean()
        out[k] = (l_o - l_b) / max(l_b, 1.0)
    return out


def perceivable(contrast: np.ndarray, transmittance: np.ndarray, threshold: float = CONTRAST_THRESHOLD) -> np.ndarray:
    """Whether each box's apparent contrast ``|C₀| · t`` reaches ``threshold`` (module docstring)."""
    return np.abs(np.asarray(contrast, np.float64)) * np.asarray(transmittance, np.float64) >= threshold

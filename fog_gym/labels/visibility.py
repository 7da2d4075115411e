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

#: The apparent contrast below which a box is not perceivable (Koschmieder's 5 % threshold of visibility).
CONTRAST_THRESHOLD = 0.05
_LUMA = np.array([0.2126, 0.7152, 0.0722])


def points_in_boxes(points: np.ndarray, centers: np.ndarray, sizes: np.ndarray, yaws: np.ndarray,
                    margin: float = 0.0) -> np.ndarray:  # fmt: skip
    """How many of ``points`` (N, ≥3) lie in each upright box (centre (B, 3), size (B, 3) = l, w, h, yaw (B,); one
    frame for all), each box grown by ``margin`` metres on every side."""
    p = np.asarray(points, np.float64).reshape(-1, max(3, np.shape(points)[-1] if np.ndim(points) == 2 else 3))[:, :3]
    centers = np.asarray(centers, np.float64).reshape(-1, 3)
    sizes = np.asarray(sizes, np.float64).reshape(-1, 3) + 2.0 * margin
    yaws = np.asarray(yaws, np.float64).reshape(-1)
    counts = np.zeros(len(centers), np.int64)
    for k, (c, size, yaw) in enumerate(zip(centers, sizes, yaws)):
        near = np.abs(p[:, :2] - c[:2]).max(axis=1) <= 0.5 * math.hypot(size[0], size[1])
        d = p[near] - c
        cs, sn = math.cos(yaw), math.sin(yaw)
        x, y = d[:, 0] * cs + d[:, 1] * sn, -d[:, 0] * sn + d[:, 1] * cs
        counts[k] = int(((np.abs(x) <= size[0] / 2) & (np.abs(y) <= size[1] / 2) & (np.abs(d[:, 2]) <= size[2] / 2)).sum())
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

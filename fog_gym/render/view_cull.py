"""Which boxes some camera of a level rig can see in the ground plane: a box is kept unless its bounding circle lies
wholly outside every camera's horizontal field of view (:meth:`fog_gym.sensors.camera.CameraRig.primitives` culls
the static props with it before the raster).

Each camera is a row ``(x, y, yaw, half)`` of ``views``: its place and heading on the ego (metres, radians) and half
its horizontal field of view plus a margin. A box at distance ``d`` from a camera, of bounding radius ``r``, is kept
when ``d ≤ r`` or when its bearing lies within ``θ = half + 10⁻³ + asin(r / d)`` of the camera's heading. Without
an angle: for ``θ < π`` the bearing's cosine ``(δ · a) / d`` (``δ`` the offset to the box, ``a`` the heading's unit
vector) is at least ``cos θ = cos H · √(d² − r²)/d − sin H · r/d`` (``H = half + 10⁻³``), so the test is
``δ · a ≥ cos H · √(d² − r²) − sin H · r``: one square root per box and camera, where the bearing and the margin
took an arctangent and an arcsine (the same decisions but where a box's circle touches the view's edge to rounding
— a box that the margin beyond the field of view keeps either way). One pass over the boxes that stops at the first
camera that sees a box.

Example:
    >>> views = np.array([[1.5, 0.0, 0.0, np.radians(35.0)]])  # one camera looking ahead, 70° wide
    >>> centers = np.array([[30.0, 0.0, 1.0], [-30.0, 0.0, 1.0], [1.0, 0.5, 1.0]])
    >>> in_views(centers, np.array([2.0, 2.0, 2.0]), (0.0, 0.0, 0.0), views).tolist()  # ahead, behind, on the camera
    [True, False, True]
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

import fog_gym._numba  # noqa: F401  (numba's fork-safe threading layer, before any kernel runs)


def in_views(centers: np.ndarray, radius: np.ndarray, ego_pose: tuple[float, float, float],
             views: np.ndarray) -> np.ndarray:  # fmt: skip
    """Boolean ``(N,)``: which boxes (centres ``(N, 2+)``, bounding radii ``(N,)``) some camera of ``views``
    (``(K, 4)``, module docstring) of an ego at ``ego_pose`` ``(x, y, yaw)`` can see."""
    centers = np.ascontiguousarray(centers, np.float64)
    radius = np.ascontiguousarray(radius, np.float64)
    views = np.ascontiguousarray(views, np.float64).reshape(-1, 4)
    if centers.ndim != 2 or centers.shape[1] < 2 or radius.shape != (len(centers),):
        raise ValueError(f"in_views needs centres (N, 2+) and radii (N,), got {centers.shape} and {radius.shape}")
    keep = np.empty(len(centers), np.bool_)
    _in_views(centers, radius, view_table(ego_pose, views), keep)
    return keep


def view_table(ego_pose: tuple[float, float, float], views: np.ndarray) -> np.ndarray:
    """``(K, 7)``: per camera of ``views`` on an ego at ``ego_pose``, what the test reads — its place ``x, y`` in the
    world, its heading's cosine and sine, ``cos H``, ``sin H`` and whether ``H ≥ π`` (every bearing in view)."""
    views = np.ascontiguousarray(views, np.float64).reshape(-1, 4)
    ex, ey, eyaw = (float(v) for v in ego_pose)
    c, s = math.cos(eyaw), math.sin(eyaw)
    k = len(views)
    angles = np.concatenate((eyaw + views[:, 2], views[:, 3] + 1e-3))  # headings, then H (numpy's cos and sin)
    cos, sin = np.cos(angles).tolist(), np.sin(angles).tolist()
    cams = np.empty((k, 7))
    for v, (x, y, _, half) in enumerate(views.tolist()):
        cams[v] = (ex + c * x - s * y, ey + s * x + c * y, cos[v], sin[v], cos[k + v], sin[k + v],
                   float(half + 1e-3 >= np.pi))  # fmt: skip
    return cams


@njit(cache=True, nogil=True)
def _in_views(centers, radius, cams, keep):
    # cams: view_table's rows
    for i in range(centers.shape[0]):
        keep[i] = _sees(centers[i, 0], centers[i, 1], radius[i], cams)


@njit(cache=True, inline="always")
def _sees(x, y, r, cams):
    # whether some camera of cams (view_table) sees the circle of radius r about (x, y): the first that does decides
    for v in range(cams.shape[0]):
        dx, dy = x - cams[v, 0], y - cams[v, 1]
        d2 = dx * dx + dy * dy
        if d2 <= r * r or cams[v, 6] != 0.0:
            return True
        # θ ≥ π (nothing out of view) only when H > π/2 and asin(r/d) ≥ π − H, i.e. r/d ≥ sin H
        wide = cams[v, 4] < 0.0 and r >= cams[v, 5] * math.sqrt(d2)
        if wide or dx * cams[v, 2] + dy * cams[v, 3] >= cams[v, 4] * math.sqrt(d2 - r * r) - cams[v, 5] * r:
            return True
    return False

"""Dense depth for real images: LiDAR points projected with the calibration, completed by a classical CPU method.

**Projection** (:func:`project_points`): points in the LiDAR frame → camera frame with ``T_cam_lidar`` (4 × 4),
kept in front of the camera (z > 0.1 m), projected with ``K``; where several land on one pixel the nearest wins.
The result is a sparse planar-depth map (0 = no return).

**Completion** (:func:`complete_depth`): the "fast" method of Ku, Harakeh and Waslander, "In Defense of Classical
Image Processing: Fast Depth Completion on the CPU" (CRV 2018), written from the paper: depths are inverted
(``D' = D_max − D`` for valid pixels, so that dilation prefers near surfaces), then dilated with a 5 × 5 diamond,
closed with a 5 × 5 full kernel, small holes filled by a 7 × 7 dilation into empty pixels only, large holes by a
31 × 31 one, a 5 × 5 median and a 5 × 5 Gaussian blur on valid pixels, and re-inverted.

**Above the scan** a LiDAR leaves the image's upper rows empty: its top beam passes under tree crowns, building
fronts and poles. The paper extends each column's top value to the image's top edge ("to account for tall objects
such as trees, poles and buildings that extend above the top of the LiDAR points"), which also puts the sky at the
depth of whatever is below it. fog-gym splits the empty pixels above the LiDAR's horizontal plane in two:

* the **sky** (:func:`sky_mask`, from the image): the smooth regions that touch the image's top edge and have the
  colour of the largest of them — smooth meaning no 4-neighbour differs by more than ``tau`` levels in any channel,
  ``tau`` four standard deviations of a difference of two pixels' noise (after Immerkær, :func:`noise_sigma`) and at
  least 3 — closed by a 5 × 5 kernel (stars, the moon, thin wires). Sky is at :data:`SKY_M` (CARLA's far plane,
  which fog-gym's fog treats as sky);
* the rest is an object above the scan and takes the paper's **extension**: the depth of the nearest completed
  pixel below it in its column (:func:`extend_up`).

``sky="horizon"`` keeps the simpler rule without the image: every empty pixel above the horizontal plane is sky.
Checked on fog-gym's frames (``docs/augment.md``), objects above the scan taken as sky were 94 % of the squared
error of the fogged image at light fog; the image's sky lifts its PSNR from 24.8 to 31.7 dB.

Example:
    >>> sparse = np.zeros((40, 60), np.float32); sparse[::4, ::4] = 12.0
    >>> dense = complete_depth(sparse)
    >>> bool(np.allclose(dense[4:36, 4:56], 12.0, atol=1e-3))
    True
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numba import njit

import fog_gym._numba  # noqa: F401  (numba's fork-safe threading layer, before any kernel runs)

#: The depth given to sky pixels [m] (CARLA's far plane; fog-gym's fog treats ≥ 1000 m as sky).
SKY_M = 1000.0
#: The inversion constant of the completion: depths above it are clipped (the paper: 100 m for KITTI's ≤ 80 m).
MAX_DEPTH = 150.0

_DIAMOND_5 = np.array([[0, 0, 1, 0, 0], [0, 1, 1, 1, 0], [1, 1, 1, 1, 1], [0, 1, 1, 1, 0], [0, 0, 1, 0, 0]], np.uint8)
_FULL_5 = np.ones((5, 5), np.uint8)
_FULL_7 = np.ones((7, 7), np.uint8)
_FULL_31 = np.ones((31, 31), np.uint8)
#: The sky rules of :func:`fog_gym.augment.image_depth` (module docstring).
SKY_RULES = ("image", "horizon")
#: Largest difference [levels, any channel] between a sky region's mean colour and the main sky's.
SKY_COLOUR_TOLERANCE = 20.0


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


def check_sky_rule(sky: str) -> str:
    """``sky`` if it is one of :data:`SKY_RULES`, else a ``ValueError`` naming them."""
    if sky not in SKY_RULES:
        raise ValueError(f"sky must be one of {SKY_RULES}, got {sky!r}")
    return sky


def reached_by_scan(sparse: np.ndarray) -> np.ndarray:
    """``(H, W)`` mask of the pixels within reach of a return (a 7 × 7 neighbourhood): where the completion stands."""
    return cv2.dilate((np.asarray(sparse) > 0.1).astype(np.uint8), _FULL_7) > 0


def complete_depth(sparse: np.ndarray, sky: np.ndarray | None = None, max_depth: float = MAX_DEPTH,
                   ground: np.ndarray | None = None, extend: np.ndarray | None = None) -> np.ndarray:  # fmt: skip
    """Dense planar depth from a sparse map (0 = empty) by Ku et al.'s fast method (module docstring); pixels the
    completion does not reach (no return within its 7-pixel fill: :func:`reached_by_scan`) are sky
    (:data:`SKY_M`) where ``sky`` is set, the flat ground's depth where ``ground`` (:func:`ground_depth`) is
    finite, the depth of the nearest pixel below them in their column where ``extend`` is set (Ku et al.'s
    extension, :func:`extend_up`), and otherwise the farthest completed depth. Float32, same shape.

    >>> sparse = np.zeros((40, 60), np.float32); sparse[30:, ::3] = 8.0  # a wall seen only in its lower rows
    >>> above = np.zeros((40, 60), bool); above[:20] = True
    >>> sky = above & (np.arange(60) >= 30)  # the sky over the wall's right half; its left half rises above the scan
    >>> d = complete_depth(sparse, sky, extend=above)
    >>> float(d[0, 10]), float(d[0, 50]), float(d[35, 10])
    (8.0, 1000.0, 8.0)
    """
    d0 = np.asarray(sparse, np.float32)
    if d0.ndim != 2 or not np.isfinite(d0).all() or (d0 < 0).any():
        raise ValueError(f"sparse must be a finite (H, W) depth map >= 0 (0 = empty), got shape {d0.shape}")
    for name, m in (("sky", sky), ("ground", ground), ("extend", extend)):
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
    rules = sky is not None or ground is not None or extend is not None
    open_ = ~reached_by_scan(d0) if rules else out < 0.1
    if sky is not None:
        s = np.asarray(sky, bool) & open_
        out = np.where(s, SKY_M, out)
        open_ &= ~s
    if ground is not None:
        g = np.asarray(ground, np.float32)
        use = open_ & np.isfinite(g)
        out = np.where(use, np.minimum(g, SKY_M), out)
        open_ &= ~use
    if extend is not None:
        e = np.asarray(extend, bool) & open_
        out = extend_up(out, e)
        open_ &= ~e | (out < 0.1)  # a column with nothing below stays open
    empty = (out < 0.1) & open_
    if empty.any():
        done = (out > 0.1) & (out < SKY_M)
        out = np.where(empty, out[done].max() if done.any() else SKY_M, out)
    return out.astype(np.float32)


def extend_up(depth: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """``depth`` with each ``mask`` pixel set to the value of the nearest pixel below it in its column that is not in
    ``mask`` (0 where there is none): Ku et al.'s extension of a column's top value upward.

    >>> d = np.array([[0.0, 0.0], [0.0, 5.0], [3.0, 4.0]], np.float32)
    >>> extend_up(d, np.array([[True, True], [True, False], [False, False]])).tolist()
    [[3.0, 5.0], [3.0, 5.0], [3.0, 4.0]]
    """
    d = np.ascontiguousarray(depth, np.float32)
    m = np.ascontiguousarray(mask, bool)
    if d.ndim != 2 or m.shape != d.shape:
        raise ValueError(f"depth must be an (H, W) map and mask of its shape, got {d.shape} and {m.shape}")
    return _extend_up(d, m, np.empty_like(d))


@njit(cache=True, nogil=True)
def _extend_up(d, m, out):
    h, w = d.shape
    carried = np.zeros(w, np.float32)
    for i in range(h - 1, -1, -1):
        for j in range(w):
            if m[i, j]:
                out[i, j] = carried[j]
            else:
                out[i, j] = d[i, j]
                carried[j] = d[i, j]
    return out


def noise_sigma(rgb: np.ndarray, mask: np.ndarray | None = None) -> float:
    """The image's noise standard deviation [levels, the noisiest channel], from Immerkær's Laplacian difference
    mask ("Fast Noise Variance Estimation", CVIU 64(2), 1996): ``[[1, −2, 1], [−2, 4, −2], [1, −2, 1]]`` responds to
    noise of σ with ``N(0, 36 σ²)`` and to a plane not at all. Immerkær takes the mean absolute response over the
    image; this takes the median over ``mask`` (``σ = median |r| / (6 · 0.6745)``; e.g. the candidates for sky), so
    that edges and a little texture do not count as noise.

    >>> rng = np.random.default_rng(0)
    >>> img = np.clip(128 + rng.normal(0, 5, (200, 200, 3)), 0, 255).astype(np.uint8)
    >>> round(noise_sigma(img))
    5
    """
    img = np.asarray(rgb)
    if img.ndim == 2:
        img = img[:, :, None]
    if img.ndim != 3 or img.shape[0] < 3 or img.shape[1] < 3:
        return 0.0
    r = _laplacian_abs(np.ascontiguousarray(img))
    if mask is not None:
        r = r[:, np.asarray(mask, bool)[1:-1, 1:-1]]
    return float(np.median(r.reshape(len(r), -1), axis=1).max() / (6.0 * 0.6745)) if r[0].size else 0.0


@njit(cache=True, nogil=True)
def _laplacian_abs(img):
    """``(C, H − 2, W − 2)`` absolute responses of Immerkær's mask on each channel."""
    h, w, nc = img.shape
    out = np.empty((nc, h - 2, w - 2), np.float32)
    for c in range(nc):
        for i in range(1, h - 1):
            for j in range(1, w - 1):
                corners = (np.float32(img[i - 1, j - 1, c]) + np.float32(img[i - 1, j + 1, c])
                           + np.float32(img[i + 1, j - 1, c]) + np.float32(img[i + 1, j + 1, c]))  # fmt: skip
                sides = (np.float32(img[i - 1, j, c]) + np.float32(img[i + 1, j, c])
                         + np.float32(img[i, j - 1, c]) + np.float32(img[i, j + 1, c]))  # fmt: skip
                out[c, i - 1, j - 1] = abs(corners - 2.0 * sides + 4.0 * np.float32(img[i, j, c]))
    return out


def sky_mask(rgb: np.ndarray, candidates: np.ndarray, tau: float | None = None,
             colour_tolerance: float = SKY_COLOUR_TOLERANCE) -> np.ndarray:  # fmt: skip
    """``(H, W)`` mask of the sky among ``candidates`` (the empty pixels above the horizon): the smooth regions
    (no 4-neighbour more than ``tau`` levels apart in any channel; ``tau`` defaults to ``max(3, 4√2 σ)``, σ the
    noise over the candidates by :func:`noise_sigma`: a difference of two noisy pixels crosses it once in 16 000)
    that touch the image's top row and whose mean colour is within ``colour_tolerance`` levels (every channel) of
    the largest such region's, closed by a 5 × 5 kernel within ``candidates``.

    >>> img = np.zeros((30, 40, 3), np.uint8); img[:] = (120, 160, 220)  # a blue sky
    >>> img[:, 25:] = (150, 90, 60)  # a brown wall reaching the top edge, with windows
    >>> img[5:8, 30:33] = 40
    >>> sky = sky_mask(img, np.ones((30, 40), bool))
    >>> bool(sky[:, :24].all()), bool(sky[:, 25:].any())
    (True, False)
    """
    img = np.asarray(rgb)
    cand = np.asarray(candidates, bool)
    if img.ndim != 3 or img.shape[2] != 3 or img.shape[:2] != cand.shape:
        raise ValueError(f"rgb must be an (H, W, 3) image of the candidates' shape {cand.shape}, got {img.shape}")
    h, w = cand.shape
    t = max(3.0, 4.0 * math.sqrt(2.0) * noise_sigma(img, cand)) if tau is None else float(tau)
    smooth = _smooth(np.ascontiguousarray(img), np.ascontiguousarray(cand), t, np.empty((h, w), np.uint8))
    n, labels, stats, _ = cv2.connectedComponentsWithStats(smooth, connectivity=4)
    top = np.unique(labels[0][labels[0] > 0])
    if len(top) == 0:
        return np.zeros((h, w), bool)
    mean = _label_sums(labels, np.ascontiguousarray(img), n) / np.maximum(stats[:, cv2.CC_STAT_AREA], 1)[:, None]
    main = top[np.argmax(stats[top, cv2.CC_STAT_AREA])]
    keep = np.zeros(n, bool)
    keep[top[np.abs(mean[top] - mean[main]).max(axis=1) <= colour_tolerance]] = True
    sky = keep[labels]
    return (cv2.morphologyEx(sky.astype(np.uint8), cv2.MORPH_CLOSE, _FULL_5) > 0) & cand


@njit(cache=True, nogil=True)
def _smooth(img, cand, tau, out):
    """1 where ``cand`` and no 4-neighbour differs by more than ``tau`` in any channel, else 0."""
    h, w, _ = img.shape
    for i in range(h):
        for j in range(w):
            ok = cand[i, j]
            if ok:
                for di, dj in ((0, 1), (0, -1), (1, 0), (-1, 0)):
                    a, b = i + di, j + dj
                    if 0 <= a < h and 0 <= b < w:
                        for c in range(3):
                            if abs(np.int16(img[i, j, c]) - np.int16(img[a, b, c])) > tau:
                                ok = False
            out[i, j] = 1 if ok else 0
    return out


@njit(cache=True, nogil=True)
def _label_sums(labels, img, n):
    """``(n, 3)`` sums of each label's pixel colours."""
    out = np.zeros((n, 3))
    h, w = labels.shape
    for i in range(h):
        for j in range(w):
            k = labels[i, j]
            for c in range(3):
                out[k, c] += img[i, j, c]
    return out

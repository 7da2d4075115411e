"""Koschmieder fog for camera images, implemented from the equations (research note ``fog_physics.md`` §1).

``I = J·t + A·(1 − t)``, ``t = exp(−α·ℓ)`` with ℓ the Euclidean distance of each pixel (from planar depth and the
intrinsics) and ``A`` the atmospheric light (dark channel 15×15, top 0.1 %, median grey); at night ``A`` comes
from the lit surroundings (:func:`night_airlight`) and lit fog glows around bright sources (:func:`add_glow`).

Example:
    >>> from fog_gym.fog.physics import parse_fog
    >>> img = fog_image(np.zeros((2, 2, 3), np.uint8), np.full((2, 2), 1000.0, np.float32), np.eye(3),
    ...                 parse_fog("dense").alpha, np.full(3, 200.0))
    >>> int(img.max())  # the sky takes the airlight
    200
"""

from __future__ import annotations

import math
import threading
from collections.abc import Sequence

import cv2
import numpy as np
from numba import njit, prange

import fog_gym._numba  # noqa: F401  (numba's fork-safe threading layer, before any kernel runs)
from fog_gym._numba import pick, serial_twin

def ray_length_factor(width: int, height: int, K: np.ndarray) -> np.ndarray:
    """Per-pixel ``ℓ / z`` = ``sqrt(1 + ((u − cx)/fx)² + ((v − cy)/fy)²)`` at pixel centres, float32 ``(H, W)``."""
    u = (np.arange(width) + 0.5 - K[0, 2]) / K[0, 0]
    v = (np.arange(height) + 0.5 - K[1, 2]) / K[1, 1]
    return np.sqrt(1.0 + u[None, :] ** 2 + v[:, None] ** 2).astype(np.float32)


def atmospheric_light(rgb: np.ndarray, window: int = 15, top_fraction: float = 0.001) -> np.ndarray:
    """Atmospheric light ``A`` (RGB, 0–255 floats) of a clear image: dark channel (``window``² erosion, channel
    minimum), the top ``top_fraction`` of its pixels (count forced odd), and the RGB of the one with median grey.
    """
    img = np.ascontiguousarray(rgb)
    if img.ndim != 3 or img.shape[2] != 3:
        raise ValueError(f"expected an (H, W, 3) RGB image, got shape {img.shape}")
    channels = cv2.split(img)
    dark = cv2.erode(cv2.min(cv2.min(channels[0], channels[1]), channels[2]), np.ones((window, window), np.uint8))
    k = max(1, int(math.floor(top_fraction * dark.size)))
    k += 1 - k % 2
    flat = dark.reshape(-1)
    # the k brightest dark-channel pixels: all above a threshold value, then ties in raster order
    counts = np.bincount(flat, minlength=256)
    above = np.cumsum(counts[::-1])[::-1]  # pixels >= value
    threshold = int(np.nonzero(above >= k)[0].max())
    strictly = np.flatnonzero(flat > threshold)
    ties = np.flatnonzero(flat == threshold)[: k - len(strictly)]
    top = np.concatenate([strictly, ties])
    pixels = img.reshape(-1, 3)[top].astype(np.float64)
    grey = pixels @ np.array([0.2989, 0.5870, 0.1140])
    return pixels[np.argsort(grey, kind="stable")[k // 2]]


#: Night airlight: pixels nearer than this [m] light the fog; their ``NIGHT_AIRLIGHT_PERCENTILE`` colour is ``A``.
NIGHT_AIRLIGHT_RANGE, NIGHT_AIRLIGHT_PERCENTILE = 30.0, 75.0
#: Glow: sources are pixels at or above ``GLOW_THRESHOLD`` (any channel, 0–255), taken at ``GLOW_SOURCE_GAIN`` ×
#: their 8-bit value (a clipped lamp is far brighter than white); ``GLOW_FORWARD`` of the light they lose to fog
#: is scattered forwards into a Gaussian of angular width ``GLOW_WIDTH_RAD · (1 + α · GLOW_DISTANCE)``.
GLOW_THRESHOLD, GLOW_SOURCE_GAIN, GLOW_FORWARD = 240, 12.0, 0.5
GLOW_WIDTH_RAD, GLOW_DISTANCE = math.radians(0.6), 50.0


def night_airlight(rgb: np.ndarray, depth: np.ndarray, max_range: float = NIGHT_AIRLIGHT_RANGE) -> np.ndarray:
    """Atmospheric light of a night frame: the fog is lit like the surfaces around the camera.

    At night there is no bright sky to take ``A`` from (the dark-channel estimate would pick a lamp head); the
    droplets near the camera are lit by the same lamps and beams as the surfaces there, so ``A`` is the
    ``NIGHT_AIRLIGHT_PERCENTILE`` colour of the pixels nearer than ``max_range`` (all pixels if none are).

    >>> rgb = np.zeros((2, 2, 3), np.uint8); rgb[0] = 80
    >>> night_airlight(rgb, np.array([[10.0, 10.0], [500.0, 500.0]], np.float32)).tolist()
    [80.0, 80.0, 80.0]
    """
    img = np.asarray(rgb)
    if img.ndim != 3 or img.shape[2] != 3 or np.shape(depth) != img.shape[:2]:
        raise ValueError(f"rgb must be (H, W, 3) and depth (H, W), got {img.shape} and {np.shape(depth)}")
    near = np.asarray(depth) < max_range
    pixels = img[near] if near.any() else img.reshape(-1, 3)
    if pixels.dtype != np.uint8:
        return np.percentile(pixels.astype(np.float64), NIGHT_AIRLIGHT_PERCENTILE, axis=0)
    # np.percentile's linear rule from the channels' 256-bin counts (no sort): the order statistics at
    # floor(q·(n − 1)) and the next one, interpolated by the fraction
    pos = NIGHT_AIRLIGHT_PERCENTILE / 100.0 * (len(pixels) - 1)
    lo, frac = int(math.floor(pos)), pos - math.floor(pos)
    out = np.empty(3)
    for ch in range(3):
        cum = np.cumsum(np.bincount(pixels[:, ch], minlength=256))
        a, b = np.searchsorted(cum, [lo + 1, min(lo + 2, len(pixels))]).astype(np.float64)
        out[ch] = b - (b - a) * (1.0 - frac) if frac >= 0.5 else a + (b - a) * frac
    return out


def glow_sigma_px(K: np.ndarray, alpha: float) -> float:
    """Width (pixels) of the glow around a bright source: ``fx · tan(GLOW_WIDTH_RAD · (1 + α · GLOW_DISTANCE))``."""
    return float(K[0, 0] * math.tan(GLOW_WIDTH_RAD * (1.0 + alpha * GLOW_DISTANCE)))


#: The glow is blurred on a grid ``f`` times coarser than the image, ``f`` the largest integer that keeps at least
#: ``GLOW_CELLS_PER_SIGMA`` cells per σ (``f = 1``, the image itself, for a narrow glow).
GLOW_CELLS_PER_SIGMA = 2.5


def glow_factor(sigma: float) -> int:
    """The coarse grid's factor for a glow of width ``sigma`` px: ``max(1, ⌊σ / GLOW_CELLS_PER_SIGMA⌋)``.

    >>> [glow_factor(s) for s in (3.0, 10.9, 14.1, 22.5)]
    [1, 4, 5, 9]
    """
    return max(1, int(sigma // GLOW_CELLS_PER_SIGMA))


def glow_sources(clean: np.ndarray, depth: np.ndarray, K: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The glow's sources in a clean frame: pixels with a channel at or above ``GLOW_THRESHOLD``, as their rows,
    columns, RGB (float32, (N, 3)) and ray distance ℓ [m] (float32), in raster order. One scan serves every fog level.

    >>> clean = np.zeros((3, 4, 3), np.uint8); clean[1, 2] = (250, 10, 10)
    >>> r, c, rgb, ell = glow_sources(clean, np.full((3, 4), 10.0, np.float32), np.array([[1e6, 0, 2], [0, 1e6, 1.5], [0, 0, 1]]))
    >>> r.tolist(), c.tolist(), rgb.tolist(), ell.round(3).tolist()
    ([1], [2], [[250.0, 10.0, 10.0]], [10.0])
    """
    h, w = depth.shape
    flat = np.ascontiguousarray(clean).reshape(-1)
    hits = np.flatnonzero(flat >= GLOW_THRESHOLD) // 3
    if len(hits) > 1:
        hits = hits[np.r_[True, hits[1:] != hits[:-1]]]  # a pixel with two or three bright channels counts once
    rows, cols = np.divmod(hits, w)
    u = (cols + 0.5 - K[0, 2]) / K[0, 0]
    v = (rows + 0.5 - K[1, 2]) / K[1, 1]
    ell = (depth.reshape(-1)[hits] * np.sqrt(1.0 + u * u + v * v)).astype(np.float32)
    return rows, cols, flat.reshape(-1, 3)[hits].astype(np.float32), ell


def glow_grid(sources: tuple[np.ndarray, ...], shape: tuple[int, int], K: np.ndarray, alpha: float) -> tuple[np.ndarray, int]:
    """The glow of one fog level on its coarse grid: ``(grid, f)`` with ``grid`` float32 ``(⌈H/f⌉ + 4, ⌈W/f⌉ + 4, 3)``,
    the value at cell ``(i, j)`` being the glow per pixel at image point ``(f·(i − 2) + (f − 1)/2, f·(j − 2) + (f − 1)/2)``:
    a margin of two cells round the image, so the pixels at its edges interpolate between cells as the others do.

    Each source's energy ``η · g · S · (1 − e^{−αℓ})`` is shared by its four nearest cell centres (bilinear weights,
    which keep its centroid), the cells are blurred with a Gaussian of ``σ_c`` cells and :func:`add_glow_grid`
    interpolates them back onto the image with Keys' cubic, which keeps a smooth glow's width. The sharing widens a
    point's spread by ``f²/6`` px² on average over its position, so ``σ_c² f² = σ² − f²/6``: the composite has the
    glow's width σ. With ``f = 1`` this is the Gaussian of σ on the image itself. On FogDrive's night frames (six towns,
    four cameras, three levels) the result is within 1/255 of the full-resolution Gaussian at every pixel.
    """
    rows, cols, rgb, ell = sources
    h, w = shape
    sigma = max(glow_sigma_px(K, alpha), 0.5)
    f = glow_factor(sigma)
    hc, wc = -(-h // f) + 4, -(-w // f) + 4
    # a cell's value is the glow per pixel: its sources' energy shared by its f² pixels
    weight = (GLOW_FORWARD * GLOW_SOURCE_GAIN / (f * f)) * (1.0 - np.exp(-alpha * ell.astype(np.float64)))
    # each source is shared by its four nearest cell centres (bilinear weights), which keeps its centroid
    y = (rows + 0.5) / f + 1.5  # cell coordinates (a margin of two cells)
    x = (cols + 0.5) / f + 1.5
    y0, x0 = np.floor(y).astype(np.int64), np.floor(x).astype(np.int64)
    py, px = y - y0, x - x0
    cells = np.concatenate([y0 * wc + x0, y0 * wc + x0 + 1, (y0 + 1) * wc + x0, (y0 + 1) * wc + x0 + 1])
    share = np.concatenate([(1 - py) * (1 - px), (1 - py) * px, py * (1 - px), py * px])
    grid = np.empty((hc * wc, 3), np.float32)
    for ch in range(3):
        grid[:, ch] = np.bincount(cells, weights=share * np.tile(rgb[:, ch] * weight, 4), minlength=hc * wc)
    grid = grid.reshape(hc, wc, 3)
    sigma_c = sigma if f == 1 else math.sqrt(max(sigma * sigma - f * f / 6.0, 0.25 * f * f)) / f
    return cv2.GaussianBlur(grid, (0, 0), sigmaX=sigma_c, sigmaY=sigma_c, borderType=cv2.BORDER_CONSTANT), f


def _cubic_weights(t: np.ndarray) -> np.ndarray:
    """Keys' cubic convolution weights (a = −1/2) of the samples at offsets −1, 0, 1, 2 for fractions ``t``: it
    reproduces quadratics, so a smooth glow keeps its width.

    >>> _cubic_weights(np.array([0.0, 0.5])).tolist()
    [[0.0, 1.0, 0.0, 0.0], [-0.0625, 0.5625, 0.5625, -0.0625]]
    """
    t2, t3 = t * t, t * t * t
    return np.stack([(-t3 + 2 * t2 - t) / 2, (3 * t3 - 5 * t2 + 2) / 2, (-3 * t3 + 4 * t2 + t) / 2, (t3 - t2) / 2], -1)


#: A cell whose glow is below this (every channel) adds nothing to the pixels it reaches: Keys' weights sum to at most
#: 1.27 in absolute value over a 4 × 4 neighbourhood, so those pixels receive less than 0.5 and round to unchanged.
GLOW_QUIET = 0.35


@njit(cache=True, inline="always")
def _next_run(mask, start):
    # the first run of true cells of a mask row at or after ``start``: (lo, hi), lo = len(mask) when there is none
    n = mask.shape[0]
    lo = start
    while lo < n and not mask[lo]:
        lo += 1
    hi = lo
    while hi < n and mask[hi]:
        hi += 1
    return lo, hi


@njit(cache=True, parallel=True, fastmath=True)
def _add_glow(out, grid, f, need, active, first, x0, wx, wide):
    # out (H, 3W) uint8 in place; grid (Hc, 3Wc) float32 with a margin of two cells; active (Hc, Wc): cells some
    # cell of whose 4 × 4 neighbourhood (what their pixels read) is not quiet; need (Hc, Wc): the cells of grid row
    # cy whose columns an active pixel of grid rows cy − 2 … cy + 1 reads. first (Wc + 1): each cell interval's
    # first column; x0 (W): each column's cell; wx (W, 4): its horizontal cubic weights. Pass 1 interpolates the
    # needed grid rows to the image's columns (f times fewer rows than the image); pass 2 blends four of them per
    # image row, a contiguous loop that vectorises: out = clip(out + glow + 0.5, 0, 255). wide (≥ Hc, 3W) float32:
    # scratch for pass 1.
    h = out.shape[0]
    hc, wc = need.shape
    for cy in prange(hc):
        g = grid[cy]
        u = wide[cy]
        lo, hi = _next_run(need[cy], 0)
        while lo < wc:
            for j in range(first[lo], first[hi]):
                b = 3 * x0[j] - 3
                a0, a1, a2, a3 = wx[j, 0], wx[j, 1], wx[j, 2], wx[j, 3]
                for ch in range(3):
                    u[3 * j + ch] = a0 * g[b + ch] + a1 * g[b + 3 + ch] + a2 * g[b + 6 + ch] + a3 * g[b + 9 + ch]
            lo, hi = _next_run(need[cy], hi)
    n_chunks = 16  # task c takes rows c, c + 16, …: the glow gathers round the lamps, so interleaved rows balance
    for c in prange(n_chunks):
        for i in range(c, h, n_chunks):
            y = (i + 0.5) / f + 1.5  # cell coordinates
            y0 = int(np.floor(y))
            t = y - y0
            t2, t3 = t * t, t * t * t
            w0, w1 = np.float32((-t3 + 2 * t2 - t) / 2), np.float32((3 * t3 - 5 * t2 + 2) / 2)
            w2, w3 = np.float32((-3 * t3 + 4 * t2 + t) / 2), np.float32((t3 - t2) / 2)
            ua, ub, uc, ud = wide[y0 - 1], wide[y0], wide[y0 + 1], wide[y0 + 2]
            o = out[i]
            lo, hi = _next_run(active[y0], 0)
            while lo < wc:
                for k in range(3 * first[lo], 3 * first[hi]):
                    v = np.int32(np.float32(o[k]) + w0 * ua[k] + w1 * ub[k] + w2 * uc[k] + w3 * ud[k] + np.float32(0.5))
                    o[k] = np.uint8(min(max(v, 0), 255))  # (the cubic's small lobes may be < 0)
                lo, hi = _next_run(active[y0], hi)


def add_glow_grid(image: np.ndarray, grid: np.ndarray, f: int) -> None:
    """Add a coarse glow grid (:func:`glow_grid`) to a uint8 ``(H, W, 3)`` image in place: interpolated from the
    cells' centres by Keys' cubic convolution (:func:`_cubic_weights`, which reproduces quadratics, so a smooth glow
    keeps its width), rounded and clipped to [0, 255]. Only pixels within reach of a cell of at least
    :data:`GLOW_QUIET` are visited; the others would round to themselves."""
    h, w = image.shape[:2]
    x = (np.arange(w) + 0.5) / f + 1.5  # cell coordinates (a margin of two cells)
    x0 = np.floor(x).astype(np.int64)
    wx = _cubic_weights(x - x0).astype(np.float32)
    loud = (np.maximum(np.maximum(grid[..., 0], grid[..., 1]), grid[..., 2]) >= GLOW_QUIET).astype(np.uint8)
    # a pixel of cell interval (y0, x0) reads cells y0 − 1 … y0 + 2 and x0 − 1 … x0 + 2
    active = cv2.dilate(loud, np.ones((4, 4), np.uint8), anchor=(2, 2), borderType=cv2.BORDER_CONSTANT, borderValue=0)
    # grid row cy is read, at the active pixels' columns, by the pixels of grid rows cy − 2 … cy + 1
    need = active.copy()
    need[:-1] |= active[1:]
    need[1:] |= active[:-1]
    need[2:] |= active[:-2]
    first = np.searchsorted(x0, np.arange(grid.shape[1] + 1))  # columns of cell interval c: first[c] … first[c + 1]
    _add_glow(image.reshape(h, 3 * w), np.ascontiguousarray(grid).reshape(grid.shape[0], -1), f, need, active, first,
              x0, wx, _scratch(grid.shape[0], 3 * w))  # fmt: skip


_SCRATCH = threading.local()


def _scratch(rows: int, cols: int) -> np.ndarray:
    """A float32 ``(≥ rows, cols)`` buffer kept per thread: a fresh one each frame would cost its page faults (≈ 1 ms
    for the 4 MB of a 1280-wide image's light glow)."""
    buf = getattr(_SCRATCH, "wide", None)
    if buf is None or buf.shape[0] < rows or buf.shape[1] != cols:
        buf = _SCRATCH.wide = np.empty((max(rows, 0 if buf is None else buf.shape[0]), cols), np.float32)
    return buf


def add_glows(images: np.ndarray, clean: np.ndarray, depth: np.ndarray, K: np.ndarray, alphas: Sequence[float]) -> np.ndarray:
    """The glow of :func:`add_glow` added in place to fogged images ``(L, H, W, 3)`` at extinctions ``alphas``: the
    sources are found once (:func:`glow_sources`), each level blurs them on its coarse grid (:func:`glow_grid`) and
    adds it to its image (:func:`add_glow_grid`)."""
    h, w = depth.shape
    sources = glow_sources(clean, depth, K)
    if not len(sources[0]):
        return images
    for img, alpha in zip(images, alphas):
        if alpha > 0.0:
            add_glow_grid(img, *glow_grid(sources, (h, w), K, alpha))
    return images


def add_glow(fogged: np.ndarray, clean: np.ndarray, depth: np.ndarray, K: np.ndarray, alpha: float) -> np.ndarray:
    """Forward-scattered light of bright sources (lamps, headlights) added to a fogged night image (a new array).

    A source pixel of radiance ``S`` (clean image, ≥ ``GLOW_THRESHOLD``, taken at ``GLOW_SOURCE_GAIN · S``) at
    ray distance ℓ loses ``1 − e^{−αℓ}`` of its light to the fog; ``GLOW_FORWARD`` of that is scattered forwards
    into a Gaussian of width :func:`glow_sigma_px`: ``G = N_σ * [η · g · S · (1 − e^{−αℓ})]`` and the result is
    ``min(255, fogged + G)``. Both the strength (through ``1 − e^{−αℓ}``) and the width grow with α; with
    ``α = 0`` nothing is added. The Gaussian is applied on a grid coarse enough for its width (:func:`glow_grid`).

    >>> clean = np.zeros((41, 41, 3), np.uint8); clean[20, 20] = 255
    >>> K = np.array([[100.0, 0, 20.5], [0, 100.0, 20.5], [0, 0, 1]])
    >>> d = np.full((41, 41), 40.0, np.float32)
    >>> g = add_glow(np.zeros_like(clean), clean, d, K, 0.06)
    >>> bool(g[20, 24, 0] > g[20, 28, 0] > 0), int(add_glow(clean, clean, d, K, 0.0)[20, 19, 0])
    (True, 0)
    """
    out = np.array(fogged, np.uint8, copy=True)
    return out if alpha <= 0.0 else add_glows(out[None], clean, depth, K, [alpha])[0]


_F32 = np.float32


@njit(cache=True, inline="always", fastmath=True)
def _exp_neg(x):
    """exp(x) for float32 x ≤ 0 without a libm call, so pixel loops vectorise: exp(x) = (exp(x/64))^64 with a
    degree-5 Taylor polynomial on [−0.25, 0] (relative error < 2e-5); x is clamped at −16 (exp(−16) = 1.1e-7)."""
    y = max(x, _F32(-16.0)) * _F32(0.015625)
    p = _F32(1.0) + y * (_F32(1.0) + y * (_F32(0.5) + y * (_F32(1.0 / 6) + y * (_F32(1.0 / 24) + y * _F32(1.0 / 120)))))
    p = p * p
    p = p * p
    p = p * p
    p = p * p
    p = p * p
    return p * p


@njit(cache=True, parallel=True, fastmath=True)
def _koschmieder(rgb, depth, col_sq, row_sq, alphas, airlight_row, out):
    # rgb (H, 3W) and out (L, H, 3W) are viewed flat per row so every inner loop is contiguous (SIMD);
    # rows go in 16 chunks so each task allocates its scratch rows once
    h, w = depth.shape
    n_levels = alphas.shape[0]
    n_chunks = 16
    for chunk in prange(n_chunks):
        ell = np.empty(w, np.float32)
        t = np.empty(w, np.float32)
        diff = np.empty(3 * w, np.float32)
        t3 = np.empty(3 * w, np.float32)
        for i in range(chunk * h // n_chunks, (chunk + 1) * h // n_chunks):
            b2 = np.float32(1.0) + row_sq[i]
            for j in range(w):
                ell[j] = depth[i, j] * np.sqrt(b2 + col_sq[j])
            for k in range(3 * w):
                diff[k] = np.float32(rgb[i, k]) - airlight_row[k]
            for lv in range(n_levels):
                a = -alphas[lv]
                for j in range(w):
                    t[j] = _exp_neg(a * ell[j])
                for j in range(w):  # repeat each pixel's transmittance for its three channels
                    t3[3 * j] = t[j]
                    t3[3 * j + 1] = t[j]
                    t3[3 * j + 2] = t[j]
                for k in range(3 * w):
                    out[lv, i, k] = np.uint8(airlight_row[k] + diff[k] * t3[k] + np.float32(0.5))


_koschmieder_serial = serial_twin(_koschmieder)


def check_fog_inputs(rgb: np.ndarray, depth: np.ndarray, K: np.ndarray, alphas: Sequence[float], airlight: np.ndarray) -> None:
    """``ValueError`` naming the problem unless the inputs of :func:`fog_images` are usable.

    rgb uint8 (H, W, 3); depth (H, W) finite and ≥ 0 (sky is a large finite depth, 1000 m in fog-gym);
    K a 3×3 intrinsic matrix with finite positive focal lengths; every α finite and > 0; airlight three finite
    values in [0, 255].
    """
    depth = np.asarray(depth)
    if depth.ndim != 2:
        raise ValueError(f"depth must be an (H, W) array of metres, got shape {depth.shape}")
    h, w = depth.shape
    if not isinstance(rgb, np.ndarray) or rgb.shape != (h, w, 3) or rgb.dtype != np.uint8:
        raise ValueError(f"expected a uint8 (H, W, 3) image matching depth {depth.shape}, got "
                         f"{getattr(rgb, 'dtype', type(rgb).__name__)} {getattr(rgb, 'shape', '')}")  # fmt: skip
    low = float(np.min(depth)) if depth.size else 0.0
    if not math.isfinite(low) or low < 0 or (depth.size and not math.isfinite(float(np.max(depth)))):
        raise ValueError("depth must be finite and >= 0 metres everywhere (sky: a large finite depth such as 1000)")
    K = np.asarray(K, np.float64)
    if K.shape != (3, 3) or not np.isfinite(K).all() or K[0, 0] <= 0 or K[1, 1] <= 0:
        raise ValueError(f"K must be a finite 3×3 intrinsic matrix with positive focal lengths, got {K.tolist()}")
    a = np.asarray(alphas, np.float64)
    if a.ndim != 1 or not len(a) or not np.isfinite(a).all() or (a <= 0).any():
        raise ValueError(f"alphas must be finite extinctions > 0 [1/m], got {list(np.atleast_1d(a))}")
    A = np.asarray(airlight, np.float64)
    if A.shape != (3,) or not np.isfinite(A).all() or (A < 0).any() or (A > 255).any():
        raise ValueError(f"airlight must be three values in [0, 255], got {A.tolist()}")


def fog_images(rgb: np.ndarray, depth: np.ndarray, K: np.ndarray, alphas: Sequence[float], airlight: np.ndarray,
               validate: bool = True) -> np.ndarray:  # fmt: skip
    """Koschmieder fog at several extinctions in one pass: ``(L, H, W, 3)`` uint8 for ``alphas`` (all > 0).

    ``ℓ = z · sqrt(1 + ((u − cx)/fx)² + ((v − cy)/fy)²)`` at pixel centres; ``t = exp(−α·ℓ)``;
    ``I = A + (J − A)·t`` rounded. One read of image and depth serves every level. Inputs are checked
    (:func:`check_fog_inputs`) unless ``validate=False`` (the env's own frames, on the hot path).
    """
    if validate:
        check_fog_inputs(rgb, depth, K, alphas, airlight)
    h, w = depth.shape
    col = (((np.arange(w) + 0.5 - K[0, 2]) / K[0, 0]) ** 2).astype(np.float32)
    row = (((np.arange(h) + 0.5 - K[1, 2]) / K[1, 1]) ** 2).astype(np.float32)
    out = np.empty((len(alphas), h, w, 3), np.uint8)
    airlight_row = np.tile(np.asarray(airlight, np.float32), w)
    pick(_koschmieder, _koschmieder_serial, len(alphas) * h * w)(
        np.ascontiguousarray(rgb).reshape(h, 3 * w), np.ascontiguousarray(depth, np.float32), col, row,
        np.asarray(alphas, np.float32), airlight_row, out.reshape(len(alphas), h, 3 * w),
    )  # fmt: skip
    return out


def fog_image(rgb: np.ndarray, depth: np.ndarray, K: np.ndarray, alpha: float, airlight: np.ndarray) -> np.ndarray:
    """Koschmieder fog on a uint8 RGB image with planar depth (metres) and intrinsic ``K``; ``alpha = 0`` copies.

    >>> from fog_gym.fog.physics import alpha_from_visibility
    >>> img = np.zeros((2, 2, 3), np.uint8); depth = np.full((2, 2), 50.0, np.float32)
    >>> K = np.array([[1e6, 0, 1], [0, 1e6, 1], [0, 0, 1]])
    >>> fog_image(img, depth, K, alpha_from_visibility(50), np.array([200.0, 200, 200]))[0, 0].tolist()
    [190, 190, 190]
    """
    if alpha == 0.0:
        check_fog_inputs(rgb, depth, K, [1.0], airlight)
        return rgb.copy()
    return fog_images(rgb, depth, K, [alpha], airlight)[0]

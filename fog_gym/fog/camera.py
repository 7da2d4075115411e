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

import functools
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


@njit(cache=True)
def _splat_sources(clean, depth, u2, v2, alphas, fs, widths, offsets, grids, box):
    # clean (H, 3W) uint8, depth (H, W) float32, u2 (W) / v2 (H) the squared ray slopes of the pixel centres; per level
    # its extinction, grid factor f, grid width Wc (cells) and offset into grids (float32, zeroed: level lv's grid is
    # grids[offsets[lv]:…] as (Hc, Wc, 3)). Every source pixel (a channel ≥ GLOW_THRESHOLD) is shared by the four
    # nearest cell centres of each level's grid with its energy η·g·S·(1 − e^{−αℓ}) / f². Returns the source count;
    # box (4,) gets the sources' first and last row and column.
    h, w = depth.shape
    gain = GLOW_FORWARD * GLOW_SOURCE_GAIN
    count = 0
    for i in range(h):
        row = clean[i]
        top = np.uint8(0)
        for k in range(3 * w):  # most rows hold no source: one vectorised maximum (kept uint8) rules them out
            v = row[k]
            top = v if v > top else top
        if top < GLOW_THRESHOLD:
            continue
        for j in range(w):
            r, g, b = row[3 * j], row[3 * j + 1], row[3 * j + 2]
            if r < GLOW_THRESHOLD and g < GLOW_THRESHOLD and b < GLOW_THRESHOLD:
                continue
            count += 1
            box[0], box[1] = min(box[0], i), max(box[1], i)
            box[2], box[3] = min(box[2], j), max(box[3], j)
            ell = depth[i, j] * np.sqrt(1.0 + u2[j] + v2[i])
            for lv in range(alphas.shape[0]):
                f = fs[lv]
                energy = gain / (f * f) * (1.0 - np.exp(-alphas[lv] * ell))
                y = (i + 0.5) / f + 1.5  # cell coordinates (a margin of two cells)
                x = (j + 0.5) / f + 1.5
                y0, x0 = int(y), int(x)
                py, px = y - y0, x - x0
                wc3 = 3 * widths[lv]
                base = offsets[lv] + y0 * wc3 + 3 * x0
                for cell, share in ((base, (1 - py) * (1 - px)), (base + 3, (1 - py) * px),
                                    (base + wc3, py * (1 - px)), (base + wc3 + 3, py * px)):  # fmt: skip
                    grids[cell] += share * energy * r
                    grids[cell + 1] += share * energy * g
                    grids[cell + 2] += share * energy * b
    return count


def glow_grids(clean: np.ndarray, depth: np.ndarray, K: np.ndarray, alphas: Sequence[float]) -> list[tuple[np.ndarray, int]]:
    """The glow of each fog level on its coarse grid, from one scan of the clean frame: ``[(grid, f), …]`` with
    ``grid`` float32 ``(⌈H/f⌉ + 4, ⌈W/f⌉ + 4, 3)``, the value at cell ``(i, j)`` being the glow per pixel at image point
    ``(f·(i − 2) + (f − 1)/2, f·(j − 2) + (f − 1)/2)``: a margin of two cells round the image, so the pixels at its
    edges interpolate between cells as the others do. An empty list when the frame has no source (no pixel with a
    channel ≥ ``GLOW_THRESHOLD``).

    Each source's energy ``η · g · S · (1 − e^{−αℓ})`` is shared by its four nearest cell centres (bilinear weights,
    which keep its centroid), the cells are blurred with a Gaussian of ``σ_c`` cells and :func:`add_glow_grid`
    interpolates them back onto the image with Keys' cubic, which keeps a smooth glow's width. The sharing widens a
    point's spread by ``f²/6`` px² on average over its position, so ``σ_c² f² = σ² − f²/6``: the composite has the
    glow's width σ. With ``f = 1`` this is the Gaussian of σ on the image itself. On FogDrive's night frames (six towns,
    four cameras, three levels) the result is within 1/255 of the full-resolution Gaussian at every pixel.

    >>> clean = np.zeros((40, 40, 3), np.uint8); clean[20, 20] = (250, 0, 0)
    >>> K = np.array([[200.0, 0, 20.0], [0, 200.0, 20.0], [0, 0, 1]])
    >>> [(g.shape, f) for g, f in glow_grids(clean, np.full((40, 40), 30.0, np.float32), K, [0.02, 0.06])]
    [((44, 44, 3), 1), ((18, 18, 3), 3)]
    """
    h, w = depth.shape
    sigmas = [max(glow_sigma_px(K, a), 0.5) for a in alphas]
    fs = np.array([glow_factor(s) for s in sigmas], np.int64)
    hcs, wcs = -(-h // fs) + 4, -(-w // fs) + 4
    sizes = hcs * wcs * 3
    offsets = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
    grids = np.zeros(int(sizes.sum()), np.float32)
    u2 = ((np.arange(w) + 0.5 - K[0, 2]) / K[0, 0]) ** 2
    v2 = ((np.arange(h) + 0.5 - K[1, 2]) / K[1, 1]) ** 2
    box = np.array([h, -1, w, -1], np.int64)
    n = _splat_sources(np.ascontiguousarray(clean).reshape(h, 3 * w), np.ascontiguousarray(depth, np.float32), u2, v2,
                       np.asarray(alphas, np.float64), fs, wcs.astype(np.int64), offsets, grids, box)  # fmt: skip
    if not n:
        return []
    out = []
    for k, (sigma, f) in enumerate(zip(sigmas, fs.tolist())):
        grid = grids[offsets[k]:offsets[k] + sizes[k]].reshape(hcs[k], wcs[k], 3)
        sigma_c = sigma if f == 1 else math.sqrt(max(sigma * sigma - f * f / 6.0, 0.25 * f * f)) / f
        # blur only the cells the kernel reaches from the sources' cells (OpenCV's float kernel has ⌊(⌊8σ + 1.5⌋ | 1)/2⌋
        # cells each side): outside that box the blurred grid is zero, and inside it the zero border stands for cells
        # that hold no energy, so the result is the whole grid's blur
        reach = (int(8.0 * sigma_c + 1.5) | 1) // 2 + 1
        cy = [int((box[0] + 0.5) / f + 1.5), int((box[1] + 0.5) / f + 1.5) + 1]  # (the bilinear share's second cell)
        cx = [int((box[2] + 0.5) / f + 1.5), int((box[3] + 0.5) / f + 1.5) + 1]
        r0, r1 = max(cy[0] - reach, 0), min(cy[1] + reach + 1, hcs[k])
        c0, c1 = max(cx[0] - reach, 0), min(cx[1] + reach + 1, wcs[k])
        blurred = np.zeros_like(grid)
        blurred[r0:r1, c0:c1] = cv2.GaussianBlur(grid[r0:r1, c0:c1], (0, 0), sigmaX=sigma_c, sigmaY=sigma_c,
                                                 borderType=cv2.BORDER_CONSTANT)  # fmt: skip
        out.append((blurred, f))
    return out


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
def _span(mask):
    # the first true cell of a mask row and the end of its last (lo = hi when there is none)
    n = mask.shape[0]
    lo = 0
    while lo < n and not mask[lo]:
        lo += 1
    hi = n
    while hi > lo and not mask[hi - 1]:
        hi -= 1
    return lo, hi


@njit(cache=True, parallel=True, fastmath=True)
def _add_glow(out, grid, need, active, first, x0, wx, y0s, wy, wide):
    # out (H, 3W) uint8 in place; grid (Hc, 3Wc) float32 with a margin of two cells. need (Hc, Wc): the cells of grid
    # row cy whose columns an active pixel (one some cell of whose 4 × 4 neighbourhood is not quiet) of grid rows
    # cy − 2 … cy + 1 reads; active (Hc, Wc): the cells of those pixels.
    # first (Wc + 1): each cell interval's first column; x0 (W): each column's cell; wx (W, 4): its horizontal cubic
    # weights; y0s (H) and wy (H, 4): the same for each row; wide (≥ Hc, 3W) float32 scratch. Pass 1 interpolates the needed cells of each grid row to the image's
    # columns (zeros between them, over the row's span); pass 2 blends four such rows per image row over the span of
    # its active cells, a contiguous loop that vectorises: out = clip(out + glow + 0.5, 0, 255).
    h = out.shape[0]
    hc, wc = need.shape
    span_lo = np.zeros(hc, np.int64)  # the first and the end of each grid row's active cells
    span_hi = np.zeros(hc, np.int64)
    for cy in range(hc):
        span_lo[cy], span_hi[cy] = _span(active[cy])
    for cy in prange(hc):
        g = grid[cy]
        u = wide[cy]
        row = need[cy]
        lo, hi = _span(row)
        for j in range(first[lo], first[hi]):
            cx = x0[j]
            if row[cx]:
                b = 3 * cx - 3
                a0, a1, a2, a3 = wx[j, 0], wx[j, 1], wx[j, 2], wx[j, 3]
                for ch in range(3):
                    u[3 * j + ch] = a0 * g[b + ch] + a1 * g[b + 3 + ch] + a2 * g[b + 6 + ch] + a3 * g[b + 9 + ch]
            else:
                for ch in range(3):
                    u[3 * j + ch] = np.float32(0.0)
    for i in prange(h):
        y0 = y0s[i]
        if span_lo[y0] >= span_hi[y0]:
            continue
        w0, w1, w2, w3 = wy[i, 0], wy[i, 1], wy[i, 2], wy[i, 3]
        k0, k1 = 3 * first[span_lo[y0]], 3 * first[span_hi[y0]]
        # views from the span's start: a unit-stride loop from 0 that vectorises (8× the indexed form)
        ua, ub, uc, ud = wide[y0 - 1, k0:k1], wide[y0, k0:k1], wide[y0 + 1, k0:k1], wide[y0 + 2, k0:k1]
        o = out[i, k0:k1]
        for k in range(k1 - k0):
            v = np.int32(np.float32(o[k]) + w0 * ua[k] + w1 * ub[k] + w2 * uc[k] + w3 * ud[k] + np.float32(0.5))
            o[k] = np.uint8(min(max(v, 0), 255))  # (the cubic's small lobes may be < 0)


def add_glow_grid(image: np.ndarray, grid: np.ndarray, f: int) -> None:
    """Add a coarse glow grid (:func:`glow_grids`) to a uint8 ``(H, W, 3)`` image in place: interpolated from the
    cells' centres by Keys' cubic convolution (:func:`_cubic_weights`, which reproduces quadratics, so a smooth glow
    keeps its width), rounded and clipped to [0, 255]. Only pixels within reach of a cell of at least
    :data:`GLOW_QUIET` are visited; the others would round to themselves."""
    h, w = image.shape[:2]
    x0, wx, first = _columns(w, f, grid.shape[1])
    y0, wy, _ = _columns(h, f, grid.shape[0])  # rows sit on the grid as columns do
    loud = (np.maximum(np.maximum(grid[..., 0], grid[..., 1]), grid[..., 2]) >= GLOW_QUIET).astype(np.uint8)
    # a pixel of cell interval (y0, x0) reads cells y0 − 1 … y0 + 2 and x0 − 1 … x0 + 2
    active = cv2.dilate(loud, np.ones((4, 4), np.uint8), anchor=(2, 2), borderType=cv2.BORDER_CONSTANT, borderValue=0)
    # grid row cy is read, at the active pixels' columns, by the pixels of grid rows cy − 2 … cy + 1
    need = active.copy()
    need[:-1] |= active[1:]
    need[1:] |= active[:-1]
    need[2:] |= active[:-2]
    _add_glow(image.reshape(h, 3 * w), np.ascontiguousarray(grid).reshape(grid.shape[0], -1), need, active, first, x0,
              wx, y0, wy, _scratch(grid.shape[0], 3 * w))  # fmt: skip


@functools.lru_cache(maxsize=64)
def _columns(w: int, f: int, wc: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per image column (or row) its cell (cell coordinates, a margin of two cells) and Keys' weights of cells
    x0 − 1 … x0 + 2; per cell the first column of its interval (``first[c] … first[c + 1]``)."""
    x = (np.arange(w) + 0.5) / f + 1.5
    x0 = np.floor(x).astype(np.int64)
    return x0, _cubic_weights(x - x0).astype(np.float32), np.searchsorted(x0, np.arange(wc + 1))


_SCRATCH = threading.local()


def _scratch(rows: int, cols: int) -> np.ndarray:
    """A float32 ``(≥ rows, cols)`` buffer kept per thread: a fresh one each frame would cost its page faults (≈ 1 ms
    for the 4 MB of a 1280-wide image's light glow)."""
    buf = getattr(_SCRATCH, "wide", None)
    if buf is None or buf.shape[0] < rows or buf.shape[1] != cols:
        buf = _SCRATCH.wide = np.empty((max(rows, 0 if buf is None else buf.shape[0]), cols), np.float32)
    return buf


def add_glows(images: np.ndarray, clean: np.ndarray, depth: np.ndarray, K: np.ndarray, alphas: Sequence[float]) -> np.ndarray:
    """The glow of :func:`add_glow` added in place to fogged images ``(L, H, W, 3)`` at extinctions ``alphas`` (all
    > 0): one scan of the clean frame puts every level's sources on its coarse grid (:func:`glow_grids`), and each
    grid is added to its image (:func:`add_glow_grid`)."""
    for img, (grid, f) in zip(images, glow_grids(clean, depth, K, alphas)):
        add_glow_grid(img, grid, f)
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

"""The glow of lit fog at night: bright sources (lamps, headlights) lose light to the fog, and part of it is scattered
forwards around them (fog-gym's own model, ``docs/fog.md`` "Fog at night").

``G = N_σ * [η · g · S · (1 − e^{−αℓ})]`` added to the fogged image, with the Gaussian applied on a grid coarse enough
for its width (:func:`glow_grids`) and interpolated back with Keys' cubic (:func:`add_glows`);
:func:`fog_gym.fog.camera.fog_images` with ``glow=True`` adds it to each fogged row while the row is in cache
(:func:`_blend_glow`).

Example:
    >>> [glow_factor(s) for s in (3.0, 22.5)]
    [1, 9]
"""

from __future__ import annotations

import functools
import math
import os
import threading
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor

import cv2
import numpy as np
from numba import njit, prange
from numba.core.cpu import ParallelOptions

import fog_gym._numba  # noqa: F401  (numba's fork-safe threading layer, before any kernel runs)
from fog_gym._numba import FASTMATH, launch, pick, serial_twin
from fog_gym._rounds import deferring

#: Glow: sources are pixels at or above ``GLOW_THRESHOLD`` (any channel, 0–255), taken at ``GLOW_SOURCE_GAIN`` ×
#: their 8-bit value (a clipped lamp is far brighter than white); ``GLOW_FORWARD`` of the light they lose to fog
#: is scattered forwards into a Gaussian of angular width ``GLOW_WIDTH_RAD · (1 + α · GLOW_DISTANCE)``.
GLOW_THRESHOLD, GLOW_SOURCE_GAIN, GLOW_FORWARD = 240, 12.0, 0.5
GLOW_WIDTH_RAD, GLOW_DISTANCE = math.radians(0.6), 50.0


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


@njit(cache=True, nogil=True, parallel=True)
def _find_sources(clean):
    # clean (H, 3W) uint8: the source pixels (a channel ≥ GLOW_THRESHOLD) in raster order, as rows and columns (int32).
    # Rows are scanned in parallel; a row's maximum (a vectorised loop, kept uint8) rules most rows out, the others
    # write their sources' columns in their own slot of an untouched buffer (only written pages cost), then the
    # lists are joined.
    h, w = clean.shape[0], clean.shape[1] // 3
    cols = np.empty(h * w, np.int32)
    found = np.zeros(h, np.int64)
    for i in prange(h):
        row = clean[i]
        top = np.uint8(0)
        for k in range(3 * w):
            v = row[k]
            top = v if v > top else top
        if top >= GLOW_THRESHOLD:
            n = 0
            for j in range(w):
                if max(row[3 * j], max(row[3 * j + 1], row[3 * j + 2])) >= GLOW_THRESHOLD:
                    cols[i * w + n] = j
                    n += 1
            found[i] = n
    total = found.sum()
    src_i = np.empty(total, np.int32)
    src_j = np.empty(total, np.int32)
    k = 0
    for i in range(h):
        for m in range(found[i]):
            src_i[k], src_j[k] = i, cols[i * w + m]
            k += 1
    return src_i, src_j


@njit(cache=True, nogil=True)
def _splat_sources(clean, depth, u2, v2, alphas, fs, widths, offsets, grids, src_i, src_j, taus):
    # clean (H, 3W) uint8, depth (H, W) float32, u2 (W) / v2 (H) the squared ray slopes of the pixel centres; per level
    # its extinction, grid factor f, grid width Wc (cells) and offset into grids (float32, zeroed: level lv's grid is
    # grids[offsets[lv]:…] as (Hc, Wc, 3)); the source pixels (_find_sources). Every source is shared by the four
    # nearest cell centres of each level's grid with its energy η·g·S·(1 − e^{−αℓ}) / f² (1 − e^{−τ} with a fog field's
    # optical depths taus (sources, levels); none: (0, levels)).
    gain = GLOW_FORWARD * GLOW_SOURCE_GAIN
    for s in range(src_i.shape[0]):
        i, j = src_i[s], src_j[s]
        row = clean[i]
        r, g, b = row[3 * j], row[3 * j + 1], row[3 * j + 2]
        ell = depth[i, j] * np.sqrt(1.0 + u2[j] + v2[i])
        for lv in range(alphas.shape[0]):
            f = fs[lv]
            # the light lost to the fog along the source's ray: 1 − e^{−αℓ}, or 1 − e^{−τ} of a fog field
            lost = 1.0 - np.exp(-alphas[lv] * ell) if taus.shape[0] == 0 else -math.expm1(-taus[s, lv])
            energy = gain / (f * f) * lost
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


_find_sources_serial = serial_twin(_find_sources)


def glow_grids(clean: np.ndarray, depth: np.ndarray, K: np.ndarray, alphas: Sequence[float]) -> list[tuple[np.ndarray, int]]:
    """The glow of each fog level on its coarse grid, from one scan of the clean frame: ``[(grid, f), …]`` with
    ``grid`` float32 ``(⌈H/f⌉ + 4, ⌈W/f⌉ + 4, 3)``, the value at cell ``(i, j)`` being the glow per pixel at image point
    ``(f·(i − 2) + (f − 1)/2, f·(j − 2) + (f − 1)/2)``: a margin of two cells round the image, so the pixels at its
    edges interpolate between cells as the others do. An empty list when the frame has no source (no pixel with a
    channel ≥ ``GLOW_THRESHOLD``).

    Each source's energy ``η · g · S · (1 − e^{−αℓ})`` is shared by its four nearest cell centres (bilinear weights,
    which keep its centroid), the cells are blurred with a Gaussian of ``σ_c`` cells and :func:`add_glows`
    interpolates them back onto the image with Keys' cubic, which keeps a smooth glow's width. The sharing widens a
    point's spread by ``f²/6`` px² on average over its position, so ``σ_c² f² = σ² − f²/6``: the composite has the
    glow's width σ. With ``f = 1`` this is the Gaussian of σ on the image itself. On FogDrive's night frames (six towns,
    four cameras, three levels) the result is within 1/255 of the full-resolution Gaussian at every pixel.

    >>> clean = np.zeros((40, 40, 3), np.uint8); clean[20, 20] = (250, 0, 0)
    >>> K = np.array([[200.0, 0, 20.0], [0, 200.0, 20.0], [0, 0, 1]])
    >>> [(g.shape, f) for g, f in glow_grids(clean, np.full((40, 40), 30.0, np.float32), K, [0.02, 0.06])]
    [((44, 44, 3), 1), ((18, 18, 3), 3)]
    """
    cells = _glow_cells(clean, depth, K, alphas)
    if cells is None:
        return []
    flat, fs, hcs, wcs, offsets = cells
    return [(flat[offsets[k]:offsets[k] + hcs[k] * wcs[k] * 3].reshape(hcs[k], wcs[k], 3), int(fs[k]))
            for k in range(len(fs))]  # fmt: skip


def _glow_cells(clean: np.ndarray, depth: np.ndarray, K: np.ndarray, alphas: Sequence[float], depths=None):
    """:func:`glow_grids` in one flat float32 buffer: ``(cells, fs, hcs, wcs, offsets)``, level k's grid being
    ``cells[offsets[k]:…]`` as ``(hcs[k], wcs[k], 3)``; None when the frame has no source. With fog fields,
    ``depths(rows, columns)`` gives the optical depth of each level along the source pixels' rays ``(sources, levels)``
    and the sources lose ``1 − e^{−τ}`` of their light (``alphas``, the fields' peak extinctions, set the widths)."""
    h, w = depth.shape
    sigmas = [max(glow_sigma_px(K, a), 0.5) for a in alphas]
    fs = np.array([glow_factor(s) for s in sigmas], np.int64)
    hcs, wcs = -(-h // fs) + 4, -(-w // fs) + 4
    sizes = hcs * wcs * 3
    offsets = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
    grids = np.zeros(int(sizes.sum()), np.float32)
    u2 = ((np.arange(w) + 0.5 - K[0, 2]) / K[0, 0]) ** 2
    v2 = ((np.arange(h) + 0.5 - K[1, 2]) / K[1, 1]) ** 2
    flat = np.ascontiguousarray(clean).reshape(h, 3 * w)
    src_i, src_j = pick(_find_sources, _find_sources_serial, h * w)(flat)
    if not len(src_i):
        return None
    taus = np.zeros((0, len(alphas))) if depths is None else np.ascontiguousarray(depths(src_i, src_j), np.float64)
    _splat_sources(flat, np.ascontiguousarray(depth, np.float32), u2, v2, np.asarray(alphas, np.float64), fs,
                   wcs.astype(np.int64), offsets, grids, src_i, src_j, taus)  # fmt: skip
    box = (int(src_i[0]), int(src_i[-1]), int(src_j.min()), int(src_j.max()))  # the sources' rows and columns
    blurred = np.zeros_like(grids)

    def blur(k: int, sigma: float, f: int) -> None:
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
        out = blurred[offsets[k]:offsets[k] + sizes[k]].reshape(hcs[k], wcs[k], 3)
        out[r0:r1, c0:c1] = cv2.GaussianBlur(grid[r0:r1, c0:c1], (0, 0), sigmaX=sigma_c, sigmaY=sigma_c,
                                             borderType=cv2.BORDER_CONSTANT)  # fmt: skip

    # OpenCV blurs a grid this small on one thread and releases the GIL: this thread blurs the largest grid while the
    # pool's threads blur the others
    order = np.argsort(fs, kind="stable").tolist()
    jobs = [_blur_pool().submit(blur, k, sigmas[k], int(fs[k])) for k in order[1:]]
    blur(order[0], sigmas[order[0]], int(fs[order[0]]))
    for job in jobs:
        job.result()
    return blurred, fs, hcs, wcs, offsets


_POOL: list = []


def _blur_pool() -> ThreadPoolExecutor:
    """Threads for the glow's blurs beside the caller's, one per other core (made on first use; a forked child makes
    its own)."""
    if not _POOL or _POOL[0][0] != os.getpid():
        _POOL[:] = [(os.getpid(), ThreadPoolExecutor(max(1, min(3, (os.cpu_count() or 1) - 1)),
                                                      thread_name_prefix="fog-glow"))]  # fmt: skip
    return _POOL[0][1]


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


# (its loops read their neighbours' rows: unfused; as ParallelOptions, since numba empties a dict of options on the
# first compilation, so a second signature, or a scan of the options, would find plain parallel with fusion)
@njit(cache=True, nogil=True, parallel=ParallelOptions({"fusion": False}), fastmath=FASTMATH)
def _glow_rows(grids, gofs, hcs, wcs, x0s, wxs, firsts, fofs, wide):
    # Stages 1 and 2 of the glow's addition (stage 3: _blend_glow); returns each grid row's span of active intervals
    # (span_lo, span_hi, in the order of the levels' rows; row r of level lv is rofs[lv] + cy). Level lv's grid is grids[gofs[lv]:…] as (hcs[lv], 3 wcs[lv]) float32 (a margin of
    # two cells); x0s/wxs (L, W) and y0s/wys (L, H): each image column's and row's cell and Keys' weights of cells
    # x0 − 1 … x0 + 2; firsts[fofs[lv]:…] (wcs[lv] + 1): each cell interval's first column; wide (≥ Σ hcs, 3W) float32
    # scratch, level lv's rows from rofs[lv] = Σ hcs[:lv].
    # 1. A cell is loud when a channel reaches GLOW_QUIET; a pixel interval (y0, x0) is active when a cell it reads
    #    (y0 − 1 … y0 + 2 × x0 − 1 … x0 + 2) is loud. Pixels outside active intervals would round to themselves.
    # 2. Each grid row is interpolated to the image's columns over the span of the active intervals of grid rows
    #    cy − 2 … cy + 1 (the pixels that read it). Pixels between active intervals get their glow too: it rounds away.
    # 3. Each image row blends four such rows over the span of its active intervals, per level, in a contiguous loop
    #    from the span's start that vectorises: out = clip(out + glow + 0.5, 0, 255).
    n_lv = hcs.shape[0]
    n_rows = 0
    for lv in range(n_lv):
        n_rows += hcs[lv]
    row_lv = np.empty(n_rows, np.int64)  # every level's grid rows in one parallel loop
    row_cy = np.empty(n_rows, np.int64)
    cofs = np.empty(n_lv + 1, np.int64)  # cell offsets of the masks
    r, cofs[0] = 0, 0
    for lv in range(n_lv):
        for cy in range(hcs[lv]):
            row_lv[r], row_cy[r] = lv, cy
            r += 1
        cofs[lv + 1] = cofs[lv] + hcs[lv] * wcs[lv]
    loud = np.zeros(cofs[n_lv], np.uint8)
    active = np.zeros(cofs[n_lv], np.uint8)
    span_lo = np.zeros(n_rows, np.int64)
    span_hi = np.zeros(n_rows, np.int64)
    for r in prange(n_rows):  # 1. loud cells
        lv, cy = row_lv[r], row_cy[r]
        wc = wcs[lv]
        g = grids[gofs[lv] + cy * 3 * wc:gofs[lv] + (cy + 1) * 3 * wc]
        m = loud[cofs[lv] + cy * wc:cofs[lv] + (cy + 1) * wc]
        for cx in range(wc):
            m[cx] = max(g[3 * cx], max(g[3 * cx + 1], g[3 * cx + 2])) >= GLOW_QUIET
    for r in prange(n_rows):  # 1. active intervals
        lv, cy = row_lv[r], row_cy[r]
        hc, wc = hcs[lv], wcs[lv]
        col = np.zeros(wc + 3, np.uint8)  # loud in rows cy − 1 … cy + 2, shifted by one cell
        for yy in range(max(cy - 1, 0), min(cy + 3, hc)):
            m = loud[cofs[lv] + yy * wc:cofs[lv] + (yy + 1) * wc]
            c = col[1:wc + 1]
            for cx in range(wc):
                c[cx] |= m[cx]
        a = active[cofs[lv] + cy * wc:cofs[lv] + (cy + 1) * wc]
        for cx in range(wc):  # cells cx − 1 … cx + 2 at col[cx … cx + 3]
            a[cx] = col[cx] | col[cx + 1] | col[cx + 2] | col[cx + 3]
        span_lo[r], span_hi[r] = _span(a)
    for r in prange(n_rows):  # 2.
        lv, cy = row_lv[r], row_cy[r]
        hc, wc = hcs[lv], wcs[lv]
        lo, hi = wc, 0
        for yy in range(max(cy - 2, 0), min(cy + 2, hc)):
            if span_lo[r - cy + yy] < span_hi[r - cy + yy]:
                lo, hi = min(lo, span_lo[r - cy + yy]), max(hi, span_hi[r - cy + yy])
        if lo >= hi:
            continue
        g = grids[gofs[lv] + cy * 3 * wc:gofs[lv] + (cy + 1) * 3 * wc]
        u = wide[r]  # (row r is rofs[lv] + cy)
        first = firsts[fofs[lv]:fofs[lv] + wc + 1]
        x0, wx = x0s[lv], wxs[lv]
        for j in range(first[lo], first[hi]):
            b = 3 * x0[j] - 3
            a0, a1, a2, a3 = wx[j, 0], wx[j, 1], wx[j, 2], wx[j, 3]
            for ch in range(3):
                u[3 * j + ch] = a0 * g[b + ch] + a1 * g[b + 3 + ch] + a2 * g[b + 6 + ch] + a3 * g[b + 9 + ch]
    return span_lo, span_hi


@njit(cache=True, inline="always", fastmath=FASTMATH)
def _blend_glow(o, i, lv, y0s, wys, firsts, fofs, wide, rofs, span_lo, span_hi):
    # Stage 3 for image row i of level lv: o (3W) uint8 in place blends four rows of wide over the span of the row's
    # active intervals, in a contiguous loop from the span's start that vectorises: o = clip(o + glow + 0.5, 0, 255).
    r = rofs[lv] + y0s[lv, i]
    if span_lo[r] >= span_hi[r]:
        return
    w0, w1, w2, w3 = wys[lv, i, 0], wys[lv, i, 1], wys[lv, i, 2], wys[lv, i, 3]
    k0, k1 = 3 * firsts[fofs[lv] + span_lo[r]], 3 * firsts[fofs[lv] + span_hi[r]]
    # views from the span's start: a unit-stride loop from 0 that vectorises (8× the indexed form)
    ua, ub, uc, ud = wide[r - 1, k0:k1], wide[r, k0:k1], wide[r + 1, k0:k1], wide[r + 2, k0:k1]
    ob = o[k0:k1]
    for k in range(k1 - k0):
        v = np.int32(np.float32(ob[k]) + w0 * ua[k] + w1 * ub[k] + w2 * uc[k] + w3 * ud[k] + np.float32(0.5))
        ob[k] = np.uint8(min(max(v, 0), 255))  # (the cubic's small lobes may be < 0)


@njit(cache=True, nogil=True, parallel=True, fastmath=FASTMATH)
def _add_glow_rows(out, y0s, wys, firsts, fofs, wide, rofs, span_lo, span_hi):
    # Stage 3 on fogged images out (L, H, 3W) uint8, in place (_glow_rows made wide and the spans).
    for i in prange(out.shape[1]):
        for lv in range(out.shape[0]):
            _blend_glow(out[lv, i], i, lv, y0s, wys, firsts, fofs, wide, rofs, span_lo, span_hi)


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
    for the 4 MB of a 1280-wide image's light glow). A world's step in :func:`fog_gym._rounds.run_rounds` (worlds that
    take turns in one thread) gets a fresh one."""
    if deferring():
        return np.empty((rows, cols), np.float32)
    buf = getattr(_SCRATCH, "wide", None)
    if buf is None or buf.shape[0] < rows or buf.shape[1] != cols:
        buf = _SCRATCH.wide = np.empty((max(rows, 0 if buf is None else buf.shape[0]), cols), np.float32)
    return buf


def add_glows(images: np.ndarray, clean: np.ndarray, depth: np.ndarray, K: np.ndarray, alphas: Sequence[float]) -> np.ndarray:
    """The glow of :func:`add_glow` added in place to fogged images ``(L, H, W, 3)`` at extinctions ``alphas`` (all
    > 0). One scan of the clean frame puts every level's sources on its coarse grid (:func:`glow_grids`); each grid
    is added to its image, interpolated from the cells' centres by Keys' cubic convolution (:func:`_cubic_weights`,
    which reproduces quadratics, so a smooth glow keeps its width), rounded and clipped to [0, 255]. Only pixels within
    reach of a cell of at least :data:`GLOW_QUIET` are visited; the others would round to themselves.
    ``fog_images(..., glow=True)`` gives the same bits in one pass."""
    rows = _glow_rows_of(clean, depth, K, alphas)
    if rows is None:
        return images
    n, h, w = images.shape[:3]
    work = images if images.flags.c_contiguous else np.ascontiguousarray(images)
    launch(_add_glow_rows)(work.reshape(n, h, 3 * w), *rows)
    if work is not images:
        images[...] = work
    return images


def _glow_rows_of(clean: np.ndarray, depth: np.ndarray, K: np.ndarray, alphas: Sequence[float],
                  depths=None) -> tuple | None:  # fmt: skip
    """Stages 1 and 2 of the glow (:func:`_glow_rows`) for a frame: the arguments of its stage 3 (:func:`_blend_glow`)
    after the image, ``(y0s, wys, firsts, fofs, wide, rofs, span_lo, span_hi)``; None when the frame has no source."""
    cells = _glow_cells(clean, depth, K, alphas, depths)
    if cells is None:
        return None
    flat, fs, hcs, wcs, gofs = cells
    h, w = depth.shape
    x0s, wxs, firsts, fofs, y0s, wys, rofs = _tables(h, w, tuple(fs.tolist()))
    wide = _scratch(int(hcs.sum()), 3 * w)
    span_lo, span_hi = launch(_glow_rows)(flat, gofs, hcs, wcs, x0s, wxs, firsts, fofs, wide)
    return y0s, wys, firsts, fofs, wide, rofs, span_lo, span_hi


#: Stage 3's arguments when there is no glow (the day): no level has rows.
_NO_GLOW = (np.zeros((0, 0), np.int64), np.zeros((0, 0, 4), np.float32), np.zeros(0, np.int64), np.zeros(0, np.int64),
            np.zeros((0, 0), np.float32), np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64))  # fmt: skip


@functools.lru_cache(maxsize=16)
def _tables(h: int, w: int, fs: tuple[int, ...]) -> tuple[np.ndarray, ...]:
    """:func:`_columns` of every level stacked for :func:`_add_glows`: the columns' cells and weights ``(L, W)`` and
    ``(L, W, 4)``, the cells' first columns concatenated and their offsets, the rows' cells and weights ``(L, H)`` and
    ``(L, H, 4)``, and each level's first row in the scratch."""
    hcs = [-(-h // f) + 4 for f in fs]
    wcs = [-(-w // f) + 4 for f in fs]
    cols = [_columns(w, f, wc) for f, wc in zip(fs, wcs)]
    rows = [_columns(h, f, hc) for f, hc in zip(fs, hcs)]  # rows sit on the grid as columns do

    def starts(sizes: list[int]) -> np.ndarray:
        return np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)

    return (np.stack([c[0] for c in cols]), np.stack([c[1] for c in cols]), np.concatenate([c[2] for c in cols]),
            starts([wc + 1 for wc in wcs]), np.stack([r[0] for r in rows]), np.stack([r[1] for r in rows]),
            starts(hcs))  # fmt: skip


def add_glow(fogged: np.ndarray, clean: np.ndarray, depth: np.ndarray, K: np.ndarray, alpha: float) -> np.ndarray:
    """Forward-scattered light of bright sources (lamps, headlights) added to a fogged night image (a new array).

    A source pixel of radiance ``S`` (clean image, ≥ ``GLOW_THRESHOLD``, taken at ``GLOW_SOURCE_GAIN · S``) at
    ray distance ℓ loses ``1 − e^{−αℓ}`` of its light to the fog; ``GLOW_FORWARD`` of that is scattered forwards
    into a Gaussian of width :func:`glow_sigma_px`: ``G = N_σ * [η · g · S · (1 − e^{−αℓ})]`` and the result is
    ``min(255, fogged + G)``. Both the strength (through ``1 − e^{−αℓ}``) and the width grow with α; with
    ``α = 0`` nothing is added. The Gaussian is applied on a grid coarse enough for its width (:func:`glow_grids`).

    >>> clean = np.zeros((41, 41, 3), np.uint8); clean[20, 20] = 255
    >>> K = np.array([[100.0, 0, 20.5], [0, 100.0, 20.5], [0, 0, 1]])
    >>> d = np.full((41, 41), 40.0, np.float32)
    >>> g = add_glow(np.zeros_like(clean), clean, d, K, 0.06)
    >>> bool(g[20, 24, 0] > g[20, 28, 0] > 0), int(add_glow(clean, clean, d, K, 0.0)[20, 19, 0])
    (True, 0)
    """
    out = np.array(fogged, np.uint8, copy=True)
    return out if alpha <= 0.0 else add_glows(out[None], clean, depth, K, [alpha])[0]

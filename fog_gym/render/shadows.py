"""Sun shadows on the ground: every primitive's silhouette cast along the sun onto the road, as a grid around the ego.

Each primitive's points (a box's eight corners; a mesh's placed outline: its vertices on its convex hull) move along the sun's rays down to z = 0,
``p − (p_z / s_z) · s`` for the sun direction ``s``; the convex hull of those footprints is the primitive's shadow
(exact for a box; for a vehicle body, a tree's trunk or crown, a building's part, their convex outline), filled into a
:class:`ShadowMap` of :data:`RESOLUTION` metres around the ego. The rasteriser shades a ground pixel in shadow with the
ambient light alone (:func:`fog_gym.render.surface.shadow_lut`). Shadows fall on the side away from the sun, as long
as the caster is tall divided by the tangent of the sun's elevation.

Example:
    >>> prims = {"centers": [[0.0, 0.0, 5.0]], "halves": [[0.5, 0.5, 5.0]], "yaws": [0.0]}
    >>> sun = np.array([1.0, 0.0, 1.0]) / np.sqrt(2.0)         # 45° elevation, towards +x
    >>> sm = shadow_map(prims, sun, (0.0, 0.0), half=20.0, resolution=0.5)
    >>> xs = np.flatnonzero(sm.grid[int((0.0 - sm.origin[1]) / 0.5)]) * 0.5 + sm.origin[0] + 0.25
    >>> float(xs.min()), float(xs.max())                      # the 10 m pole's shadow runs 10 m away from the sun
    (-10.25, 0.25)
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from fog_gym._numba import defer  # (numba's fork-safe threading layer, before any kernel runs)
from fog_gym.geometry import BOX_CORNER_SIGNS as _SIGNS
from fog_gym.world.meshlib import LIBRARY
from fog_gym.world.primitives import Primitives

#: Shadow-map cell [m] and half-width of the window around the ego [m].
RESOLUTION, HALF = 0.2, 80.0


class ShadowMap(NamedTuple):
    """Ground cells in shadow (rows = y, cols = x) uint8; cell (0, 0)'s corner at ``origin``; ``resolution`` m."""

    grid: np.ndarray
    origin: tuple[float, float]
    resolution: float

    @classmethod
    def empty(cls) -> ShadowMap:
        """No shadows (nights, and the boxes' geometry)."""
        return cls(np.zeros((1, 1), np.uint8), (1e18, 1e18), 1.0)


@njit(cache=True, nogil=True)
def _hull_fill(pts, n, grid, ox, oy, inv, order, hull):
    """Fill the convex hull of the first ``n`` points (x, y) into ``grid`` (cells whose centre lies inside);
    ``order`` (≥ n) and ``hull`` (≥ 2 n + 1, 2) are scratch space."""
    # monotone chain, over the points sorted by x + 1e-9 y (insertion sort: a few dozen points, no allocation)
    for q in range(n):
        key = pts[q, 0] + 1e-9 * pts[q, 1]
        j = q
        while j > 0 and pts[order[j - 1], 0] + 1e-9 * pts[order[j - 1], 1] > key:
            order[j] = order[j - 1]
            j -= 1
        order[j] = q
    m = 0
    for rep in range(2):
        start = m
        for q in range(n):
            k = order[q] if rep == 0 else order[n - 1 - q]
            x, y = pts[k, 0], pts[k, 1]
            while m >= start + 2:
                ux = hull[m - 1, 0] - hull[m - 2, 0]
                uy = hull[m - 1, 1] - hull[m - 2, 1]
                if ux * (y - hull[m - 2, 1]) - uy * (x - hull[m - 2, 0]) <= 0.0:
                    m -= 1
                else:
                    break
            hull[m, 0] = x
            hull[m, 1] = y
            m += 1
        m -= 1  # the last point of each chain starts the other
    if m < 3:
        return
    rows, cols = grid.shape
    ymin, ymax = hull[:m, 1].min(), hull[:m, 1].max()
    r0 = max(int(np.ceil((ymin - oy) * inv - 0.5)), 0)
    r1 = min(int(np.floor((ymax - oy) * inv - 0.5)), rows - 1)
    for r in range(r0, r1 + 1):
        y = oy + (r + 0.5) / inv
        lo = 1e30
        hi = -1e30
        for q in range(m):
            x0, y0 = hull[q, 0], hull[q, 1]
            x1, y1 = hull[(q + 1) % m, 0], hull[(q + 1) % m, 1]
            if (y0 <= y <= y1) or (y1 <= y <= y0):
                if abs(y1 - y0) < 1e-12:
                    lo = min(lo, min(x0, x1))
                    hi = max(hi, max(x0, x1))
                else:
                    x = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
                    lo = min(lo, x)
                    hi = max(hi, x)
        c0 = max(int(np.ceil((lo - ox) * inv - 0.5)), 0)
        c1 = min(int(np.floor((hi - ox) * inv - 0.5)), cols - 1)
        for c in range(c0, c1 + 1):
            grid[r, c] = 1


@njit(cache=True, nogil=True)
def _shadow_map(grid, centers, halves, yaws, meshes, outline, outline_start, sun, ox, oy, inv, reach):
    """Fill every caster's shadow into ``grid`` (cell (0, 0)'s corner at ``ox``, ``oy``; ``1 / inv`` m cells) and
    return it; casters whose shadow cannot reach within ``reach`` of the grid's centre are skipped. A mesh casts
    from its outline vertices (:class:`~fog_gym.world.meshlib.LibraryArrays`' ``outline``)."""
    rows, cols = grid.shape
    kx = sun[0] / sun[2]
    ky = sun[1] / sun[2]
    cx0 = ox + 0.5 * cols / inv
    cy0 = oy + 0.5 * rows / inv
    max_v = 8
    for p in range(centers.shape[0]):
        if meshes[p] != 0:
            max_v = max(max_v, outline_start[meshes[p] + 1] - outline_start[meshes[p]])
    pts = np.empty((max_v, 2))
    order = np.empty(max_v, np.int64)
    hull = np.empty((2 * max_v + 1, 2))
    for p in range(centers.shape[0]):
        # skip casters whose shadow cannot reach the window (its half-diagonal plus the top's displacement)
        top = centers[p, 2] + halves[p, 2]
        span = np.sqrt(halves[p, 0] ** 2 + halves[p, 1] ** 2) + top * np.sqrt(kx * kx + ky * ky)
        if abs(centers[p, 0] - cx0) > reach + span or abs(centers[p, 1] - cy0) > reach + span:
            continue
        c = np.cos(yaws[p])
        s = np.sin(yaws[p])
        n = 0
        if meshes[p] == 0:
            for k in range(8):
                lx = _SIGNS[k, 0] * halves[p, 0]
                ly = _SIGNS[k, 1] * halves[p, 1]
                z = centers[p, 2] + _SIGNS[k, 2] * halves[p, 2]
                pts[n, 0] = centers[p, 0] + lx * c - ly * s - z * kx
                pts[n, 1] = centers[p, 1] + lx * s + ly * c - z * ky
                n += 1
        else:
            for v in range(outline_start[meshes[p]], outline_start[meshes[p] + 1]):
                lx = outline[v, 0] * 2.0 * halves[p, 0]
                ly = outline[v, 1] * 2.0 * halves[p, 1]
                z = centers[p, 2] + outline[v, 2] * 2.0 * halves[p, 2]
                pts[n, 0] = centers[p, 0] + lx * c - ly * s - z * kx
                pts[n, 1] = centers[p, 1] + lx * s + ly * c - z * ky
                n += 1
        _hull_fill(pts, n, grid, ox, oy, inv, order, hull)
    return grid


def shadow_map(prims: Primitives | Mapping[str, Any], sun_dir: np.ndarray, center: tuple[float, float],
               half: float = HALF, resolution: float = RESOLUTION) -> ShadowMap:  # fmt: skip
    """The ground cells that ``prims`` shade from a sun in direction ``sun_dir`` (pointing at the sun, above the
    horizon), in a square ``half`` metres around ``center``, cells ``resolution`` metres wide."""
    sun = _checked(sun_dir, half, resolution)
    prims = Primitives.coerce(prims)
    n = int(np.ceil(2 * half / resolution))
    ox, oy = float(center[0]) - half, float(center[1]) - half
    return ShadowMap(_fill(np.zeros((n, n), np.uint8), prims, sun, ox, oy, resolution), (ox, oy), float(resolution))


def _checked(sun_dir: np.ndarray, half: float, resolution: float) -> np.ndarray:
    """The sun direction as float64, after refusing a sun at or below the horizon and a non-positive size."""
    sun = np.asarray(sun_dir, np.float64)
    if sun.shape != (3,) or not np.isfinite(sun).all() or sun[2] <= 1e-6:
        raise ValueError(f"sun_dir must be a finite direction above the horizon, got {sun.tolist()}")
    if not (half > 0 and resolution > 0):
        raise ValueError(f"half and resolution must be > 0, got {half!r}, {resolution!r}")
    return sun


def _fill(grid: np.ndarray, prims: Primitives, sun: np.ndarray, ox: float, oy: float, resolution: float) -> np.ndarray:
    lib = LIBRARY.arrays()
    reach = 0.5 * max(grid.shape) * resolution
    unit = np.array(_unit(tuple(sun.tolist())))
    return defer(_shadow_map)(grid, prims.centers, prims.halves, prims.yaws, prims.meshes, lib.outline,
                              lib.outline_start, unit, float(ox), float(oy), 1.0 / resolution, float(reach))  # fmt: skip


@functools.lru_cache(maxsize=64)
def _unit(sun: tuple[float, float, float]) -> tuple[float, float, float]:
    """``sun`` over its length, once per sun (``np.linalg.norm`` calls BLAS, which releases the GIL)."""
    v = np.asarray(sun, np.float64)
    return tuple((v / np.linalg.norm(v)).tolist())


class ShadowCache:
    """Shadow maps of a static world and moving casters, the static part filled once: the static casters' shadows go
    into a map ``margin`` metres wider on every side than the window, on a grid of ``resolution`` cells from the
    origin, and each frame's window is a crop of it (its corner on that grid) with the moving casters' shadows added.
    The static map is filled again when the static world, the sun, the window's size or cell change, or when the
    window leaves it. A window equals :func:`shadow_map` of all casters with the same corner (tested).

    >>> static = {"centers": [[0.0, 0.0, 5.0]], "halves": [[0.5, 0.5, 5.0]], "yaws": [0.0]}
    >>> cache, sun = ShadowCache(), np.array([1.0, 0.0, 1.0]) / np.sqrt(2.0)
    >>> sm = cache.window(static, "town", Primitives.empty(), sun, (3.0, 0.0), half=20.0, resolution=0.5)
    >>> int(sm.grid.sum()), sm.origin                          # the pole's 10 m shadow and footprint, 2 cells wide
    (44, (-17.0, -20.0))
    >>> cache.window(static, "town", Primitives.empty(), sun, (3.2, 0.1), half=20.0, resolution=0.5).origin
    (-17.0, -20.0)
    """

    def __init__(self, margin: float = 40.0) -> None:
        self.margin = float(margin)
        self._key: tuple | None = None
        self._map: ShadowMap | None = None

    def window(self, static: Primitives | Mapping[str, Any], key: Any, moving: Primitives | Mapping[str, Any],
               sun_dir: np.ndarray, center: tuple[float, float], half: float = HALF,
               resolution: float = RESOLUTION) -> ShadowMap:  # fmt: skip
        """The shadows of ``static`` (identified by ``key``: the same key, the same casters) and ``moving`` in a
        square about ``half`` metres around ``center`` (its corner on the ``resolution`` grid)."""
        sun = _checked(sun_dir, half, resolution)
        n = int(np.ceil(2 * half / resolution))
        full = (key, tuple(sun.tolist()), float(half), float(resolution))
        c0 = r0 = -1
        if self._map is not None and self._key == full:
            c0 = int(round((center[0] - half - self._map.origin[0]) / resolution))
            r0 = int(round((center[1] - half - self._map.origin[1]) / resolution))
        rows, cols = (0, 0) if self._map is None else self._map.grid.shape
        if not (0 <= c0 and c0 + n <= cols and 0 <= r0 and r0 + n <= rows):
            big = int(np.ceil(2 * (half + self.margin) / resolution))
            ox = np.floor((center[0] - half - self.margin) / resolution) * resolution
            oy = np.floor((center[1] - half - self.margin) / resolution) * resolution
            grid = _fill(np.zeros((big, big), np.uint8), Primitives.coerce(static), sun, ox, oy, resolution)
            self._map, self._key = ShadowMap(grid, (float(ox), float(oy)), float(resolution)), full
            c0 = int(round((center[0] - half - ox) / resolution))
            r0 = int(round((center[1] - half - oy) / resolution))
        ox, oy = self._map.origin[0] + c0 * resolution, self._map.origin[1] + r0 * resolution
        grid = self._map.grid[r0 : r0 + n, c0 : c0 + n].copy()
        return ShadowMap(_fill(grid, Primitives.coerce(moving), sun, ox, oy, resolution), (ox, oy), float(resolution))

"""The road surface as the renderer reads it: the class map in cache-friendly 8×8 tiles (:class:`TiledSurface`, built
once per static world by :func:`tiled_surface`), its per-pixel lookup with a hashed texture (:func:`surface_cell`)
and the colour tables of day and night (:func:`ground_lut`, :func:`albedo_lut`).

Example:
    >>> t = tile_surface(np.arange(4, dtype=np.uint8).reshape(2, 2), (0.0, 0.0), 1.0)
    >>> [surface_cell(x + 0.5, y + 0.5, t.flat, t.rows, t.cols, t.tiles_x)[0] for y in (0, 1) for x in (0, 1)]
    [0, 1, 2, 3]
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numba import njit

from fog_gym.world.scene import evict_oldest
from fog_gym.world.scenery import SURFACE_RGB


@njit(cache=True, inline="always")
def hash_noise(ix, iy):
    h = (ix * 73856093) ^ (iy * 19349663)
    h = (h ^ (h >> 13)) * 1274126177
    return (h >> 7) & 15


@njit(cache=True, inline="always")
def surface_cell(fxw, fyw, surface, s_rows, s_cols, tiles_x):
    """Surface class at surface-grid coordinates (fxw, fyw) (0 off the map) and its colour-table row."""
    cls = 0
    gx = 0
    gy = 0
    if fxw >= 0.0 and fyw >= 0.0 and fxw < s_cols and fyw < s_rows:
        gx = int(fxw)
        gy = int(fyw)
        cls = surface[(((gy >> 3) * tiles_x + (gx >> 3)) << 6) + ((gy & 7) << 3) + (gx & 7)]
    return cls, cls * 16 + hash_noise(gx, gy)


class TiledSurface(NamedTuple):
    """A road-surface class map stored in 8×8 tiles (one cache line each), for fast lookups from any view."""

    flat: np.ndarray  # uint8, tiled
    rows: int
    cols: int
    tiles_x: int
    origin: tuple[float, float]  # world (x, y) of cell (0, 0)'s corner
    resolution: float  # metres per cell


def tile_surface(grid: np.ndarray, origin: tuple[float, float], resolution: float) -> TiledSurface:
    """Convert a row-major (rows = world y, cols = world x) class grid into :class:`TiledSurface`."""
    rows, cols = grid.shape
    ty, tx = -(-rows // 8), -(-cols // 8)
    padded = np.zeros((ty * 8, tx * 8), np.uint8)
    padded[:rows, :cols] = grid
    flat = np.ascontiguousarray(padded.reshape(ty, 8, tx, 8).transpose(0, 2, 1, 3)).reshape(-1)
    return TiledSurface(flat, rows, cols, tx, (float(origin[0]), float(origin[1])), float(resolution))


_TILED: dict[int, tuple[Any, TiledSurface]] = {}


def tiled_surface(static: Any) -> TiledSurface:
    """The :class:`TiledSurface` of a :class:`~fog_gym.world.scene.StaticWorld`'s road-surface map, built once per
    static world (the last few are kept)."""
    hit = _TILED.get(id(static))
    if hit is not None and hit[0] is static:
        return hit[1]
    s = static.surface
    tiled = tile_surface(s.grid, s.origin, s.resolution)
    evict_oldest(_TILED, 8)
    _TILED[id(static)] = (static, tiled)
    return tiled


def surface_lut(class_rgb: np.ndarray, texture_amp: float) -> np.ndarray:
    """Per-class shaded colours with 16 texture levels: ``(n_classes * 16, 3)`` uint8."""
    base = np.asarray(class_rgb, np.float64)[:, None, :]
    levels = (np.arange(16) - 7.5)[None, :, None] * texture_amp
    return np.clip(np.rint(base + levels), 0, 255).astype(np.uint8).reshape(-1, 3)


_SHADED: dict[tuple[float, float], np.ndarray] = {}


def _shaded_lut(shade: float, texture_amp: float) -> np.ndarray:
    # surface_lut of the surface colours times shade, kept per (shade, amplitude): a light's tables are the same every
    # frame (shared: not to be written; not flagged read-only, which would give the kernels that read it a signature
    # of its own to compile)
    key = (float(shade), float(texture_amp))
    lut = _SHADED.get(key)
    if lut is None:
        lut = surface_lut(SURFACE_RGB * key[0], key[1])
        evict_oldest(_SHADED, 64)
        _SHADED[key] = lut
    return lut


def ground_lut(lighting: Any) -> np.ndarray:
    """The road-surface colours of a day :class:`~fog_gym.world.scene.Lighting`, shaded by its sun and ambient
    (the same array for every frame of a light: not to be written)."""
    return _shaded_lut(lighting.ground_shade, lighting.texture_amp)


def shadow_lut(lighting: Any) -> np.ndarray:
    """The road-surface colours of a day :class:`~fog_gym.world.scene.Lighting` in shade: its ambient light only
    (shared, as :func:`ground_lut`'s)."""
    return _shaded_lut(lighting.ambient, lighting.texture_amp)


def albedo_lut() -> np.ndarray:
    """Unshaded surface colours (day texture) for the night lighting pass (shared, as :func:`ground_lut`'s)."""
    return _shaded_lut(1.0, 1.0)

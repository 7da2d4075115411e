"""Pillarisation of LiDAR sweeps for the PointPillars-style detector (Lang et al., CVPR 2019). Pure numpy + numba.

A sweep's points inside the grid (``±range_m`` in x and y, ``z_min ≤ z < z_max``; :class:`~.bev.BEVGrid`) are
grouped by the vertical column ("pillar") of ``cell_m × cell_m`` they fall in. :func:`pillarise` does it once per
sweep and its result is what the study caches (:mod:`~.cache`): the points sorted by pillar (row-major flat cell
``i · W + j``, ``i`` the x cell, ``j`` the y cell), each pillar's points in a fixed random order (seeded), the
non-empty pillars' flat cells and point counts. :func:`pillar_points` then keeps at most ``max_points`` points per
pillar (the first ones of that order: a seeded random subsample, as the paper's) and decorates each with the
paper's nine features: ``x, y, z, r``, the offsets ``x_c, y_c, z_c`` to the mean of the pillar's kept points and
``x_p, y_p`` to the pillar's centre.

Mirroring a sweep (``y → −y`` or ``x → −x``; :func:`mirror`) maps every pillar onto the mirrored cell with the
same points, so the cached pillars serve the flip augmentation exactly.

Example:
    >>> grid = BEVGrid(range_m=2.0, cell_m=1.0, stride=1)
    >>> p = pillarise(np.array([[0.2, 0.3, -1.0, 0.5], [0.7, 0.1, 0.0, 0.1], [-1.5, 1.2, 0.5, 0.9]], np.float32), grid)
    >>> p.cells.tolist(), p.counts.tolist()
    ([3, 10], [1, 2])
    >>> f, pillar = pillar_points(p, grid, max_points=32)
    >>> f.shape, pillar.tolist()
    ((3, 9), [0, 1, 1])
    >>> [round(float(v), 3) for v in f[0]]  # x y z r, offsets to the mean (one point: 0), offsets to the centre
    [-1.5, 1.2, 0.5, 0.9, 0.0, 0.0, 0.0, 0.0, -0.3]
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from fog_gym.experiments.detection3d.bev import BEVGrid

#: Features per point after decoration (x, y, z, r, x_c, y_c, z_c, x_p, y_p).
POINT_FEATURES = 9


@dataclass(frozen=True)
class Pillars:
    """A pillarised sweep: ``points`` (M, 4) float32 sorted by pillar, ``cells`` (P,) int64 flat cells in
    ascending order, ``counts`` (P,) int64 points per pillar (sum M)."""

    points: np.ndarray
    cells: np.ndarray
    counts: np.ndarray

    def __post_init__(self) -> None:
        if self.points.ndim != 2 or self.points.shape[1] != 4 or len(self.cells) != len(self.counts):
            raise ValueError("points must be (M, 4) and cells and counts of equal length")
        if int(self.counts.sum()) != len(self.points):
            raise ValueError(f"counts sum to {int(self.counts.sum())}, but there are {len(self.points)} points")

    @property
    def starts(self) -> np.ndarray:
        """Index of each pillar's first point."""
        return np.concatenate([[0], np.cumsum(self.counts)[:-1]]).astype(np.int64)

    def save(self) -> dict[str, np.ndarray]:
        return {"points": self.points, "cells": self.cells.astype(np.int32), "counts": self.counts.astype(np.int32)}

    @classmethod
    def load(cls, d) -> Pillars:
        return cls(np.asarray(d["points"], np.float32), np.asarray(d["cells"], np.int64), np.asarray(d["counts"], np.int64))


@njit(cache=True, nogil=True)
def _cells(points, range_m, cell_m, z_min, z_max, n):
    """Flat cell of each point, −1 outside the grid."""
    out = np.empty(points.shape[0], np.int64)
    for k in range(points.shape[0]):
        x, y, z = points[k, 0], points[k, 1], points[k, 2]
        i = int(math.floor((x + range_m) / cell_m))
        j = int(math.floor((y + range_m) / cell_m))
        if z < z_min or z >= z_max or i < 0 or i >= n or j < 0 or j >= n:
            out[k] = -1
        else:
            out[k] = i * n + j
    return out


def _runs(starts: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """The indices ``starts[k], …, starts[k] + lengths[k] − 1`` of every run, concatenated."""
    lengths = np.asarray(lengths, np.int64)
    first = np.cumsum(lengths) - lengths
    return np.repeat(np.asarray(starts, np.int64) - first, lengths) + np.arange(int(lengths.sum()))


def pillarise(points: np.ndarray, grid: BEVGrid, seed: int = 0) -> Pillars:
    """Group an ``(N, ≥4)`` sweep's points inside ``grid`` by pillar (module docstring); the order of the points
    within a pillar is a random permutation drawn from ``seed``."""
    pts = np.asarray(points, np.float32)
    if pts.ndim != 2 or pts.shape[1] < 4:
        raise ValueError(f"points must be an (N, >=4) array (x, y, z, intensity, ...), got shape {pts.shape}")
    pts = np.ascontiguousarray(pts[:, :4])
    n = grid.shape[0]
    cell = _cells(pts, float(grid.range_m), float(grid.cell_m), float(grid.z_min), float(grid.z_max), n)
    keep = np.flatnonzero(cell >= 0)
    shuffled = keep[np.random.default_rng(seed).permutation(len(keep))]
    order = shuffled[np.argsort(cell[shuffled], kind="stable")]  # by pillar; random within a pillar
    cells, counts = np.unique(cell[order], return_counts=True)
    return Pillars(pts[order], cells.astype(np.int64), counts.astype(np.int64))


def mirror(p: Pillars, grid: BEVGrid, flip_y: bool, flip_x: bool = False) -> Pillars:
    """The pillars of the sweep mirrored across the x axis (``y → −y``) and/or the y axis (``x → −x``)."""
    if not (flip_y or flip_x):
        return p
    n = grid.shape[0]
    i, j = p.cells // n, p.cells % n
    if flip_y:
        j = n - 1 - j
    if flip_x:
        i = n - 1 - i
    cells = i * n + j
    order = np.argsort(cells, kind="stable")
    pts = p.points[_runs(p.starts[order], p.counts[order])] * np.float32([-1 if flip_x else 1, -1 if flip_y else 1, 1, 1])
    return Pillars(pts, cells[order], p.counts[order])


def pillar_points(p: Pillars, grid: BEVGrid, max_points: int = 32) -> tuple[np.ndarray, np.ndarray]:
    """The decorated points ``(M', 9)`` float32 (at most ``max_points`` per pillar, the first in the cached order)
    and the index of each one's pillar in ``p.cells`` ``(M',)``."""
    if isinstance(max_points, bool) or not isinstance(max_points, (int, np.integer)) or max_points < 1:
        raise ValueError(f"max_points must be a positive integer, got {max_points!r}")
    counts = np.minimum(p.counts, max_points)
    pillar = np.repeat(np.arange(len(p.cells)), counts)
    pts = p.points[_runs(p.starts, counts)]
    sums = np.stack([np.bincount(pillar, pts[:, k], len(p.cells)) for k in range(3)], axis=1)
    means = (sums / np.maximum(counts, 1)[:, None]).astype(np.float32)
    n = grid.shape[0]
    centre = np.stack([(p.cells // n + 0.5) * grid.cell_m - grid.range_m, (p.cells % n + 0.5) * grid.cell_m - grid.range_m],
                      axis=1).astype(np.float32)  # fmt: skip
    feats = np.concatenate([pts, pts[:, :3] - means[pillar], pts[:, :2] - centre[pillar]], axis=1)
    return feats.astype(np.float32), pillar

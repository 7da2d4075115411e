"""Bird's-eye-view encoding of LiDAR sweeps and of 3D boxes for the baseline detector. Pure numpy + numba.

The grid covers ``±range_m`` around the LiDAR in x and y (FogDrive's ±40 m) at ``cell_m`` per cell; each cell
holds five features of the points above it (a PIXOR-style hand-made pillar encoding, cheap on a CPU):
``log(1 + count)``, highest, mean and lowest z (metres relative to ``z_min``, scaled by the z span) and mean
intensity. Boxes ``(N, 7)`` ``[x, y, z, l, w, h, yaw]`` come from FogDrive's eight-corner JSON with
:func:`boxes_from_corners`; the class from the box height with :func:`class_from_height` (fog-gym's classes have
disjoint height ranges, and FogDrive's 3D box files carry no class).

Example:
    >>> grid = BEVGrid()
    >>> grid.shape, grid.out_shape
    ((160, 160), (80, 80))
    >>> class_from_height(np.array([1.5, 2.2, 3.4])).tolist()
    [0, 4, 1]
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from fog_gym.geometry import corners_to_boxes as boxes_from_corners  # noqa: F401  (re-exported)

#: fog-gym's vehicle classes (FogDrive ids) in the detector's channel order, and their height boundaries [m]:
#: car 1.40–1.60, bigger car 1.85–2.50, truck 3.00–3.80 (``fog_gym.world.traffic_world.CLASS_SPECS``).
CLASSES = (0, 4, 1)
CLASS_LABELS = {0: "car", 4: "bigger car", 1: "truck"}
_HEIGHT_EDGES = (1.725, 2.75)
N_FEATURES = 5


def class_from_height(h: np.ndarray) -> np.ndarray:
    """FogDrive class id of boxes of height ``h`` [m]."""
    h = np.asarray(h, np.float64)
    return np.where(h < _HEIGHT_EDGES[0], 0, np.where(h < _HEIGHT_EDGES[1], 4, 1)).astype(np.int64)


@dataclass(frozen=True)
class BEVGrid:
    """The detector's grid: ``±range_m`` square at ``cell_m``, z from ``z_min`` to ``z_max`` (LiDAR frame; the
    FogDrive LiDAR sits 2 m above the road), outputs at ``stride`` cells."""

    range_m: float = 40.0
    cell_m: float = 0.5
    z_min: float = -3.0
    z_max: float = 2.0
    stride: int = 2

    def __post_init__(self) -> None:
        for name in ("range_m", "cell_m"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a positive number, got {v!r}")
        if not self.z_max > self.z_min:
            raise ValueError(f"z_max must exceed z_min, got {self.z_min} and {self.z_max}")
        n = 2 * self.range_m / self.cell_m
        if abs(n - round(n)) > 1e-9 or round(n) % self.stride:
            raise ValueError(f"2·range_m / cell_m must be an integer multiple of stride, got {n}")

    @property
    def shape(self) -> tuple[int, int]:
        n = int(round(2 * self.range_m / self.cell_m))
        return n, n

    @property
    def out_shape(self) -> tuple[int, int]:
        return self.shape[0] // self.stride, self.shape[1] // self.stride

    @property
    def out_cell_m(self) -> float:
        return self.cell_m * self.stride

    def in_range(self, boxes: np.ndarray) -> np.ndarray:
        """Mask of boxes whose centre lies inside the grid."""
        b = np.asarray(boxes).reshape(-1, 7)
        return (np.abs(b[:, 0]) < self.range_m) & (np.abs(b[:, 1]) < self.range_m)


@njit(cache=True, nogil=True)
def _features(points, range_m, cell_m, z_min, z_max, n):
    out = np.zeros((N_FEATURES, n, n), np.float32)
    count = np.zeros((n, n), np.int32)
    zspan = z_max - z_min
    for k in range(points.shape[0]):
        x, y, z = points[k, 0], points[k, 1], points[k, 2]
        if z < z_min or z >= z_max:
            continue
        i = int(math.floor((x + range_m) / cell_m))
        j = int(math.floor((y + range_m) / cell_m))
        if i < 0 or i >= n or j < 0 or j >= n:
            continue
        zn = (z - z_min) / zspan
        c = count[i, j]
        if c == 0:
            out[1, i, j] = zn
            out[3, i, j] = zn
        else:
            out[1, i, j] = max(out[1, i, j], zn)
            out[3, i, j] = min(out[3, i, j], zn)
        out[2, i, j] += zn
        out[4, i, j] += points[k, 3]
        count[i, j] = c + 1
    for i in range(n):
        for j in range(n):
            c = count[i, j]
            if c > 0:
                out[0, i, j] = math.log1p(c)
                out[2, i, j] /= c
                out[4, i, j] /= c
    return out


def point_features(points: np.ndarray, grid: BEVGrid = BEVGrid()) -> np.ndarray:
    """``(5, H, W)`` float32 features of an ``(N, ≥4)`` sweep (x, y, z, intensity); row = x cell, column = y cell.

    >>> f = point_features(np.array([[0.1, 0.1, -1.0, 0.5], [0.2, 0.3, 0.0, 0.7]], np.float32))
    >>> [round(float(v), 3) for v in f[:, 80, 80]]  # log 3, max z, mean z, min z (of 5 m span), intensity
    [1.099, 0.6, 0.5, 0.4, 0.6]
    """
    pts = np.asarray(points, np.float32)
    if pts.ndim != 2 or pts.shape[1] < 4:
        raise ValueError(f"points must be an (N, >=4) array (x, y, z, intensity, ...), got shape {pts.shape}")
    return _features(np.ascontiguousarray(pts[:, :4]), grid.range_m, grid.cell_m, grid.z_min, grid.z_max, grid.shape[0])


def _gaussian_sigma(length: float, width: float, cell: float) -> float:
    return max(min(length, width) / cell / 3.0, 0.8)


def make_targets(boxes: np.ndarray, classes: np.ndarray, grid: BEVGrid = BEVGrid()) -> dict[str, np.ndarray]:
    """CenterNet targets on the output grid: ``heatmap`` (K, H, W) Gaussian peaks of 1 at box centres, and per box
    ``index`` (flat cell), ``regression`` (8: cell offsets dx, dy, z, log l, log w, log h, sin yaw, cos yaw)."""
    b = np.asarray(boxes, np.float64).reshape(-1, 7)
    cls = np.asarray(classes, np.int64).reshape(-1)
    keep = grid.in_range(b) & np.isin(cls, CLASSES)
    b, cls = b[keep], cls[keep]
    h, w = grid.out_shape
    cell = grid.out_cell_m
    heat = np.zeros((len(CLASSES), h, w), np.float32)
    fx = (b[:, 0] + grid.range_m) / cell
    fy = (b[:, 1] + grid.range_m) / cell
    ix, iy = np.floor(fx).astype(np.int64), np.floor(fy).astype(np.int64)
    rows, cols = np.arange(h)[:, None] + 0.5, np.arange(w)[None, :] + 0.5
    for k in range(len(b)):
        s = _gaussian_sigma(b[k, 3], b[k, 4], cell)
        g = np.exp(-((rows - fx[k]) ** 2 + (cols - fy[k]) ** 2) / (2 * s * s)).astype(np.float32)
        c = CLASSES.index(int(cls[k]))
        heat[c] = np.maximum(heat[c], g)
        heat[c, ix[k], iy[k]] = 1.0
    reg = np.stack([fx - ix, fy - iy, b[:, 2], np.log(b[:, 3]), np.log(b[:, 4]), np.log(b[:, 5]), np.sin(b[:, 6]),
                    np.cos(b[:, 6])], axis=1).astype(np.float32)  # fmt: skip
    return {"heatmap": heat, "index": (ix * w + iy).astype(np.int64), "regression": reg,
            "classes": np.array([CLASSES.index(int(c)) for c in cls], np.int64)}  # fmt: skip


def decode_cells(index: np.ndarray, regression: np.ndarray, grid: BEVGrid = BEVGrid()) -> np.ndarray:
    """``(N, 7)`` boxes from flat output cells and their 8 regression values (the inverse of :func:`make_targets`)."""
    idx = np.asarray(index, np.int64).reshape(-1)
    r = np.asarray(regression, np.float64).reshape(-1, 8)
    w = grid.out_shape[1]
    cell = grid.out_cell_m
    x = (idx // w + r[:, 0]) * cell - grid.range_m
    y = (idx % w + r[:, 1]) * cell - grid.range_m
    size = np.exp(np.clip(r[:, 3:6], -3.0, 3.0))  # an untrained network cannot ask for a 10⁴³ m box
    return np.stack([x, y, r[:, 2], size[:, 0], size[:, 1], size[:, 2], np.arctan2(r[:, 6], r[:, 7])], axis=1)

"""The fleet: FogDrive's vehicle classes (supplementary D1: 0 car, 1 truck, 4 bigger car), their spawn shares, size
ranges and colours, the ego car, :class:`VehicleState` (every vehicle at one instant as arrays) and the draws
that give a spawned vehicle its class, size and colour (:func:`draw_vehicle`; both traffic cores use it, so a seed
gives the same fleet in each).

Example:
    >>> cls, size, color = draw_vehicle(np.random.default_rng(0))
    >>> cls in CLASS_SPECS, len(size), bool((0 <= color).all() and (color <= 1).all())
    (True, 3, True)
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass

import numpy as np

EGO_ID = 1
#: Tesla Model 3 (CARLA ``vehicle.tesla.model3`` bounding box): length, width, height [m].
EGO_SIZE = (4.79, 2.16, 1.49)
#: Spawn probability and (length, width, height) ranges of each class.
CLASS_SPECS: dict[int, tuple[float, tuple[float, float], tuple[float, float], tuple[float, float]]] = {
    0: (0.72, (4.2, 4.9), (1.80, 2.00), (1.40, 1.60)),
    4: (0.18, (4.9, 5.9), (1.95, 2.10), (1.85, 2.50)),
    1: (0.10, (7.5, 10.0), (2.40, 2.60), (3.00, 3.80)),
}
_CAR_COLORS = np.array([
    [0.92, 0.92, 0.92], [0.08, 0.08, 0.09], [0.62, 0.63, 0.65], [0.35, 0.36, 0.38], [0.70, 0.08, 0.07],
    [0.10, 0.22, 0.55], [0.05, 0.10, 0.25], [0.12, 0.32, 0.18], [0.85, 0.65, 0.10], [0.55, 0.32, 0.18],
])  # fmt: skip
#: The ego's colour.
EGO_COLOR = np.array([0.75, 0.10, 0.10])


_CLASSES = list(CLASS_SPECS)
_CDF = np.array([CLASS_SPECS[c][0] for c in _CLASSES]).cumsum()
_CDF /= _CDF[-1]
_CDF_LIST = _CDF.tolist()  # (numpy's searchsorted releases the GIL for one number; bisect does not)


def draw_vehicle(rng: np.random.Generator) -> tuple[int, tuple[float, float, float], np.ndarray]:
    """``(class, (length, width, height), colour)`` of one spawned vehicle, drawn from ``rng`` in a fixed order (class,
    length, width, height, colour, brightness). The class is ``rng.choice(classes, p=shares)`` written out as numpy
    computes it (one uniform against the normalised cumulative shares), which is the same draw without its checks."""
    cls = int(_CLASSES[bisect.bisect_right(_CDF_LIST, rng.random())])  # _CDF.searchsorted(side="right"), in Python
    _, lr, wr, hr = CLASS_SPECS[cls]
    length, width, height = float(rng.uniform(*lr)), float(rng.uniform(*wr)), float(rng.uniform(*hr))
    color = _CAR_COLORS[rng.integers(len(_CAR_COLORS))] * rng.uniform(0.9, 1.05)
    return cls, (length, width, height), np.minimum(np.maximum(color, 0.0), 1.0)


@dataclass(frozen=True)
class VehicleState:
    """All vehicles at one instant (ego first). Positions are box centres at z = h/2, CARLA world frame."""

    ids: np.ndarray  # (N,) int32, stable for the episode
    classes: np.ndarray  # (N,) int8, FogDrive taxonomy
    centers: np.ndarray  # (N, 3)
    sizes: np.ndarray  # (N, 3) length, width, height
    yaws: np.ndarray  # (N,) radians
    velocities: np.ndarray  # (N, 3) m/s, world frame
    colors: np.ndarray  # (N, 3) albedo in [0, 1]

    def __len__(self) -> int:
        return len(self.ids)

    def take(self, mask: np.ndarray) -> VehicleState:
        """The vehicles where the boolean ``mask`` holds, every array a copy, in order. Contiguous rows (the ego:
        row 0; every other vehicle: rows 1 …) are sliced rather than indexed: numpy releases the GIL to index with a
        mask or an index array however few the rows, and in the pixel vector env another world's thread then takes
        it for its whole stretch of Python (docs/performance.md).

        >>> v = VehicleState(np.array([1, 7, 9]), np.zeros(3, np.int8), np.eye(3), np.ones((3, 3)), np.zeros(3),
        ...                  np.zeros((3, 3)), np.ones((3, 3)))
        >>> v.take(v.ids != 1).ids.tolist(), v.take(v.ids == 1).centers.tolist(), len(v.take(v.ids == 3))
        ([7, 9], [[1.0, 0.0, 0.0]], 0)
        """
        mask = np.asarray(mask)
        if mask.dtype != np.bool_ or mask.shape != (len(self),):
            raise ValueError(f"mask must be a boolean array of shape ({len(self)},), got {mask.dtype} {mask.shape}")
        rows = np.flatnonzero(mask)
        if len(rows) == 0 or rows[-1] - rows[0] + 1 == len(rows):
            sel = slice(int(rows[0]), int(rows[-1]) + 1) if len(rows) else slice(0, 0)
            return VehicleState(*(getattr(self, f)[sel].copy() for f in self.__dataclass_fields__))
        return VehicleState(*(getattr(self, f)[rows] for f in self.__dataclass_fields__))

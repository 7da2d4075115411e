"""``Primitives``: what every sensor sees (vehicles and static props), as one typed value: per row an upright oriented
box and the mesh drawn in it (``meshes``: an id of :mod:`fog_gym.world.meshlib`, 0 for the box itself), scaled to
fill it.

Scene building makes them (:func:`fog_gym.world.scene.vehicle_primitives`, :func:`fog_gym.world.scene.prop_primitives`); the
rasteriser, the night lighting and the ray caster read them. Pure numpy; imports nothing from the project.

Example:
    >>> boxes = Primitives.coerce({"centers": [[10.0, 0, 1]], "halves": [[2.0, 1, 1]], "yaws": [0.0],
    ...                            "tags": [14], "insts": [7]})
    >>> len(boxes), boxes.insts.dtype.name, len(Primitives.concat(boxes, Primitives.empty()))
    (1, 'uint16', 1)
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

#: field → (dtype, trailing shape); every field has one row per box.
LAYOUT: dict[str, tuple[type, tuple[int, ...]]] = {
    "centers": (np.float64, (3,)),  # box centre, world frame [m]
    "halves": (np.float64, (3,)),  # half length, half width, half height [m]
    "yaws": (np.float64, ()),  # heading about +z [rad]
    "colors": (np.float64, (3,)),  # albedo (or emitted colour) in [0, 1]
    "tags": (np.uint8, ()),  # CARLA semantic tag
    "insts": (np.uint16, ()),  # vehicle id; 0 = static world
    "emissive": (np.bool_, ()),  # lamps: drawn at their colour, unlit (a mesh: its lamp materials are)
    "meshes": (np.int32, ()),  # the mesh drawn in the box (fog_gym.world.meshlib; 0: the box itself)
}


@dataclass(frozen=True)
class Primitives:
    """Boxes as structure-of-arrays (see :data:`LAYOUT`); ``len`` is the number of boxes."""

    centers: np.ndarray
    halves: np.ndarray
    yaws: np.ndarray
    colors: np.ndarray
    tags: np.ndarray
    insts: np.ndarray
    emissive: np.ndarray
    meshes: np.ndarray

    def __len__(self) -> int:
        return len(self.yaws)

    @classmethod
    def empty(cls) -> Primitives:
        """No boxes (a scene of ground only)."""
        return cls(**{k: np.zeros((0, *shape), dtype) for k, (dtype, shape) in LAYOUT.items()})

    @classmethod
    def coerce(cls, value: Primitives | Mapping[str, Any]) -> Primitives:
        """``value`` itself, or a mapping with at least ``centers``, ``halves`` and ``yaws`` converted to the layout
        (missing ``colors`` grey, ``tags`` 0, ``insts`` 0, ``emissive`` False); inconsistent rows are a
        ``ValueError``."""
        if isinstance(value, Primitives):
            return value
        if not isinstance(value, Mapping):
            raise TypeError(f"primitives must be Primitives or a mapping of arrays, got {type(value).__name__}")
        unknown = set(value) - set(LAYOUT)
        if unknown or not {"centers", "halves", "yaws"} <= set(value):
            raise ValueError(f"primitives need centers, halves and yaws (optional: colors, tags, insts, emissive, meshes), "
                             f"got {sorted(value)}")  # fmt: skip
        n = len(np.asarray(value["yaws"]).reshape(-1))
        defaults = {"colors": np.full((n, 3), 0.5), "tags": np.zeros(n), "insts": np.zeros(n), "emissive": np.zeros(n),
                    "meshes": np.zeros(n)}
        out = {}
        for k, (dtype, shape) in LAYOUT.items():
            a = np.ascontiguousarray(np.asarray(value.get(k, defaults.get(k)), dtype))
            if a.size == n * int(np.prod(shape)):
                a = a.reshape((n, *shape))
            if a.shape != (n, *shape):
                raise ValueError(f"primitives: {k} must have shape {(n, *shape)} (one row per box), got {a.shape}")
            out[k] = a
        return cls(**out)

    @classmethod
    def concat(cls, *groups: Primitives) -> Primitives:
        """All boxes of ``groups``, in order."""
        return cls(**{k: np.concatenate([getattr(g, k) for g in groups]) for k in LAYOUT})

    def take(self, keep: np.ndarray | slice) -> Primitives:
        """The boxes selected by a boolean mask, an index array or a slice."""
        if isinstance(keep, slice):
            return Primitives(**{k: np.ascontiguousarray(getattr(self, k)[keep]) for k in LAYOUT})
        keep = np.asarray(keep)  # (a mask's rows found once, not once per array: np.take copies them fastest)
        if keep.dtype == np.bool_ and keep.shape != (len(self),):
            raise IndexError(f"a mask of {len(self)} boxes must have shape ({len(self)},), got {keep.shape}")
        rows = np.flatnonzero(keep) if keep.dtype == np.bool_ else keep
        return Primitives(**{k: np.take(getattr(self, k), rows, axis=0) for k in LAYOUT})

    def near(self, center_xy: np.ndarray, radius: float) -> Primitives:
        """Boxes whose centre lies within ``radius`` (plus their own size) of ``center_xy`` in the ground plane."""
        return self.take(self.near_mask(center_xy, radius))

    def near_mask(self, center_xy: np.ndarray, radius: float) -> np.ndarray:
        """Which boxes :meth:`near` keeps."""
        d = np.hypot(self.centers[:, 0] - center_xy[0], self.centers[:, 1] - center_xy[1])
        return d - np.linalg.norm(self.halves, axis=1) <= radius

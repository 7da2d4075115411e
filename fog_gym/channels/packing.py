"""Fixed-shape observation representation of point clouds, and :func:`unpack_points`.

SB3 and vector envs need fixed shapes, while a LiDAR sweep has a variable number of points. Each point channel
is a ``(capacity, C)`` float32 array whose capacity is the number of rays the sensor casts per tick (so no
sweep can overflow it): the sweep's points come first, in the sensor's order (laser-major, as CARLA's
``raw_data``), and the rest of the rows are zero. No real return is an all-zero row (a LiDAR point has a
non-zero range, a radar detection a non-zero depth), so :func:`unpack_points` recovers the exact ``(N, C)``
array — the one the recorder writes.

Example:
    >>> pts = np.array([[1.0, 2.0, 0.5, 0.9]], np.float32)
    >>> obs = {"LIDAR_TOP": pack_points(pts, capacity=3)}
    >>> unpack_points(obs, "LIDAR_TOP").tolist()
    [[1.0, 2.0, 0.5, 0.8999999761581421]]
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numba import njit

from fog_gym.channels.spec import COLUMNS, LIDAR, RADAR, SEMANTIC_LIDAR  # noqa: F401  (COLUMNS re-exported)


def channel_kind(channel: str) -> str | None:
    """``LIDAR_TOP``, ``SEM_LIDAR_TOP`` or ``RADAR_FRONT`` for a FogDrive point channel (fog variants
    ``LIDAR_TOP_FOG_*`` included); None for an added point sensor's channel, whose points are its non-zero rows.
    A camera or box channel (``CAM_*``, ``*_DEPTH``, ``*_SEM``, ``*_BBOX``) raises ``ValueError``."""
    if channel == SEMANTIC_LIDAR or channel.startswith(SEMANTIC_LIDAR + "_"):
        return SEMANTIC_LIDAR
    if channel == LIDAR or channel.startswith(LIDAR + "_"):
        return LIDAR
    if channel == RADAR or channel.startswith(RADAR + "_"):
        return RADAR
    if channel.startswith("CAM_") or channel.endswith(("_DEPTH", "_SEM", "_BBOX")) or channel == "BBOX_3D":
        raise ValueError(f"channel must be a point channel ({LIDAR}[_FOG_*], {SEMANTIC_LIDAR}, {RADAR} or an added "
                         f"point sensor's), got the camera or box channel {channel!r}")  # fmt: skip
    return None


def pack_points(points: np.ndarray, capacity: int) -> np.ndarray:
    """Points ``(N, C)`` → ``(capacity, C)`` float32, zero rows after the N points."""
    points = np.asarray(points, np.float32)
    if points.ndim != 2 or len(points) > capacity:
        raise ValueError(f"expected at most {capacity} points as an (N, C) array, got shape {points.shape}")
    out = np.zeros((capacity, points.shape[1]), np.float32)
    out[: len(points)] = points
    return out


def unpack_points(obs: Mapping[str, np.ndarray] | np.ndarray, channel: str | None = None,
                  columns: int | None = None, copy: bool = True) -> np.ndarray:  # fmt: skip
    """The exact ``(N, 4)`` / ``(N, 6)`` / ``(N, 4)`` float32 points of ``LIDAR_TOP*``, ``SEM_LIDAR_TOP`` or
    ``RADAR_FRONT`` (or ``(N, C)`` of an added point sensor) from an observation dict (or from the channel's array
    itself); ``columns``: only the first ``columns`` columns of each point (the points are found on the whole
    channel), e.g. a dual-return sweep without its ``return`` column. ``copy=False``: when the channel is packed
    (its points its first rows, as fog-gym writes it), the view ``channel[:N, :columns]`` instead of a copy — for
    a reader that only reads; a channel with empty rows between its points still gives a compacted copy.

    >>> unpack_points(np.array([[1, 2, 3, 0.5, 1], [0, 0, 0, 0, 0]], np.float32), "LIDAR_TOP_DUAL", columns=4)
    array([[1. , 2. , 3. , 0.5]], dtype=float32)
    """
    if columns is not None and (isinstance(columns, bool) or not isinstance(columns, (int, np.integer)) or columns < 1):
        raise ValueError(f"columns must be a positive number of leading columns or None, got {columns!r}")
    if not isinstance(copy, (bool, np.bool_)):
        raise ValueError(f"copy must be True or False, got {copy!r}")
    kind = None if channel is None else channel_kind(channel)  # None: an added sensor, any non-zero row is a point
    if isinstance(obs, Mapping):
        if channel is None:
            raise ValueError("unpack_points needs the channel name when given an observation dict")
        if channel not in obs:
            raise KeyError(f"{channel!r} is not in the observation (keys: {sorted(obs)})")
        array = np.asarray(obs[channel])
    else:
        array = np.asarray(obs)
    if array.ndim != 2:
        raise ValueError(
            f"expected one (capacity, C) point array, got shape {array.shape} (index a vector env's batch first)"
        )
    rule = 1 if kind == RADAR else (0 if kind is not None else 2)
    if array.dtype == np.float32 and array.shape[1] >= (4 if rule == 1 else 3 if rule == 0 else 0):
        n, packed = _leading_rows(array, rule)  # one pass that stops reading at the first empty row it can
        if packed and not copy:
            return array[:n, :columns]
        if packed:  # whole rows of a C-contiguous channel are one block (numpy's copy); some columns, a strided copy
            whole = (columns is None or columns >= array.shape[1]) and array.flags.c_contiguous
            return array[:n].copy() if whole else _copy_rows(array if columns is None else array[:, :columns], n)
    if rule == 1:  # a detection has a non-zero depth
        valid = array[:, 3] != 0
    elif rule == 0:  # a LiDAR return has a non-zero position
        valid = (array[:, 0] != 0) | (array[:, 1] != 0) | (array[:, 2] != 0)
    else:
        valid = np.any(array != 0, axis=1)
    n = int(valid.sum())
    if n and not valid[:n].all():  # not packed: keep every non-zero row, in order
        return np.ascontiguousarray(array[valid][:, :columns], np.float32)
    return np.ascontiguousarray(array[:n, :columns], np.float32)


@njit(cache=True, nogil=True)
def _leading_rows(array, rule):
    """The number of leading points of a point channel and whether every later row is empty (packed): one pass over
    the rows (a point's test, :func:`unpack_points`: ``rule`` 0 a non-zero position, 1 a non-zero depth, 2 any
    non-zero value) that stops at the first empty row of a C-contiguous array when every value after it is zero (a
    channel as fog-gym packs it; that check reads the tail as one flat run, which vectorises)."""
    rows, cols = array.shape
    count = 0
    first_empty = rows
    for i in range(rows):
        if rule == 0:
            v = (array[i, 0] != 0) | (array[i, 1] != 0) | (array[i, 2] != 0)
        elif rule == 1:
            v = array[i, 3] != 0
        else:
            v = False
            for j in range(cols):
                v |= array[i, j] != 0
        if not v and first_empty == rows:
            first_empty = i
            if array.flags.c_contiguous:
                tail = array.ravel()[i * cols:]
                nonzero = False
                for k in range(tail.shape[0]):
                    nonzero |= tail[k] != 0
                if not nonzero:
                    return count, True
        count += v
    return count, first_empty >= count


@njit(cache=True, nogil=True)
def _copy_rows(array, n):
    """The first ``n`` rows of ``array`` (any strides: a view of some columns) as a new C-contiguous array."""
    out = np.empty((n, array.shape[1]), np.float32)
    for i in range(n):
        for j in range(array.shape[1]):
            out[i, j] = array[i, j]
    return out


def pad_rows(rows: np.ndarray, capacity: int, fill: float = 0) -> np.ndarray:
    """``rows`` (N, …) in a ``(capacity, …)`` array, the rest ``fill`` (zeros: equal to themselves, unlike NaN, so
    Gymnasium's determinism checks hold): the fixed-shape form of a variable-length ``info`` entry, so that
    Gymnasium's vectorisers can stack it (the count goes beside it).

    >>> pad_rows(np.array([[1.0, 2.0]]), 3).tolist()
    [[1.0, 2.0], [0.0, 0.0], [0.0, 0.0]]
    >>> pad_rows(np.array([7, 8]), 3, fill=-1).tolist()
    [7, 8, -1]
    """
    rows = np.asarray(rows)
    if len(rows) > capacity:
        raise ValueError(f"{len(rows)} rows do not fit a capacity of {capacity}")
    out = np.full((capacity, *rows.shape[1:]), fill, dtype=rows.dtype)
    out[: len(rows)] = rows
    return out

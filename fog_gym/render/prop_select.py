"""A frame's props in two numba calls: which rows of the near props' table every sensor sees and which of them the
cameras see (:func:`select_rows`), then those rows followed by the vehicles as new primitives (:func:`take_concat`) —
what :meth:`fog_gym.sensors.camera.CameraRig.scene_primitives` did with a dozen numpy passes and two ``take`` and
``concat`` over the eight fields of :class:`~fog_gym.world.primitives.Primitives` per set (105 → 42–53 µs a frame on
``FogDriveRL-v0``'s town, the same rows in the same order).

The rule, per box ``b`` of the table's first ``n_boxes`` rows (the boxes; after them, the parts of the boxes near the
ego, each with its box's row in ``owner``): its distance to the ego less its half diagonal, ``d_b``; kept when
``d_b ≤ render_radius``, as its box when ``d_b > detail_radius`` or the table has no parts, else as its parts. The
boxes drawn as boxes come first, in table order, then the parts, in table order. The cameras' rows are those whose
bounding circle (half diagonal + 0.5 m) some camera's view meets (:func:`fog_gym.render.view_cull.in_views`).

Example:
    >>> from fog_gym.world.primitives import Primitives
    >>> table = Primitives.coerce({"centers": [[10.0, 0, 1], [-250.0, 0, 1], [900.0, 0, 1]], "halves": [[1.0, 1, 1]] * 3,
    ...                            "yaws": [0.0] * 3})
    >>> views = np.array([[1.5, 0.0, 0.0, np.radians(35.0)]])
    >>> rows, seen = select_rows(table.centers, np.linalg.norm(table.halves, axis=1), 3, None, (0.0, 0.0, 0.0),
    ...                          600.0, 215.0, views)
    >>> rows.tolist(), seen.tolist()  # the far box is beyond the render radius, the one behind out of view
    ([0, 1], [0])
    >>> len(take_concat(table, seen, Primitives.empty()))
    1
"""

from __future__ import annotations

import numpy as np
from numba import njit

from fog_gym._numba import defer  # (numba's fork-safe threading layer, before any kernel runs)
from fog_gym.render.view_cull import _sees, view_table
from fog_gym.world.primitives import LAYOUT, Primitives

_NO_OWNER = np.zeros(0, np.int64)
#: :func:`_gather`'s fields, in :data:`~fog_gym.world.primitives.LAYOUT`'s order: their trailing axes.
_TRAILING = ((3,), (3,), (), (3,), (), (), (), ())
if tuple(shape for _, shape in LAYOUT.values()) != _TRAILING:  # pragma: no cover  (a new field: extend _gather)
    raise ImportError("fog_gym.render.prop_select._gather does not match Primitives' LAYOUT")


def select_rows(centers: np.ndarray, diagonals: np.ndarray, n_boxes: int, owner: np.ndarray | None,
                ego_pose: tuple[float, float, float], render_radius: float, detail_radius: float,
                views: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """(rows every sensor sees, rows the cameras see) of a near props' table (module docstring): ``centers`` and
    ``diagonals`` of all its rows, its first ``n_boxes`` rows the boxes, ``owner`` each later row's box (None: no
    parts); ``views`` the cameras' ``(K, 4)`` views (:mod:`fog_gym.render.view_cull`), or None when they see every
    row kept (a camera with pitch or roll). The cameras' rows are a subsequence of the first."""
    n_boxes = int(n_boxes)
    if centers.ndim != 2 or centers.shape[1] < 2 or diagonals.shape != (len(centers),) or not 0 <= n_boxes <= len(centers):
        raise ValueError(f"select_rows needs centres (N, 2+), diagonals (N,) and 0 <= n_boxes <= N, got "
                         f"{centers.shape}, {diagonals.shape}, {n_boxes}")  # fmt: skip
    own = _NO_OWNER if owner is None else np.ascontiguousarray(owner, np.int64)
    if own.shape != (len(centers) - n_boxes if owner is not None else 0,):
        raise _owner_error(len(centers) - n_boxes, n_boxes, own.shape)
    cams = view_table(ego_pose, views if views is not None else np.zeros((0, 4)))
    rows = np.empty(len(centers), np.int64)
    seen = np.empty(len(centers), np.int64)
    n, m = defer(_select)(np.ascontiguousarray(centers, np.float64), np.ascontiguousarray(diagonals, np.float64),
                          n_boxes, own, owner is not None, float(ego_pose[0]), float(ego_pose[1]),
                          float(render_radius), float(detail_radius), cams, views is not None, rows, seen)  # fmt: skip
    if n < 0:  # an owner outside the boxes (checked in the kernel, before it selects)
        raise _owner_error(len(centers) - n_boxes, n_boxes, own.shape)
    return rows[:n], (seen[:m] if views is not None else rows[:n])


def _owner_error(n_parts: int, n_boxes: int, shape: tuple) -> ValueError:
    return ValueError(f"owner must give each of the {n_parts} parts its box (0 .. {n_boxes - 1}), got shape {shape}")


@njit(cache=True, nogil=True)
def _select(centers, diagonals, n_boxes, owner, parts, ex, ey, render_radius, detail_radius, cams, cull, rows, seen):
    for p in range(owner.shape[0]):  # every part's box among the boxes, else (-1, -1) and nothing selected
        if owner[p] < 0 or owner[p] >= n_boxes:
            return -1, -1
    # the boxes drawn as boxes, then the parts of the boxes drawn as parts (a box's parts: d ≤ detail_radius)
    state = np.zeros(n_boxes, np.uint8)  # 0 out, 1 as its box, 2 as its parts
    n = 0
    for b in range(n_boxes):
        d = np.hypot(centers[b, 0] - ex, centers[b, 1] - ey) - diagonals[b]
        if d <= render_radius:
            state[b] = 2 if parts and d <= detail_radius else 1
            if state[b] == 1:
                rows[n] = b
                n += 1
    if parts:
        for p in range(owner.shape[0]):
            if state[owner[p]] == 2:
                rows[n] = n_boxes + p
                n += 1
    m = 0
    for i in range(n if cull else 0):
        r = rows[i]
        if _sees(centers[r, 0], centers[r, 1], diagonals[r] + 0.5, cams):
            seen[m] = r
            m += 1
    return n, m


def take_concat(table: Primitives, rows: np.ndarray, tail: Primitives) -> Primitives:
    """The boxes of ``table`` at ``rows`` followed by every box of ``tail``
    (``Primitives.concat(table.take(rows), tail)``, in one pass)."""
    rows = np.ascontiguousarray(rows, np.int64)
    n = len(rows) + len(tail)
    out = tuple(np.empty((n, *shape), dtype) for dtype, shape in LAYOUT.values())
    if not defer(_gather)(rows, tuple(getattr(table, k) for k in LAYOUT), tuple(getattr(tail, k) for k in LAYOUT), out):
        raise IndexError(f"rows must index the table's {len(table)} boxes, got {rows.min()}..{rows.max()}")
    return Primitives(*out)


@njit(cache=True, nogil=True)
def _gather(rows, src, tail, out):
    # False, having written nothing, when a row lies outside src (the check here: numpy's min and max of the rows
    # release the GIL); else each field (LAYOUT's order: three (N, 3) float64, then five (N,) of their own types) of
    # src at rows, then tail's
    for i in range(rows.shape[0]):
        if rows[i] < 0 or rows[i] >= src[0].shape[0]:
            return False
    _gather2(rows, src[0], tail[0], out[0])
    _gather2(rows, src[1], tail[1], out[1])
    _gather1(rows, src[2], tail[2], out[2])
    _gather2(rows, src[3], tail[3], out[3])
    _gather1(rows, src[4], tail[4], out[4])
    _gather1(rows, src[5], tail[5], out[5])
    _gather1(rows, src[6], tail[6], out[6])
    _gather1(rows, src[7], tail[7], out[7])
    return True


@njit(cache=True, inline="always")
def _gather1(rows, a, tail, out):
    n = rows.shape[0]
    for i in range(n):
        out[i] = a[rows[i]]
    for i in range(tail.shape[0]):
        out[n + i] = tail[i]


@njit(cache=True, inline="always")
def _gather2(rows, a, tail, out):
    # (N, 3) fields: the three columns written in turn
    n = rows.shape[0]
    for i in range(n):
        r = rows[i]
        out[i, 0], out[i, 1], out[i, 2] = a[r, 0], a[r, 1], a[r, 2]
    for i in range(tail.shape[0]):
        out[n + i, 0], out[n + i, 1], out[n + i, 2] = tail[i, 0], tail[i, 1], tail[i, 2]

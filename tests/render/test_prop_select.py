"""A frame's props selected in two numba calls are the rows, in the order, that the numpy rule gave."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fog_gym.render.prop_select import select_rows, take_concat
from fog_gym.render.view_cull import in_views
from fog_gym.world.primitives import LAYOUT, Primitives


def random_table(rng, n_boxes: int, n_parts: int) -> tuple[Primitives, np.ndarray]:
    n = n_boxes + n_parts
    table = Primitives.coerce({
        "centers": np.c_[rng.uniform(-800, 800, (n, 2)), rng.uniform(0, 10, n)], "halves": rng.uniform(0.1, 20, (n, 3)),
        "yaws": rng.uniform(-np.pi, np.pi, n), "colors": rng.uniform(0, 1, (n, 3)), "tags": rng.integers(0, 30, n),
        "insts": rng.integers(0, 9, n), "emissive": rng.random(n) < 0.1, "meshes": rng.integers(0, 40, n),
    })  # fmt: skip
    return table, rng.integers(0, max(n_boxes, 1), n_parts)


def numpy_rule(table, n_boxes, owner, pose, render_radius, detail_radius, views):
    """The selection as numpy passes (the rule CameraRig.scene_primitives applied before the kernels)."""
    diag = np.linalg.norm(table.halves, axis=1)
    boxes = table.centers[:n_boxes]
    d = np.hypot(boxes[:, 0] - pose[0], boxes[:, 1] - pose[1]) - diag[:n_boxes]
    within = d <= render_radius
    if owner is None:
        rows = np.flatnonzero(within)
    else:
        close = within & (d <= detail_radius)
        rows = np.concatenate((np.flatnonzero(within & ~close), n_boxes + np.flatnonzero(close[owner])))
    if views is None or len(rows) == 0:
        return rows, rows
    return rows, rows[in_views(table.centers[rows], diag[rows] + 0.5, pose, views)]


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n_boxes=st.integers(0, 300), parts=st.booleans(), cull=st.booleans(),
       n_views=st.integers(1, 4))  # fmt: skip
def test_the_kernels_select_the_numpy_rules_rows_in_its_order(seed, n_boxes, parts, cull, n_views):
    rng = np.random.default_rng(seed)
    table, owner = random_table(rng, n_boxes, int(rng.integers(0, 400)) if parts and n_boxes else 0)
    owner = owner if parts and n_boxes else None
    views = np.c_[rng.uniform(-3, 3, (n_views, 2)), rng.uniform(-np.pi, np.pi, n_views), rng.uniform(0.1, 1.6, n_views)]
    pose = (float(rng.uniform(-300, 300)), float(rng.uniform(-300, 300)), float(rng.uniform(-4, 4)))
    radii = sorted(rng.uniform(0, 900, 2))
    args = (n_boxes, owner, pose, radii[1], radii[0], views if cull else None)
    rows, seen = select_rows(table.centers, np.linalg.norm(table.halves, axis=1), *args)
    want_rows, want_seen = numpy_rule(table, *args)
    assert rows.tolist() == want_rows.tolist() and seen.tolist() == want_seen.tolist()
    vehicles = random_table(rng, int(rng.integers(0, 20)), 0)[0]
    got = take_concat(table, seen, vehicles)
    want = Primitives.concat(table.take(seen), vehicles)
    for k, (dtype, _) in LAYOUT.items():
        a, b = getattr(got, k), getattr(want, k)
        assert a.dtype == dtype and a.shape == b.shape and np.array_equal(a, b)


def test_far_boxes_are_left_out_near_ones_drawn_as_their_parts_and_the_cameras_see_what_is_ahead():
    table = Primitives.coerce({"centers": [[10.0, 0, 1], [-250.0, 0, 1], [900.0, 0, 1], [300.0, 5, 1],
                                           [10.5, 0, 1], [10.2, 0.3, 1]],
                               "halves": [[1.0, 1, 1]] * 6, "yaws": [0.0] * 6})  # fmt: skip
    owner = np.array([0, 0])  # two parts of the near box ahead
    views = np.array([[1.5, 0.0, 0.0, np.radians(35.0)]])
    rows, seen = select_rows(table.centers, np.linalg.norm(table.halves, axis=1), 4, owner, (0.0, 0.0, 0.0), 600.0,
                             215.0, views)  # fmt: skip
    # beyond the detail radius as boxes (the one 300 m ahead, the one 250 m behind), the near one as its two parts,
    # beyond 600 m none; the cameras: not the one behind
    assert rows.tolist() == [1, 3, 4, 5] and seen.tolist() == [3, 4, 5]


def test_bad_tables_and_rows_are_one_line_errors():
    table, _ = random_table(np.random.default_rng(0), 5, 0)
    diag = np.linalg.norm(table.halves, axis=1)
    for call, match in ((lambda: select_rows(table.centers, diag[:3], 5, None, (0.0, 0.0, 0.0), 1.0, 1.0, None), "diagonals"),
                        (lambda: select_rows(table.centers, diag, 6, None, (0.0, 0.0, 0.0), 1.0, 1.0, None), "n_boxes"),
                        (lambda: select_rows(table.centers, diag, 3, np.zeros(5), (0.0, 0.0, 0.0), 1.0, 1.0, None), "owner"),
                        (lambda: select_rows(table.centers, diag, 3, np.array([0, 3]), (0.0, 0.0, 0.0), 1.0, 1.0, None), "owner"),
                        (lambda: take_concat(table, np.array([0, 5]), Primitives.empty()), "rows")):  # fmt: skip
        with pytest.raises((ValueError, IndexError), match=match) as err:
            call()
        assert "\n" not in str(err.value)

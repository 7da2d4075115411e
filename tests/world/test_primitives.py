"""``Primitives``: one typed value for the boxes every sensor sees; coercion checks rows before any kernel runs."""

from __future__ import annotations

import numpy as np
import pytest

from fog_gym.world.primitives import LAYOUT, Primitives


def _boxes(n: int, seed: int = 0) -> Primitives:
    rng = np.random.default_rng(seed)
    return Primitives.coerce({"centers": rng.uniform(-50, 50, (n, 3)), "halves": rng.uniform(0.5, 3, (n, 3)),
                              "yaws": rng.uniform(-3, 3, n), "tags": np.full(n, 14), "insts": np.arange(n) + 1})  # fmt: skip


def test_empty_has_every_field_with_its_dtype_and_no_rows():
    e = Primitives.empty()
    assert len(e) == 0
    for k, (dtype, shape) in LAYOUT.items():
        assert getattr(e, k).dtype == np.dtype(dtype) and getattr(e, k).shape == (0, *shape)


def test_coerce_fills_optional_fields_and_keeps_a_primitives_value_as_is():
    b = _boxes(3)
    assert Primitives.coerce(b) is b
    assert b.colors.tolist() == [[0.5] * 3] * 3 and not b.emissive.any() and b.insts.dtype == np.uint16
    assert b.centers.flags["C_CONTIGUOUS"] and b.centers.dtype == np.float64


def test_concat_take_and_near_keep_rows_together():
    a, b = _boxes(4, 1), _boxes(2, 2)
    both = Primitives.concat(a, b)
    assert len(both) == 6 and both.insts.tolist() == [1, 2, 3, 4, 1, 2]
    np.testing.assert_array_equal(both.take(np.array([4, 0])).centers, np.stack([b.centers[0], a.centers[0]]))
    near = both.near(np.zeros(2), 20.0)
    d = np.hypot(*both.centers[:, :2].T) - np.linalg.norm(both.halves, axis=1)
    assert len(near) == int((d <= 20.0).sum()) and set(near.yaws.tolist()) <= set(both.yaws.tolist())


def test_take_by_mask_index_or_slice_equals_numpy_indexing_and_refuses_a_mask_of_another_length():
    b = _boxes(7, 3)
    mask = np.array([True, False, True, True, False, False, True])
    for keep in (mask, np.flatnonzero(mask), np.array([6, 0, 6]), slice(1, 5), np.zeros(7, bool)):
        got = b.take(keep)
        for k in LAYOUT:
            want = getattr(b, k)[keep]
            assert getattr(got, k).dtype == want.dtype and getattr(got, k).flags["C_CONTIGUOUS"]
            np.testing.assert_array_equal(getattr(got, k), want)
    with pytest.raises(IndexError, match="mask of 7 boxes"):
        b.take(mask[:5])


@pytest.mark.parametrize(
    "value, message",
    [({"centers": [[0, 0, 0]], "halves": [[1, 1, 1]]}, "need centers, halves and yaws"),
     ({"centers": [[0, 0, 0]], "halves": [[1, 1, 1]], "yaws": [0.0], "radius": [1.0]}, "need centers"),
     ({"centers": [[0, 0, 0]], "halves": [[1, 1, 1]], "yaws": [0.0, 1.0]}, "centers must have shape"),
     ({"centers": [[0, 0]], "halves": [[1, 1, 1]], "yaws": [0.0]}, "centers must have shape")],
)  # fmt: skip
def test_inconsistent_rows_are_refused_naming_the_field(value, message):
    with pytest.raises(ValueError, match=message):
        Primitives.coerce(value)
    with pytest.raises(TypeError, match="Primitives or a mapping"):
        Primitives.coerce([1, 2, 3])

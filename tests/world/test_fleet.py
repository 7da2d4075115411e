"""``VehicleState.take``: the rows of a mask, as numpy's mask indexing gives them (row slices where contiguous)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fog_gym.world.fleet import VehicleState


def _state(n: int, rng: np.random.Generator) -> VehicleState:
    return VehicleState(rng.permutation(n).astype(np.int32) + 1, rng.integers(0, 5, n).astype(np.int8),
                        rng.normal(size=(n, 3)), rng.uniform(1, 5, (n, 3)), rng.uniform(-3, 3, n),
                        rng.normal(size=(n, 3)), rng.uniform(0, 1, (n, 3)))  # fmt: skip


@settings(max_examples=60, deadline=None)
@given(n=st.integers(0, 12), seed=st.integers(0, 2**32 - 1), kind=st.sampled_from(["random", "run", "one", "none"]))
def test_take_gives_the_rows_of_mask_indexing_as_copies(n, seed, kind):
    rng = np.random.default_rng(seed)
    state = _state(n, rng)
    if kind == "random":
        mask = rng.random(n) < 0.5
    elif kind == "run":  # contiguous rows: sliced
        lo = int(rng.integers(0, n + 1))
        mask = (np.arange(n) >= lo) & (np.arange(n) < int(rng.integers(lo, n + 1)))
    elif kind == "one":
        mask = np.arange(n) == (int(rng.integers(0, n)) if n else 0)
    else:
        mask = np.zeros(n, bool)
    got = state.take(mask)
    for f in dataclasses.fields(state):
        a, b = getattr(got, f.name), getattr(state, f.name)[mask]
        assert a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b) and a.flags.c_contiguous
        assert not np.shares_memory(a, getattr(state, f.name))


def test_take_refuses_anything_but_a_mask_of_every_vehicle():
    state = _state(3, np.random.default_rng(0))
    for bad in (np.array([0, 2]), np.ones(2, bool), np.ones((3, 1), bool), [1, 0, 1]):
        with pytest.raises(ValueError, match="mask must be a boolean array of shape \\(3,\\)"):
            state.take(bad)

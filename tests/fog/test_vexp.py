"""The vectorisable exponential of the fog kernels: within one unit in the last place of the C library's, its edges,
and that a loop of it vectorises."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numba import njit

from fog_gym.fog.vexp import OVERFLOW, UNDERFLOW, round_int, vexp


@njit(cache=False, error_model="numpy")
def _vexps(x, out):
    for i in range(x.shape[0]):
        out[i] = vexp(x[i])


@njit(cache=False, error_model="numpy")
def _round_ints(x, out):
    for i in range(x.shape[0]):
        out[i] = round_int(x[i])


def _ulps(x: np.ndarray) -> np.ndarray:
    got = np.empty_like(x)
    _vexps(x, got)
    want = np.exp(x)
    return np.abs(got - want) / np.spacing(want)


@pytest.mark.parametrize("lo, hi", [(-1.0, 1.0), (-0.35, 0.35), (-40.0, 0.0), (UNDERFLOW, OVERFLOW)])
def test_vexp_is_within_one_unit_in_the_last_place_of_the_c_librarys_exp(lo, hi):
    x = np.random.default_rng(0).uniform(lo, hi, 1_000_000)
    ulps = _ulps(x)
    assert ulps.max() <= 1.0
    assert (ulps == 0).mean() > 0.9  # and equal to it on most arguments


@settings(max_examples=200, deadline=None)
@given(x=st.floats(UNDERFLOW, OVERFLOW))
def test_vexp_matches_exp_anywhere_in_its_range(x):
    assert _ulps(np.array([x]))[0] <= 1.0


def test_vexp_flushes_below_its_range_to_zero_overflows_to_inf_and_keeps_nan():
    x = np.array([-math.inf, -800.0, UNDERFLOW - 1e-9, 0.0, -0.0, 709.78, 709.79, 800.0, math.inf, math.nan])
    got = np.empty_like(x)
    _vexps(x, got)
    assert got[:3].tolist() == [0.0, 0.0, 0.0] and got[3] == got[4] == 1.0
    assert got[5] == pytest.approx(math.exp(709.78), rel=1e-15) and np.isinf(got[6:9]).all() and np.isnan(got[9])


def test_round_int_rounds_half_to_even_as_rint():
    x = np.r_[np.arange(-6, 6) + 0.5, np.random.default_rng(1).uniform(-1e6, 1e6, 10_000), 0.0, 2000.0]
    got = np.empty(len(x), np.int64)
    _round_ints(x, got)
    assert np.array_equal(got, np.rint(x).astype(np.int64))


def test_a_loop_of_vexp_vectorises():
    _vexps(np.zeros(8), np.empty(8))
    asm = next(iter(_vexps.inspect_asm().values()))
    assert "ymm" in asm or "zmm" in asm  # packed registers: the loop runs on vectors, without calls to exp
    assert "exp" not in "".join(line for line in asm.splitlines() if "call" in line)

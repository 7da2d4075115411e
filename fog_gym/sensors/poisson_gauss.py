"""The exact law of a pixel's output under photon shot noise and Gaussian read noise: ``F[v, d] = P(N_v + R < t_d)``
for a Poisson count ``N_v`` and read noise ``R ~ N(0, σ²)`` at the thresholds ``t_d`` where the output steps from
level ``d`` to ``d + 1``, summed exactly (:func:`_cdf_tables`), and its quantile tables (:func:`_quantile_rows`).

Pure numba kernels over arrays, used by :mod:`fog_gym.sensors.camera_noise` (which holds the sensor model, the
thresholds and the draws): every camera of a frame in one launch, each kernel with a serial twin (the same bits).

Example:
    >>> lam = np.array([[0.0, 4.0, 100.0]]); t = np.array([[0.5, 4.5, 100.5]])
    >>> F = _cdf_tables_serial(lam, t, np.array([0.0]))
    >>> [round(float(x), 4) for x in F[0, 1]]  # P(Poisson(4) < 0.5), P(< 4.5), P(< 100.5)
    [0.0183, 0.6288, 1.0]
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

import fog_gym._numba  # noqa: F401  (numba's fork-safe threading layer, before any kernel runs)
from fog_gym._numba import serial_twin


@njit(cache=True, nogil=True, inline="always")
def _phi_row(t, sigma, r, row):
    """``row[j] = Φ((t − k)/σ)`` for the counts ``k = floor(t) − r + j``, ``j = 0..2r`` (the read noise's CDF
    around threshold ``t``; zeros for a threshold beyond the well or no read noise)."""
    if t >= 0.0 and sigma > 0.0:
        base = math.floor(t) - r
        for j in range(2 * r + 1):
            row[j] = 0.5 * math.erfc(-(t - (base + j)) / (sigma * math.sqrt(2.0)))


@njit(cache=True, nogil=True, inline="always")
def _level_cdf(L, thresholds, sigma, r, phi, inv, out, scratch):
    """``out[d] = P(N + R < t_d)``, ``N ~ Poisson(L)``, ``R ~ N(0, σ²)``, for one level (:func:`_cdf_tables`);
    ``inv[k] = 1/k`` (the recurrences multiply: a chain of multiplications, not of divisions); ``scratch`` holds at
    least ``2·(16√L + 23)`` values (the Poisson window's masses and their running sum)."""
    n_t = thresholds.shape[0]
    half = 8.0 * math.sqrt(L) + 10.0
    k0 = max(0, int(L - half))
    k1 = int(L + half) + 1
    n = k1 - k0 + 1
    p = scratch[:n]
    cum = scratch[n:2 * n]
    mode = int(L)
    if L > 0.0:
        inv_l = 1.0 / L
        p[mode - k0] = math.exp(mode * math.log(L) - L - math.lgamma(mode + 1.0))
        up, down = k1 - mode, mode - k0  # both recurrences in one loop: two chains of multiplications in flight
        for i in range(1, max(up, down) + 1):
            if i <= up:
                k = mode + i
                p[k - k0] = p[k - 1 - k0] * (L * inv[k])
            if i <= down:
                k = mode - i
                p[k - k0] = p[k + 1 - k0] * ((k + 1) * inv_l)
    else:
        p[:] = 0.0
        p[0] = 1.0
    total = p.sum()
    scale = 1.0 / total
    acc = 0.0
    for i in range(n):  # cum[i] = P(N <= k0 + i)
        p[i] *= scale
        acc += p[i]
        cum[i] = acc
    for d in range(n_t):
        t = thresholds[d]
        if t < 0.0:
            out[d] = 1.0
            continue
        if sigma == 0.0:
            m = int(math.ceil(t)) - 1 - k0  # P(N < t) = P(N <= ceil(t) − 1)
            out[d] = 0.0 if m < 0 else (1.0 if m >= n else min(cum[m], 1.0))
            continue
        base = int(math.floor(t)) - r  # counts below base add their whole mass, above base + 2r none
        if base > k1:
            out[d] = 1.0
            continue
        if base + 2 * r < k0:
            out[d] = 0.0
            continue
        out[d] = _window_sum(p, cum, phi, k0, k1, r, d, base)


@njit(cache=True, nogil=True, inline="always")
def _window_sum(p, cum, phi, k0, k1, r, d, base):
    """``P(N < base) + Σ_j P(N = base + j)·phi[d, j]`` (at most 1) over the counts in the Poisson window, in eight
    partial sums (eight chains of additions in flight, over unit-stride slices the compiler vectorises)."""
    lo = max(k0 - base, 0)
    hi = min(k1 - base, 2 * r) + 1
    f0, f1, f2, f3, f4, f5, f6, f7 = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    n = max(hi - lo, 0)
    pp, ph = p[base - k0 + lo:], phi[d, lo:]  # from 0 over slices: unit strides the compiler sees
    i = 0
    while i + 7 < n:
        f0 += pp[i] * ph[i]
        f1 += pp[i + 1] * ph[i + 1]
        f2 += pp[i + 2] * ph[i + 2]
        f3 += pp[i + 3] * ph[i + 3]
        f4 += pp[i + 4] * ph[i + 4]
        f5 += pp[i + 5] * ph[i + 5]
        f6 += pp[i + 6] * ph[i + 6]
        f7 += pp[i + 7] * ph[i + 7]
        i += 8
    while i < n:
        f0 += pp[i] * ph[i]
        i += 1
    below = cum[base - 1 - k0] if base - 1 - k0 >= 0 else 0.0
    return min(below + (((f0 + f4) + (f1 + f5)) + ((f2 + f6) + (f3 + f7))), 1.0)


_CDF_CHUNKS = 8  # each law's levels split over this many tasks


@njit(cache=True, nogil=True, parallel=True)
def _cdf_tables(lam, thresholds, sigma):
    """``F[i, v, d] = P(N_v + R < t_d)`` of law ``i``: ``N_v ~ Poisson(lam[i, v])``, ``R ~ N(0, sigma[i]²)``, exactly:
    the Poisson mass over ``λ ± (8√λ + 10)`` by recurrence from its mode, the read noise's Φ over ``t ± 7σ``
    (tabulated once per threshold; below that window each count adds its whole mass). A negative threshold stands
    for one beyond the full well (never reached: F = 1); rounding never takes F above 1. Every law's levels in one
    launch."""
    n_law, n_lv, n_t = lam.shape[0], lam.shape[1], thresholds.shape[1]
    out = np.empty((n_law, n_lv, n_t))
    rs = np.empty(n_law, np.int64)
    for i in range(n_law):
        rs[i] = int(math.ceil(7.0 * sigma[i])) + 1  # counts farther than 7σ from a threshold are wholly below or above
    width = 2 * rs.max() + 1 if n_law else 1
    # phi[i, d, j] = Φ((t_d − k)/σ) for the count k = floor(t_d) − r + j: the same for every level of a law
    phi = np.zeros((n_law, n_t, width))
    for task in prange(n_law * n_t):
        i, d = task // n_t, task % n_t
        _phi_row(thresholds[i, d], sigma[i], rs[i], phi[i, d])
    # a level's Poisson window is longer the brighter it is: each chunk takes every _CDF_CHUNKS-th level (dark and
    # bright alike) and allocates its scratch once (allocating in the loop serialises the threads on the allocator)
    longest = 2 * (int(16.0 * math.sqrt(max(lam.max(), 0.0))) + 24) if n_law else 0
    top = int(max(lam.max(), 0.0) + 8.0 * math.sqrt(max(lam.max(), 0.0)) + 10.0) + 2 if n_law else 1
    inv = np.empty(top + 1)  # 1/k for every count of every window
    inv[0] = 0.0
    for k in range(1, top + 1):
        inv[k] = 1.0 / k
    for task in prange(n_law * _CDF_CHUNKS):
        i, c = task // _CDF_CHUNKS, task % _CDF_CHUNKS
        scratch = np.empty(longest)
        for v in range(c, n_lv, _CDF_CHUNKS):
            _level_cdf(lam[i, v], thresholds[i], sigma[i], rs[i], phi[i], inv, out[i, v], scratch)
    return out


_cdf_tables_serial = serial_twin(_cdf_tables)


@njit(cache=True, nogil=True, parallel=True)
def _quantile_rows(cdf, size):
    """``(rows, size)`` uint8: per row of ``cdf`` (``P(output <= d)``, ``d = 0..254``) the output level at each
    quantile ``(m + ½)/size`` (:func:`_quantiles`)."""
    rows, n_t = cdf.shape
    out = np.empty((rows, size), np.uint8)
    chunks = min(rows, 16)
    for c in prange(chunks):  # a histogram per chunk of rows, allocated once
        counts = np.empty(size + 1, np.int64)
        for row in range(c * rows // chunks, (c + 1) * rows // chunks):
            counts[:] = 0
            for d in range(n_t):
                q = math.ceil(cdf[row, d] * size - 0.5)
                counts[0 if q < 0 else (size if q > size else q)] += 1
            acc = 0
            for m in range(size):
                acc += counts[m]
                out[row, m] = acc
    return out


_quantile_rows_serial = serial_twin(_quantile_rows)

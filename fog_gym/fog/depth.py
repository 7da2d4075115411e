"""Optical depth of a packed fog field in closed form, one implementation for the kernels and for numpy
(``docs/fog.md``, "Fog with a shape"; the fields are in :mod:`fog_gym.fog.fields`).

A packed field is a float64 table of rows ``[kind, p0, …, p6]`` (``FogField.pack``): kind 0 homogeneous ``[β]``, kind 1
height ``[β0, H]``, kind 2 bank ``[Δβ, a, b, c, d, p, β_bg]`` (the trapezoid ``w`` rises from 0 at ``a`` to ``p`` at ``b``,
stays until ``c`` and falls to 0 at ``d``). A segment starts at ``(u0, z0)`` in the field frame with unit-direction
components ``du`` (along u) and ``dz`` (up).

Example:
    >>> bank = np.array([[2.0, 0.06, 100.0, 100.0, 140.0, 140.0, 1.0, 0.0]])  # 40 m of β = 0.06 from u = 100 m
    >>> round(float(segment_depth(bank, 0.0, 1.0, 1.0, 0.0, 200.0)), 6)
    2.4
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

import fog_gym._numba  # noqa: F401  (numba's fork-safe threading layer, before any kernel runs)

#: Kinds of the packed rows ``[kind, p0, …, p6]``.
HOMOGENEOUS, HEIGHT, BANK = 0.0, 1.0, 2.0

@njit(cache=True, inline="always")
def _g(x):
    """``(1 − e^{−x}) / x`` (1 at 0), stable for small ``x``."""
    if abs(x) < 1e-8:
        return 1.0 - 0.5 * x
    return -math.expm1(-x) / x


@njit(cache=True, inline="always")
def _ramp_integral(u, a, b, c, d, p):
    """``W(u) = ∫_{−∞}^{u} w``: the trapezoid ``w`` of knots ``a ≤ b ≤ c ≤ d`` and plateau ``p``."""
    x = min(max(u, a), b) - a
    rise = x * x / (2.0 * (b - a)) if b > a else 0.0
    flat = min(max(u, b), c) - b
    y = min(max(u, c), d) - c
    fall = y - y * y / (2.0 * (d - c)) if d > c else 0.0
    return p * (rise + flat + fall)


@njit(cache=True, inline="always")
def _ramp(u, a, b, c, d, p):
    """``w(u)`` of the trapezoid (a step at ``a = b`` and ``c = d``)."""
    if u < a or u > d:
        return 0.0
    if u < b:
        return p * (u - a) / (b - a)
    if u <= c:
        return p
    return p * (d - u) / (d - c)


@njit(cache=True, inline="always")
def _height_term(b0, h, z0, dz, length):
    """τ of one height term ``β0·exp(−max(z, 0)/H)`` along a segment from height ``z0`` rising ``dz`` per metre."""
    z1 = z0 + dz * length
    lo, hi = min(z0, z1), max(z0, z1)
    if hi <= 0.0:
        return b0 * length
    if lo >= 0.0:
        return b0 * math.exp(-lo / h) * length * _g((hi - lo) / h)
    below = length * (-lo) / (hi - lo)  # the part below the road sees β(0)
    return b0 * (below + (length - below) * _g(hi / h))


@njit(cache=True, nogil=True)
def segment_depth(terms, u0, z0, du, dz, length):
    """Optical depth ``τ`` of the packed field ``terms`` along the segment from ``(u0, z0)`` with unit direction
    components ``du`` (along ``u``) and ``dz`` (up), ``length`` metres long, in closed form."""
    tau = 0.0
    for k in range(terms.shape[0]):
        kind = terms[k, 0]
        if kind == 0.0:  # homogeneous
            tau += terms[k, 1] * length
        elif kind == 1.0:  # height: β0·exp(−max(z, 0)/H)
            tau += _height_term(terms[k, 1], terms[k, 2], z0, dz, length)
        else:  # bank: β_bg + Δβ·w(u)
            db, a, b, c, d, p, bg = terms[k, 1], terms[k, 2], terms[k, 3], terms[k, 4], terms[k, 5], terms[k, 6], terms[k, 7]
            span = du * length
            if abs(span) < 1e-6:
                mean_w = _ramp(u0 + 0.5 * span, a, b, c, d, p)
            else:
                mean_w = (_ramp_integral(u0 + span, a, b, c, d, p) - _ramp_integral(u0, a, b, c, d, p)) / span
            tau += (bg + db * mean_w) * length
    return tau


def origin_constants(terms: np.ndarray, u0: float, z0: float) -> np.ndarray:
    """What :func:`origin_depth` needs of a packed field that depends only on the segments' common start ``(u0, z0)``
    (a sensor's place in the field frame): ``(K, 4)`` float64, a row per term ``[c0, c1, c2, fast]``. A height term
    seen from ``z0 > 0``: ``e^{−z0/H}``, ``g(z0/H) = (1 − e^{−z0/H}) / (z0/H)``, ``1/H``, 1 (else zeros: the general
    form); a bank: ``W(u0)``, the trapezoid's integral up to the start, 0, 0, 1; a homogeneous term: zeros.

    >>> origin_constants(np.array([[1.0, 0.05, 4.0, 0, 0, 0, 0, 0]]), 0.0, 2.0).round(4).tolist()
    [[0.6065, 0.7869, 0.25, 1.0]]
    """
    terms = np.ascontiguousarray(terms, np.float64)
    out = np.zeros((len(terms), 4))
    for k, row in enumerate(terms):
        if row[0] == HEIGHT and z0 > 0.0:
            x = z0 / row[2]
            out[k] = math.exp(-x), -math.expm1(-x) / x, 1.0 / row[2], 1.0
        elif row[0] == BANK:
            out[k, 0], out[k, 3] = _ramp_integral(float(u0), *(float(v) for v in row[2:7])), 1.0
    return out


@njit(cache=True, inline="always")
def origin_depth(terms, consts, u0, z0, du, dz, length):
    """:func:`segment_depth` of segments that all start at ``(u0, z0)``, with that start's constants
    (:func:`origin_constants`): a bank's integral up to the start is read, not recomputed, and a height term takes
    one exponential, not two (``β(z0)·L·(e^{x} − 1)/x``, ``x = (z0 − z1)/H``; below the road ``β(0)`` there and the mean
    of β over ``[0, z0]`` above it). Banks and homogeneous terms give ``segment_depth``'s bits; height terms agree to
    rounding (1e-13 relative)."""
    tau = 0.0
    for k in range(terms.shape[0]):
        kind, b0 = terms[k, 0], terms[k, 1]
        if kind == 0.0:
            tau += b0 * length
        elif kind == 1.0 and consts[k, 3] != 0.0:
            z1 = z0 + dz * length
            if z1 < 0.0:  # (z0 > 0: the part below the road is (−z1)/(z0 − z1) of the segment)
                below = length * (-z1) / (z0 - z1)
                tau += b0 * (below + (length - below) * consts[k, 1])
            else:  # x = (z0 − z1)/H, > 0 down: the mean of e^{x·s} over s ∈ [0, 1], (e^x − 1)/x (its series near 0)
                x = (z0 - z1) * consts[k, 2]
                mean = 1.0 + x * (0.5 + x * (1.0 / 6.0 + x / 24.0)) if abs(x) < 1e-3 else (math.exp(x) - 1.0) / x
                tau += b0 * consts[k, 0] * length * mean
        elif kind == 1.0:  # a start at or below the road: the general form
            tau += _height_term(b0, terms[k, 2], z0, dz, length)
        else:
            a, b, c, d, p = terms[k, 2], terms[k, 3], terms[k, 4], terms[k, 5], terms[k, 6]
            span = du * length
            if abs(span) < 1e-6:
                mean_w = _ramp(u0 + 0.5 * span, a, b, c, d, p)
            else:
                mean_w = (_ramp_integral(u0 + span, a, b, c, d, p) - consts[k, 0]) / span
            tau += (terms[k, 7] + b0 * mean_w) * length
    return tau


@njit(cache=True, nogil=True)
def point_extinction(terms, u, z):
    """``β`` of the packed field at ``(u, z)`` [1/m]."""
    beta = 0.0
    for k in range(terms.shape[0]):
        kind = terms[k, 0]
        if kind == 0.0:
            beta += terms[k, 1]
        elif kind == 1.0:
            beta += terms[k, 1] * math.exp(-max(z, 0.0) / terms[k, 2])
        else:
            beta += terms[k, 7] + terms[k, 1] * _ramp(u, terms[k, 2], terms[k, 3], terms[k, 4], terms[k, 5], terms[k, 6])
    return beta


@njit(cache=True, nogil=True)
def _depths(terms, u0, z0, du, dz, length, out):
    for n in range(out.shape[0]):
        out[n] = segment_depth(terms, u0[n], z0[n], du[n], dz[n], length[n])


@njit(cache=True, nogil=True)
def _betas(terms, u, z, out):
    for n in range(out.shape[0]):
        out[n] = point_extinction(terms, u[n], z[n])


def optical_depths(terms: np.ndarray, u0, z0, du, dz, length) -> np.ndarray:
    """:func:`segment_depth` for arrays (broadcast together), float64 of their shape."""
    args = np.broadcast_arrays(*(np.asarray(a, np.float64) for a in (u0, z0, du, dz, length)))
    out = np.empty(args[0].size)
    _depths(np.ascontiguousarray(terms, np.float64), *(np.ascontiguousarray(a).reshape(-1) for a in args), out)
    return out.reshape(args[0].shape)


def extinctions(terms: np.ndarray, u, z) -> np.ndarray:
    """:func:`point_extinction` for arrays (broadcast together)."""
    uu, zz = np.broadcast_arrays(np.asarray(u, np.float64), np.asarray(z, np.float64))
    out = np.empty(uu.size)
    _betas(np.ascontiguousarray(terms, np.float64), np.ascontiguousarray(uu).reshape(-1),
           np.ascontiguousarray(zz).reshape(-1), out)  # fmt: skip
    return out.reshape(uu.shape)


def field_pose(sensor_to_world: np.ndarray, frame: tuple[float, float, float]) -> np.ndarray:
    """A sensor in the field frame: ``(u, z, a_u, a_z)`` as 8 floats, its origin's distance along the frame's heading
    and its height, and the rows that turn a direction of the sensor's frame into its run along ``u`` and up (for a
    camera's optical frame, x right, y down, z forward, a pixel's ray ``(x, y, 1)`` per metre of planar depth:
    ``fog_gym.fog.camera.fog_field_images``; for a LiDAR, a unit direction: ``fog_gym.fog.lidar_field.fog_lidar_field``).
    ``sensor_to_world`` is the sensor's 4×4 frame → world transform; ``frame`` the field frame ``(x0, y0, heading)``:
    its origin on the road and its heading [rad].

    >>> pose = field_pose(np.array([[0, 0, 1, 5.0], [-1, 0, 0, 0], [0, -1, 0, 1.5], [0, 0, 0, 1]]), (0.0, 0.0, 0.0))
    >>> pose.tolist()  # a camera 5 m ahead, 1.5 m up, looking along the heading: ray (0, 0, 1) runs 1 m along u
    [5.0, 1.5, 0.0, 0.0, 1.0, 0.0, -1.0, 0.0]
    """
    M = np.asarray(sensor_to_world, np.float64)
    x0, y0, heading = (float(v) for v in frame)
    h = np.array([math.cos(heading), math.sin(heading), 0.0])
    centre = M[:3, 3]
    return np.concatenate([[(centre[0] - x0) * h[0] + (centre[1] - y0) * h[1], centre[2]], h @ M[:3, :3], M[2, :3]])

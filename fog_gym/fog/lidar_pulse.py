"""The LiDAR fog field paths' shared parts (:mod:`fog_gym.fog.lidar_field`): the soft return's kernel on a range grid
(:func:`field_pulse_weights`), its running maximum along beam directions (``_curves``: the curves every point of a
direction reads), and Hahner et al.'s rule given a point's hard and soft returns (``_field_rule``; its callers
write the row).

Example:
    >>> W, V = field_pulse_weights(); W.shape[1], round(float(KAPPA), 5)
    (61, 0.01536)
"""

from __future__ import annotations

import functools
import math

import numpy as np
from numba import njit, prange

import fog_gym._numba  # noqa: F401  (numba's fork-safe threading layer, before any kernel runs)
from fog_gym._numba import SERIAL_BELOW, pick, serial_twin
from fog_gym.fog.depth import BANK, origin_constants, origin_depth, point_extinction, segment_depth
from fog_gym.fog.lidar import BETA_PER_MOR, GAMMA, REFERENCE_REFLECTIVITY, SPEED_OF_LIGHT, TAU_H, XI_R1, XI_R2


#: The field path's range grid [m]: returns are decided on ranges kΔ, the pulse integral on the same step.
FIELD_STEP = 0.1
#: The soft return's maximum is looked for every FIELD_COARSE nodes (with their own weights), then on every node within
#: two coarse steps of the coarse maximum and of the coarse maximum within NEAR_FIELD_NODES of the sensor.
FIELD_COARSE, NEAR_FIELD_NODES = 5, 100
#: Fine nodes per range step in the pulse integral's kernel (the transmittance is interpolated between range nodes).
FIELD_SUBSTEPS = 20
#: Backscatter per extinction: Hahner et al.'s β = 0.046 / MOR with MOR = ln 20 / α, so β(r) = KAPPA · β_ext(r).
KAPPA = BETA_PER_MOR / math.log(20.0)


@functools.lru_cache(maxsize=4)
def field_pulse_weights(step: float = FIELD_STEP, max_range: float = 200.0) -> tuple[np.ndarray, np.ndarray]:
    """Weights of the soft return on the range grid ``R_k = k·step``: ``W (K, N + 1)`` and ``V (K,)`` with
    ``F(R_k) = Σ_n W[k, n]·E_{k−n} + V[k]·β₁·E_{j₁}``, ``E_j = e^{−2τ(j·step)}`` the two-way transmittance on the ray,
    ``β₁`` the extinction 1 m out and ``j₁`` its node (``N`` nodes over the pulse's 6 m: 60).

    From the LiDAR equation with the local backscatter ``κ·β``: ``F(R) = ∫ P(t)·κβ(R′)·E(R′)·g(R′) dt``, ``R′ = R − ct/2``,
    ``g = ξ/R′²``, ``P = sin²(πt / 2τ_H)``. Where the overlap ξ is full (``R′ ≥ 1 m``), ``βE = −½ dE/dR′ = (1/c) dE/dt``
    and integration by parts gives ``−(κ/c) ∫ E·d/dt[P·g] dt`` plus ``(κ/c)·P·g·E`` where the window reaches 1 m (P
    vanishes at the pulse's ends): a field-independent kernel applied to the transmittance, which stays continuous
    where β jumps (a bank with ``edge = 0``); Simpson's rule over the nodes. The overlap's ramp (0.9–1 m, ξ linear)
    adds ``κ·β·E·∫ P·ξ/R′² dt`` with β and E taken halfway up the ramp (``β₁``, ``E₁·e^{0.1·β₁}``).

    >>> W, V = field_pulse_weights(); W.shape, V.shape
    ((2001, 61), (2001,))
    """
    n_nodes = int(round(SPEED_OF_LIGHT * TAU_H / step))  # 2τ_H·c/2 = 6 m of range
    n_nodes += n_nodes % 2
    fine = FIELD_SUBSTEPS * n_nodes  # the kernel varies fast near the sensor (1/R′³): Simpson on a finer grid, E
    ds = step / FIELD_SUBSTEPS  # interpolated linearly between its nodes
    s_f = np.arange(fine + 1) * ds  # range behind R of each fine node
    t_f = 2.0 * s_f / SPEED_OF_LIGHT
    phase = np.pi * t_f / (2.0 * TAU_H)
    pulse, d_pulse = np.sin(phase) ** 2, np.pi / (2.0 * TAU_H) * np.sin(2.0 * phase)
    full = int(round(XI_R2 / step))  # the node of R′ = 1 m
    ramp_dt = 2.0 * (XI_R2 - XI_R1) / SPEED_OF_LIGHT
    k_max = int(round(max_range / step))
    W = np.zeros((k_max + 1, n_nodes + 1))
    V = np.zeros(k_max + 1)
    node, frac = np.arange(fine + 1) // FIELD_SUBSTEPS, (np.arange(fine + 1) % FIELD_SUBSTEPS) / FIELD_SUBSTEPS
    for k in range(full, k_max + 1):
        m = min(fine, (k - full) * FIELD_SUBSTEPS)  # fine nodes 0 … m lie where ξ = 1
        r = k * step - s_f[:m + 1]
        d_pg = d_pulse[:m + 1] / r**2 + pulse[:m + 1] * (-2.0 / r**3) * (-SPEED_OF_LIGHT / 2.0)  # d/dt[P·g]
        wf = -(KAPPA / SPEED_OF_LIGHT) * d_pg * _composite_weights(m, 2.0 * ds / SPEED_OF_LIGHT)
        np.add.at(W[k], node[:m + 1], wf * (1.0 - frac[:m + 1]))
        np.add.at(W[k], np.minimum(node[:m + 1] + 1, n_nodes), wf * frac[:m + 1])
        if m < fine:  # the window reaches 1 m: the boundary term and the overlap's ramp
            W[k, m // FIELD_SUBSTEPS] += (KAPPA / SPEED_OF_LIGHT) * pulse[m] / (XI_R2 * XI_R2)
            ramp = np.linspace(0.0, ramp_dt, 41)  # ∫ P·ξ/R′² dt over the ramp (β and E taken 5 cm in)
            r_ramp = XI_R2 - SPEED_OF_LIGHT * ramp / 2.0
            p_ramp = np.sin(np.pi * (t_f[m] + ramp) / (2.0 * TAU_H)) ** 2
            V[k] = KAPPA * float(_composite_weights(40, ramp[1]) @ (p_ramp * (r_ramp - XI_R1) / (XI_R2 - XI_R1) / r_ramp**2))
    return W, V


def _composite_weights(m: int, h: float) -> np.ndarray:
    """Quadrature weights of m + 1 equally spaced nodes: Simpson, with Simpson's 3/8 on the last three intervals
    when m is odd (the trapezoid for m = 1, nothing for m = 0)."""
    w = np.zeros(m + 1)
    if m == 0:
        return w
    if m == 1:
        return np.array([h / 2, h / 2])
    even = m if m % 2 == 0 else m - 3
    if even > 0:
        w[:even + 1] += np.r_[1.0, np.tile([4.0, 2.0], even // 2)[:-1], 1.0] * h / 3.0
    if m % 2:
        w[even:even + 4] += np.array([1.0, 3.0, 3.0, 1.0]) * 3.0 * h / 8.0
    return w


#: ``∫ P(t) dt`` over the pulse (sin² averages ½ over 2τ_H).
PULSE_INTEGRAL = TAU_H


@njit(cache=True, inline="always")
def _soft_bound(r, beta_max, window_far):
    # An upper bound of the soft return F at range r ≥ 7 m: κ·β_max·E(r − 6 m)·∫P dt / (r − 6 m)² (the pulse's window
    # reaches back 6 m, where ξ ≤ 1, R′ ≥ r − 6 m and E(R′) ≤ E(r − 6 m) = window_far, as E falls along the ray);
    # infinite nearer.
    near = r - SPEED_OF_LIGHT * TAU_H
    return KAPPA * beta_max * window_far * PULSE_INTEGRAL / (near * near) if near >= XI_R2 else np.inf


@njit(cache=True, inline="always")
def _field_rule(intensity, r0, i_orig, i_hard, best, r_tmp, log_noise, u_n, attenuation):
    # Hahner et al.'s rule for a point of CARLA intensity `intensity` given its soft return's maximum `best` (s/m², with
    # the backscatter) at range r_tmp: the fog's return replaces the point when stronger, on the same ray with the
    # range noise (u_n: the point's uniform draw); as _hahner. Returns the factor on the point's x, y, z (1 when kept:
    # float32 → float64 → × 1 → float32 is the same number) and its new intensity. Scalars in and out: the caller
    # writes the row in its own loop (numba counted references to arrays passed to a helper at every point).
    ratio = math.pi / GAMMA
    if attenuation >= 0.0:  # reflectance intensities: the point's own reflectivity stands in for Γ
        rho = min(max(intensity / np.exp(-attenuation * r0), 1e-3), 1.0)
        ratio = ratio * REFERENCE_REFLECTIVITY / rho
    i_soft = min(255.0, best * i_orig * r0 * r0 * ratio)
    if i_soft > i_hard:  # the fog's own return is stronger: a fog point on the same ray
        return r_tmp / max(r0, 1e-12) * np.exp(log_noise * u_n), np.float32(i_soft / 255.0)
    return 1.0, np.float32(i_hard / 255.0)


@njit(cache=True, nogil=True, parallel=True)
def _soft_curves(terms, consts, u0, z0, dus, dzs, tops, weights, ramp, step, best, where, stops, beta_max):
    # For beam directions (dus[i], dzs[i]): the running maximum of the soft return F over ranges k·step, k ≤ tops[i],
    # into best[i, k], and the range node where it lies into where[i, k] (every node from the first with fog on the
    # ray, as _hahner_field's refinement does near its maximum, until _soft_bound shows that no farther range can beat
    # the maximum so far: stops[i] is the last node written, and the curve is constant beyond it). τ from the sensor's
    # constants (origin_depth).
    n_nodes = weights.shape[1]
    one = int(np.round(XI_R2 / step))
    n = dus.shape[0]
    chunks = min(n, _CURVE_CHUNKS)
    longest = 0
    for i in range(n):
        longest = max(longest, tops[i])
    for c in prange(chunks):  # curves c, c + chunks, …: a chunk's curves from every part of the grid (their lengths
        trans = np.empty(longest + 1)  # differ by rows: contiguous shares left one thread most of the work), and one
        for i in range(c, n, chunks):  # scratch array a chunk (an allocation per curve kept the threads waiting)
            _soft_curve(terms, consts, u0, z0, dus[i], dzs[i], tops[i], weights, ramp, step, best, where, stops,
                        beta_max, n_nodes, one, trans, i)


#: Chunks of :func:`_soft_curves`'s parallel loop (each takes every ``_CURVE_CHUNKS``-th curve).
_CURVE_CHUNKS = 64


@njit(cache=True, inline="always")
def _soft_curve(terms, consts, u0, z0, du, dz, top, weights, ramp, step, best, where, stops, beta_max, n_nodes, one,
                trans, i):
    # _soft_curves' curve i, its transmittance in trans (scratch, at least top + 1 long)
    beta1 = point_extinction(terms, u0 + du * XI_R2, z0 + dz * XI_R2)
    lift = 0.0 if one > top else beta1 * np.exp(-2.0 * origin_depth(terms, consts, u0, z0, du, dz, one * step)) * \
        np.exp(beta1 * (XI_R2 - XI_R1))  # fmt: skip
    start = max(one, _clear_node(terms, u0, z0, du, dz, step, top))
    for j in range(max(start - n_nodes + 1, 0), min(start, top + 1)):  # the first window's transmittance
        trans[j] = np.exp(-2.0 * origin_depth(terms, consts, u0, z0, du, dz, j * step))
    top_f, top_k, k = 0.0, 0, 0
    while k <= top:
        if k >= start:
            if top_f > 0.0 and top_f >= _soft_bound(k * step, beta_max, trans[max(k - n_nodes + 1, 0)]):
                break
            trans[k] = np.exp(-2.0 * origin_depth(terms, consts, u0, z0, du, dz, k * step))
            f = ramp[k] * lift + _window(weights, k, trans, min(n_nodes, k + 1))
            if f > top_f:
                top_f, top_k = f, k
        best[i, k], where[i, k] = top_f, top_k
        k += 1
    stops[i] = k - 1


_soft_curves_serial = serial_twin(_soft_curves)


@njit(cache=True, inline="always")
def _window(weights, k, trans, count):
    # Σ_{m < count} weights[k, m]·trans[k − m] on four accumulators (a sum's chain of additions is the loop's cost)
    s0, s1, s2, s3 = 0.0, 0.0, 0.0, 0.0
    m = 0
    while m + 3 < count:
        s0 += weights[k, m] * trans[k - m]
        s1 += weights[k, m + 1] * trans[k - m - 1]
        s2 += weights[k, m + 2] * trans[k - m - 2]
        s3 += weights[k, m + 3] * trans[k - m - 3]
        m += 4
    while m < count:
        s0 += weights[k, m] * trans[k - m]
        m += 1
    return (s0 + s1) + (s2 + s3)


@njit(cache=True, inline="always")
def _transmission(terms, consts, u0, z0, du, dz, r):
    # E = e^{−2τ(r)} on the ray (τ from the start's constants, origin_depth, when consts has rows; else
    # segment_depth). Its callers cache it in their own array: the array is not passed in, since numba counted a
    # reference to it at every call of a helper that wrote to it (two atomic operations per node: 14–16 µs a beam
    # against 4.1 µs without)
    if consts.shape[0]:
        return np.exp(-2.0 * origin_depth(terms, consts, u0, z0, du, dz, r))
    return np.exp(-2.0 * segment_depth(terms, u0, z0, du, dz, r))


#: No start constants: :func:`beam_soft_maximum` takes τ from :func:`~fog_gym.fog.depth.segment_depth`.
_NO_CONSTS = np.zeros((0, 4))


@njit(cache=True, inline="always")
def beam_soft_maximum(terms, u0, z0, du, dz, r0, weights, ramp, weights5, ramp5, coarse, step, beta_max):
    """:func:`beam_soft_maximum_from` with τ from :func:`~fog_gym.fog.depth.segment_depth` (the per-beam path's)."""
    return beam_soft_maximum_from(terms, _NO_CONSTS, u0, z0, du, dz, r0, weights, ramp, weights5, ramp5, coarse, step,
                                  beta_max)  # fmt: skip


@njit(cache=True, inline="always")
def beam_soft_maximum_from(terms, consts, u0, z0, du, dz, r0, weights, ramp, weights5, ramp5, coarse, step, beta_max):
    """The soft return's maximum ``max_{R ≤ R0} F(R)`` (s/m², with the backscatter) on a beam from ``(u0, z0)`` with
    unit-direction components ``du`` (along u) and ``dz`` (up) to range ``r0``, and the range node where it lies:
    ``E_j = e^{−2τ(jΔ)}`` on the ray, ``F_k = Σ_n W[k, n]·E_{k−n}`` (:func:`field_pulse_weights`) on coarse ranges every
    ``coarse`` nodes (their own weights ``weights5``), stopped by the bound, then on every node near the sensor (where
    1/R′² varies fast) and around the coarse maximum. τ from the sensor's constants ``consts``
    (:func:`~fog_gym.fog.depth.origin_constants`, one exponential a node for a height term; the same decisions) or,
    with no rows, from :func:`~fog_gym.fog.depth.segment_depth`."""
    n_nodes = weights.shape[1]
    top = min(int(np.round(min(r0, 200.0) / step)), weights.shape[0] - 1)
    trans = np.full(top + 1, -1.0)  # E_j, computed when a window first needs it (written here, not in a helper)
    clear = _clear_node(terms, u0, z0, du, dz, step, top)
    one = int(np.round(XI_R2 / step))  # the node 1 m out, and the extinction there
    beta1 = point_extinction(terms, u0 + du * XI_R2, z0 + dz * XI_R2)
    near = 0.0
    if one <= top:
        trans[one] = near = _transmission(terms, consts, u0, z0, du, dz, one * step)
    lift = beta1 * near * np.exp(beta1 * (XI_R2 - XI_R1))
    best5, best5_k, near5, near5_k = -1.0, -1, -1.0, -1  # the coarse maximum, and the one near the sensor
    for k5 in range((max(one, clear) + coarse - 1) // coarse, top // coarse + 1):
        back = k5 * coarse - (n_nodes - 1)  # where the pulse's window begins (the bound takes E there)
        if best5 > 0.0 and back >= 0:
            if trans[back] < 0.0:
                trans[back] = _transmission(terms, consts, u0, z0, du, dz, back * step)
            if _soft_bound(k5 * coarse * step, beta_max, trans[back]) < 0.95 * best5:
                break  # no farther range can beat the maximum so far (a margin for the coarse weights)
        f = ramp5[k5] * lift
        for m in range(min(weights5.shape[1], k5 + 1)):
            j = coarse * (k5 - m)
            if trans[j] < 0.0:
                trans[j] = _transmission(terms, consts, u0, z0, du, dz, j * step)
            f += weights5[k5, m] * trans[j]
        if f > best5:
            best5, best5_k = f, k5 * coarse
        if f > near5 and k5 * coarse <= NEAR_FIELD_NODES:
            near5, near5_k = f, k5 * coarse
    best, best_k = 0.0, 0
    start = max(one, clear)
    for part in range(2):
        centre = near5_k if part == 0 else best5_k
        if centre < 0 or (part == 1 and centre == near5_k):
            continue
        for k in range(max(start, centre - 2 * coarse), min(centre + 2 * coarse, top) + 1):
            f = ramp[k] * lift
            for m in range(min(n_nodes, k + 1)):
                j = k - m
                if trans[j] < 0.0:
                    trans[j] = _transmission(terms, consts, u0, z0, du, dz, j * step)
                f += weights[k, m] * trans[j]
            if f > best:
                best, best_k = f, k
    return best, best_k


@njit(cache=True, inline="always")
def _clear_node(terms, u0, z0, du, dz, step, top):
    # The last node before the fog starts on the ray (a window in clear air returns nothing): τ only grows along the
    # ray, so a bisection finds it (0 where the fog starts at the sensor, top where the ray stays clear).
    clear, fog = 0, top
    if segment_depth(terms, u0, z0, du, dz, step) > 0.0:
        fog = 1
    while fog - clear > 1:
        mid = (clear + fog) // 2
        if segment_depth(terms, u0, z0, du, dz, mid * step) == 0.0:
            clear = mid
        else:
            fog = mid
    return clear


def peak_extinction(terms: np.ndarray) -> float:
    """An upper bound of a packed field's extinction anywhere [1/m]: the sum of its terms' peaks."""
    peak = 0.0
    for row in np.asarray(terms, np.float64):
        peak += row[1] if row[0] != BANK else row[7] + max(row[1], 0.0) * row[6]
    return float(peak)


def _curves(terms: np.ndarray, pose: np.ndarray, dus: np.ndarray, dzs: np.ndarray, tops: np.ndarray,
            consts: np.ndarray | None = None, points: int = SERIAL_BELOW):
    """:func:`_soft_curves` of these beam directions: ``best``, ``where`` (each row written up to its ``stops``);
    ``consts`` the sensor's :func:`~fog_gym.fog.depth.origin_constants` (computed when not given); ``points`` the
    sweep's size, which picks the kernel (one thread below :data:`~fog_gym._numba.SERIAL_BELOW`: an RL agent's sweep
    reads a few dozen curves, less work than a parallel launch costs)."""
    if consts is None:
        consts = origin_constants(terms, float(pose[0]), float(pose[1]))
    weights, ramp = field_pulse_weights()
    best = np.empty((len(dus), int(tops.max(initial=0)) + 1))
    where = np.empty(best.shape, np.int64)
    stops = np.zeros(len(dus), np.int64)
    pick(_soft_curves, _soft_curves_serial, points)(terms, consts, pose[0], pose[1], dus, dzs, tops, weights, ramp,
                                                    FIELD_STEP, best, where, stops, peak_extinction(terms))
    return best, where, stops

"""Hahner et al.'s LiDAR fog with a fog field (:mod:`fog_gym.fog.fields`): the local extinction β(r) along each beam
(``docs/fog.md``, "Fog with a shape"). :func:`fog_lidar_field` is the entry; a homogeneous field goes through
:func:`fog_gym.fog.lidar.fog_lidar`.

Three paths give the same decisions (tested against each other and against a direct integration of the LiDAR
equation): fields whose β depends on height only read one soft-return curve per beam elevation; a single fog bank
reads curves per beam run along the bank's axis, aligned on the bank's face (:func:`_bank_plan`); any other
field integrates each beam on its own (:func:`_hahner_field`).

Example:
    >>> from fog_gym.fog.fields import FogBank
    >>> from fog_gym.fog.depth import field_pose
    >>> pts = np.array([[30.0, 0, 0, 0.5], [120.0, 0, 0, 0.5]], np.float32)
    >>> pose = field_pose(np.eye(4), (0, 0, 0))
    >>> out = fog_lidar_field(pts, FogBank(20.0, 60.0, 30.0), np.random.default_rng(0), pose, noise=0.0)
    >>> out[0].tolist() == pts[0].tolist(), bool(50.0 < out[1, 0] < 70.0)  # kept before the bank; behind: its face
    (True, True)
"""

from __future__ import annotations

import functools
import math

import numpy as np
from numba import njit, prange

import fog_gym._numba  # noqa: F401  (numba's fork-safe threading layer, before any kernel runs)
from fog_gym.fog.depth import BANK, point_extinction, segment_depth
from fog_gym.fog.lidar import (
    BETA_PER_MOR, GAMMA, REFERENCE_REFLECTIVITY, SPEED_OF_LIGHT, TAU_H, XI_R1, XI_R2, _checked_points, fog_lidar,
)  # fmt: skip
from fog_gym.fog.physics import FogLevel


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
def _soft_bound(r, beta_max):
    # An upper bound of the soft return F at range r ≥ 7 m: κ·β_max·∫P dt / (r − 6 m)² (E ≤ 1, ξ ≤ 1, R′ ≥ r − 6 m);
    # infinite nearer.
    near = r - SPEED_OF_LIGHT * TAU_H
    return KAPPA * beta_max * PULSE_INTEGRAL / (near * near) if near >= XI_R2 else np.inf


@njit(cache=True, inline="always")
def _beam(pts, n, pose, terms, out, height):
    # Point n's beam in the field frame: its range, unit direction's run along u and up, τ to the point in closed form,
    # its 0–255 intensity and hard return; a beam without fog keeps the point as in clear air (written to out).
    # height: empty, or for a field of height and homogeneous terms each term's constants (_height_depth).
    x, y, z = np.float64(pts[n, 0]), np.float64(pts[n, 1]), np.float64(pts[n, 2])
    r0 = np.sqrt(x * x + y * y + z * z)
    inv = 1.0 / max(r0, 1e-12)
    du = (pose[2] * x + pose[3] * y + pose[4] * z) * inv
    dz = (pose[5] * x + pose[6] * y + pose[7] * z) * inv
    if height.shape[0]:
        tau0 = _height_depth(terms, height, pose[1], dz, r0)
    else:
        tau0 = segment_depth(terms, pose[0], pose[1], du, dz, r0)
    i_orig = np.round(np.float64(pts[n, 3]) * 255.0)
    if tau0 == 0.0:
        for c in range(pts.shape[1]):
            out[n, c] = pts[n, c]
    return r0, du, dz, tau0, i_orig, np.round(i_orig * np.exp(-2.0 * tau0))


@njit(cache=True, inline="always")
def _height_depth(terms, height, z0, dz, length):
    # segment_depth of height and homogeneous terms from a sensor at z0 > 0, with the sensor's constants per term
    # (height[k] = e^{−z0/H}, g(z0/H) = (1 − e^{−z0/H})/(z0/H)): a segment that ends below the road sees β(0) there
    # and the mean of β over [0, z0] above it (no exponential); one that stays above it β(z0)·L·(e^{x} − 1)/x down or
    # β(z0)·L·(1 − e^{−x})/x up, x = |Δz|/H (one). The same formulas as segment_depth, rearranged.
    z1 = z0 + dz * length
    tau = 0.0
    for k in range(terms.shape[0]):
        b0 = terms[k, 1]
        if terms[k, 0] == 0.0:
            tau += b0 * length
        elif z1 < 0.0:  # (z0 > 0: the part below the road is (−z1)/(z0 − z1) of the segment)
            below = length * (-z1) / (z0 - z1)
            tau += b0 * (below + (length - below) * height[k, 1])
        else:
            x = abs(z1 - z0) / terms[k, 2]
            if x < 1e-6:
                mean = 1.0 + 0.5 * x if z1 < z0 else 1.0 - 0.5 * x
            else:
                mean = (math.exp(x) - 1.0) / x if z1 < z0 else -math.expm1(-x) / x
            tau += b0 * height[k, 0] * length * mean
    return tau


def _height_constants(terms: np.ndarray, z0: float) -> np.ndarray:
    """_height_depth's constants of a field of height and homogeneous terms seen from z0 > 0 (empty otherwise: the
    general closed form)."""
    if z0 <= 0.0 or not np.all((terms[:, 0] == 0.0) | (terms[:, 0] == 1.0)):
        return np.zeros((0, 2))
    out = np.zeros((len(terms), 2))
    for k, row in enumerate(terms):
        if row[0] == 1.0:
            x = z0 / row[2]
            out[k] = math.exp(-x), -math.expm1(-x) / x
    return out


@njit(cache=True, inline="always")
def _field_rule(pts, n, out, r0, i_orig, i_hard, best, r_tmp, log_noise, u, attenuation):
    # Hahner et al.'s rule for point n given its soft return's maximum `best` (s/m², with the backscatter) at range
    # r_tmp: the fog's return replaces the point when stronger, on the same ray with the range noise; as _hahner.
    ratio = math.pi / GAMMA
    if attenuation >= 0.0:  # reflectance intensities: the point's own reflectivity stands in for Γ
        rho = min(max(np.float64(pts[n, 3]) / np.exp(-attenuation * r0), 1e-3), 1.0)
        ratio = ratio * REFERENCE_REFLECTIVITY / rho
    i_soft = min(255.0, best * i_orig * r0 * r0 * ratio)
    if i_soft > i_hard:  # the fog's own return is stronger: a fog point on the same ray
        scale = r_tmp / max(r0, 1e-12) * np.exp(log_noise * u[n])
        for c in range(3):
            out[n, c] = np.float32(np.float64(pts[n, c]) * scale)
        out[n, 3] = np.float32(i_soft / 255.0)
    else:
        for c in range(3):
            out[n, c] = pts[n, c]
        out[n, 3] = np.float32(i_hard / 255.0)
    for c in range(4, pts.shape[1]):
        out[n, c] = pts[n, c]


@njit(cache=True, parallel=True)
def _elevation_nodes(pts, pose, rounding, most, step, last):
    # The beam elevations (run up per metre) of the points, rounded to `rounding`, when there are at most `most` of
    # them; else a uniform grid of `most` over their span. Per node, the farthest range node of a point that reads
    # its curve (the nodes on both sides of the point).
    n = pts.shape[0]
    dz = np.empty(n)
    ks = np.empty(n, np.int64)
    for i in prange(n):
        x, y, z = np.float64(pts[i, 0]), np.float64(pts[i, 1]), np.float64(pts[i, 2])
        r0 = np.sqrt(x * x + y * y + z * z)
        dz[i] = (pose[5] * x + pose[6] * y + pose[7] * z) / max(r0, 1e-12)
        ks[i] = min(int(np.round(min(r0, 200.0) / step)), last)
    low, high = dz.min(), dz.max()
    lo_key = int(np.round(low / rounding))
    far = np.full(int(np.round(high / rounding)) - lo_key + 1, -1, np.int64)  # per rounded elevation, its farthest node
    for i in range(n):
        key = int(np.round(dz[i] / rounding)) - lo_key
        far[key] = max(far[key], ks[i])
    count = int((far >= 0).sum())
    if count <= most:  # a node per elevation, which reads its own points only
        nodes = np.empty(count)
        tops = np.empty(count, np.int64)
        j = 0
        for key in range(far.shape[0]):
            if far[key] >= 0:
                nodes[j], tops[j] = (key + lo_key) * rounding, far[key]
                j += 1
        own = tops.copy()  # (a point rounds to its node but may read its neighbour's curve too)
        for j in range(count):
            tops[j] = max(own[max(j - 1, 0)], own[j], own[min(j + 1, count - 1)])
        return nodes, tops, _first_at_or_above(nodes, lo_key, far.shape[0], rounding), lo_key
    nodes = np.linspace(low, high, most)
    tops = np.zeros(most, np.int64)
    width = (high - low) / (most - 1)
    for key in range(far.shape[0]):
        if far[key] >= 0:
            cell = min(int(((key + lo_key) * rounding - low) / width), most - 2) if width > 0.0 else 0
            for j in range(max(cell - 1, 0), min(cell + 3, most)):
                tops[j] = max(tops[j], far[key])
    return nodes, tops, _first_at_or_above(nodes, lo_key, far.shape[0], rounding), lo_key


@njit(cache=True)
def _first_at_or_above(nodes, lo_key, keys, rounding):
    # per rounded elevation key (lo_key + c), the first node at or above (key − ½)·rounding: a point's searchsorted in
    # one read and at most one step (_hahner_curves)
    first = np.empty(keys, np.int64)
    j = 0
    for c in range(keys):
        while j < nodes.shape[0] and nodes[j] < (lo_key + c - 0.5) * rounding:
            j += 1
        first[c] = j
    return first


@njit(cache=True, parallel=True)
def _soft_curves(terms, u0, z0, dus, dzs, tops, weights, ramp, step, best, where, stops, beta_max):
    # For beam directions (dus[i], dzs[i]): the running maximum of the soft return F over ranges k·step, k ≤ tops[i],
    # into best[i, k], and the range node where it lies into where[i, k] (every node from the first with fog on the
    # ray, as _hahner_field's refinement does near its maximum, until _soft_bound shows that no farther range can beat
    # the maximum so far: stops[i] is the last node written, and the curve is constant beyond it).
    n_nodes = weights.shape[1]
    one = int(np.round(XI_R2 / step))
    for i in prange(dus.shape[0]):
        du, dz, top = dus[i], dzs[i], tops[i]
        trans = np.full(top + 1, -1.0)
        beta1 = point_extinction(terms, u0 + du * XI_R2, z0 + dz * XI_R2)
        lift = 0.0 if one > top else beta1 * _transmittance(trans, one, terms, u0, z0, du, dz, step) * \
            np.exp(beta1 * (XI_R2 - XI_R1))  # fmt: skip
        start = max(one, _clear_node(terms, u0, z0, du, dz, step, top))
        top_f, top_k, k = 0.0, 0, 0
        while k <= top:
            if k >= start:
                if top_f > 0.0 and top_f >= _soft_bound(k * step, beta_max):
                    break
                f = ramp[k] * lift
                for m in range(min(n_nodes, k + 1)):
                    f += weights[k, m] * _transmittance(trans, k - m, terms, u0, z0, du, dz, step)
                if f > top_f:
                    top_f, top_k = f, k
            best[i, k], where[i, k] = top_f, top_k
            k += 1
        stops[i] = k - 1


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


@njit(cache=True, parallel=True)
def _hahner_curves(pts, pose, terms, height, node_dz, first, lo_key, rounding, best, where, stops, step, log_noise, u,
                   out, attenuation):
    # Hahner et al. with a field whose β depends on height only: each point's soft-return maximum from the curves of
    # the two beam elevations around its own (node_dz ascending; linear in dz, the range of the nearer), its hard
    # return exactly (τ in closed form); then the rule (_field_rule).
    last = best.shape[1] - 1
    for n in prange(pts.shape[0]):
        r0, _, dz, tau0, i_orig, i_hard = _beam(pts, n, pose, terms, out, height)
        if tau0 == 0.0:  # (kept as in clear air)
            continue
        k = min(int(np.round(min(r0, 200.0) / step)), last)
        hi = first[min(max(int(np.round(dz / rounding)) - lo_key, 0), first.shape[0] - 1)]
        while hi < node_dz.shape[0] and node_dz[hi] < dz:  # (searchsorted: the first node at or above dz)
            hi += 1
        hi = min(max(hi, 1), node_dz.shape[0] - 1) if node_dz.shape[0] > 1 else 0
        lo = max(hi - 1, 0)
        span = node_dz[hi] - node_dz[lo]
        t = min(max((dz - node_dz[lo]) / span, 0.0), 1.0) if span > 0.0 else 0.0
        f = (1.0 - t) * best[lo, min(k, stops[lo])] + t * best[hi, min(k, stops[hi])]
        near = hi if t >= 0.5 else lo
        r_tmp = where[near, min(k, stops[near])] * step
        _field_rule(pts, n, out, r0, i_orig, i_hard, f, r_tmp, log_noise, u, attenuation)


#: A single fog bank's curves: beam runs along u (the bank's axis) on a geometric grid of this ratio, face-aligned (a
#: point reads the two runs around its own at the same range past the bank's face); inside a bank the runs go down to
#: ±BANK_MIN_RUN on both sides of 0.
BANK_RATIO, BANK_MIN_RUN = 1.05, 0.02


def _bank_plan(terms: np.ndarray, pose: np.ndarray):
    """``(side, align, nodes, background)`` for a field of one bank and homogeneous terms (None for any other field),
    ``background`` the extinction outside the bank: ``side``
    +1 where the sensor lies before the bank (the beams that reach it run along +u and meet its face at ``u = align``),
    −1 past it, 0 inside it (every beam starts in fog; ``nodes`` the signed runs); else ``nodes`` the runs
    ``side·du`` > 0 of the curves, from the shallowest whose ray meets the face within the points' range."""
    kinds = terms[:, 0]
    if (kinds == BANK).sum() != 1 or not np.all((kinds == BANK) | (kinds == 0.0)):
        return None
    a, d = terms[kinds == BANK][0, [2, 5]]
    u0, r_max = float(pose[0]), 201.0  # (ranges are cut at 200 m)
    if a < u0 < d or (u0 == a == d):
        side, align, low = 0, u0, BANK_MIN_RUN
    else:
        side, align = (1, a) if u0 <= a else (-1, d)
        low = min(max(abs(align - u0) / r_max, BANK_MIN_RUN), 0.5)  # (a bank out of range: every point reads the background)
    n = int(math.ceil(math.log(1.0 / low) / math.log(BANK_RATIO))) + 1
    runs = np.minimum(low * BANK_RATIO ** np.arange(n), 1.0)
    if side == 0:
        runs = np.r_[-runs[::-1], runs]
    background = float(terms[kinds == 0.0, 1].sum() + terms[kinds == BANK][0, 7])
    return side, float(align), runs, background


@njit(cache=True, inline="always")
def _bank_read(r0, du, side, dist, nodes, log_ratio, step, last):
    # The two curves a point reads (j, j + 1; j = len(nodes): the background's curve only), the weight of j + 1 and
    # the range node of each. Before or past the bank (side ±1) a curve is read at the point's range past the face:
    # k = (R0 − s + s_j)/step, s = dist / run the face's range on the point's ray, s_j the node's; a point whose ray
    # meets no face before it reads the background's curve at its range. Inside (side 0) the signed runs around du.
    n_nodes = nodes.shape[0]
    k0 = min(int(np.round(min(r0, 200.0) / step)), last)
    if side == 0:
        half = n_nodes // 2  # nodes: −runs reversed, then runs
        low = nodes[half]
        if abs(du) < low:
            return half - 1, (du + low) / (2.0 * low), k0, k0
        if du > 0.0:
            j = half + min(int(math.log(du / low) / log_ratio), half - 2)
        else:
            j = half - 2 - min(int(math.log(-du / low) / log_ratio), half - 2)
        return j, min(max((du - nodes[j]) / (nodes[j + 1] - nodes[j]), 0.0), 1.0), k0, k0
    g = side * du
    if g < nodes[0] or dist >= g * r0:
        return n_nodes, 0.0, k0, k0
    j = min(int(math.log(g / nodes[0]) / log_ratio), n_nodes - 2)
    face = dist / g
    k_j = min(max(int(np.round((r0 - face + dist / nodes[j]) / step)), 0), last)
    k_j1 = min(max(int(np.round((r0 - face + dist / nodes[j + 1]) / step)), 0), last)
    return j, min(max((g - nodes[j]) / (nodes[j + 1] - nodes[j]), 0.0), 1.0), k_j, k_j1


@njit(cache=True, parallel=True)
def _hahner_bank(pts, pose, terms, side, align, nodes, clear_outside, best, where, stops, step, log_noise, u, out,
                 attenuation):
    # Hahner et al. with one bank: each point's soft-return maximum interpolated between the curves of the two runs
    # around its own (_bank_read), its hard return exactly; then the rule (_field_rule). A point whose ray meets no
    # face before it sees the homogeneous background only: it reads the background's curve (the last), or is kept
    # as in clear air when there is no background (clear_outside).
    n_nodes = nodes.shape[0]
    last = best.shape[1] - 1
    dist = abs(align - pose[0])
    half = n_nodes // 2
    log_ratio = math.log(nodes[1] / nodes[0]) if side != 0 else math.log(nodes[half + 1] / nodes[half])
    none = np.zeros((0, 2))  # (_beam's general closed form)
    for n in prange(pts.shape[0]):
        x, y, z = np.float64(pts[n, 0]), np.float64(pts[n, 1]), np.float64(pts[n, 2])
        r0 = np.sqrt(x * x + y * y + z * z)
        du = (pose[2] * x + pose[3] * y + pose[4] * z) / max(r0, 1e-12)
        j, t, k_j, k_j1 = _bank_read(r0, du, side, dist, nodes, log_ratio, step, last)
        if j == n_nodes and clear_outside:  # no fog on the ray
            for c in range(pts.shape[1]):
                out[n, c] = pts[n, c]
            continue
        r0, du, dz, tau0, i_orig, i_hard = _beam(pts, n, pose, terms, out, none)
        if tau0 == 0.0:  # (kept as in clear air)
            continue
        j1 = min(j + 1, n_nodes)  # (the background's curve alone: weight 0)
        k_j, k_j1 = min(k_j, stops[j]), min(k_j1, stops[j1])
        f = (1.0 - t) * best[j, k_j] + t * best[j1, k_j1]
        near, kn = (j1, k_j1) if t >= 0.5 else (j, k_j)
        r_tmp = where[near, kn] * step
        if side != 0 and near < n_nodes:  # the maximum's range moves with the face (unless it lies before it)
            face, face_node = dist / (side * du), dist / nodes[near]
            if r_tmp >= face_node:
                r_tmp += face - face_node
        _field_rule(pts, n, out, r0, i_orig, i_hard, f, r_tmp, log_noise, u, attenuation)


@njit(cache=True, inline="always")
def _transmittance(trans, j, terms, u0, z0, du, dz, step):
    # E_j = e^{−2τ(j·step)} on the ray, cached in trans (−1: not yet computed)
    if trans[j] < 0.0:
        trans[j] = np.exp(-2.0 * segment_depth(terms, u0, z0, du, dz, j * step))
    return trans[j]


@njit(cache=True, inline="always")
def beam_soft_maximum(terms, u0, z0, du, dz, r0, weights, ramp, weights5, ramp5, coarse, step, beta_max):
    """The soft return's maximum ``max_{R ≤ R0} F(R)`` (s/m², with the backscatter) on a beam from ``(u0, z0)`` with
    unit-direction components ``du`` (along u) and ``dz`` (up) to range ``r0``, and the range node where it lies:
    ``E_j = e^{−2τ(jΔ)}`` on the ray, ``F_k = Σ_n W[k, n]·E_{k−n}`` (:func:`field_pulse_weights`) on coarse ranges every
    ``coarse`` nodes (their own weights ``weights5``), stopped by the bound, then on every node near the sensor (where
    1/R′² varies fast) and around the coarse maximum."""
    n_nodes = weights.shape[1]
    top = min(int(np.round(min(r0, 200.0) / step)), weights.shape[0] - 1)
    trans = np.full(top + 1, -1.0)  # E_j, computed when a window first needs it
    clear = _clear_node(terms, u0, z0, du, dz, step, top)
    one = int(np.round(XI_R2 / step))  # the node 1 m out, and the extinction there
    beta1 = point_extinction(terms, u0 + du * XI_R2, z0 + dz * XI_R2)
    near = 0.0 if one > top else _transmittance(trans, one, terms, u0, z0, du, dz, step)
    lift = beta1 * near * np.exp(beta1 * (XI_R2 - XI_R1))
    best5, best5_k, near5, near5_k = -1.0, -1, -1.0, -1  # the coarse maximum, and the one near the sensor
    for k5 in range((max(one, clear) + coarse - 1) // coarse, top // coarse + 1):
        if best5 > 0.0 and _soft_bound(k5 * coarse * step, beta_max) < 0.95 * best5:
            break  # no farther range can beat the maximum so far (a margin for the coarse weights)
        f = ramp5[k5] * lift
        for m in range(min(weights5.shape[1], k5 + 1)):
            f += weights5[k5, m] * _transmittance(trans, coarse * (k5 - m), terms, u0, z0, du, dz, step)
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
                f += weights[k, m] * _transmittance(trans, k - m, terms, u0, z0, du, dz, step)
            if f > best:
                best, best_k = f, k
    return best, best_k


@njit(cache=True)
def field_keeps(r0, intensity, terms, u0, z0, du, dz, weights, ramp, weights5, ramp5, beta_max):
    """Whether a return at range ``r0`` with CARLA intensity ``intensity`` ∈ [0, 1] on the beam ``(u0, z0, du, dz)``
    survives the fog field ``terms`` (``i_soft <= i_hard``): the decision :func:`fog_lidar_field` makes per point (CARLA
    intensities), for the perception kernels; the field's counterpart of ``fog_gym.fog.lidar.hahner_keeps``."""
    tau0 = segment_depth(terms, u0, z0, du, dz, r0)
    if tau0 == 0.0:
        return True
    i_orig = np.round(intensity * 255.0)
    i_hard = np.round(i_orig * np.exp(-2.0 * tau0))
    best, _ = beam_soft_maximum(terms, u0, z0, du, dz, r0, weights, ramp, weights5, ramp5, FIELD_COARSE, FIELD_STEP,
                                beta_max)  # fmt: skip
    return not min(255.0, best * i_orig * r0 * r0 * math.pi / GAMMA) > i_hard


@njit(cache=True, parallel=True)
def _hahner_field(pts, pose, terms, weights, ramp, weights5, ramp5, coarse, step, log_noise, u, out, attenuation,
                  beta_max):
    # pts (N, C) in the sensor frame; pose (8,): the sensor origin (u0, z0) in the field frame and the rows a_u, a_z
    # that turn a unit direction of the sensor frame into its run along u and up; terms a packed field
    # (fog_gym.fog.fields). Per point: τ(R0) in closed form, the soft return's maximum on its beam
    # (beam_soft_maximum); then Hahner et al.'s rule as _hahner.
    u0, z0 = pose[0], pose[1]
    none = np.zeros((0, 2))  # (_beam's general closed form)
    for n in prange(pts.shape[0]):
        r0, du, dz, tau0, i_orig, i_hard = _beam(pts, n, pose, terms, out, none)
        if tau0 == 0.0:  # no fog on the ray: no backscatter either, the point is kept as in clear air
            continue
        best, best_k = beam_soft_maximum(terms, u0, z0, du, dz, r0, weights, ramp, weights5, ramp5, coarse, step,
                                         beta_max)  # fmt: skip
        _field_rule(pts, n, out, r0, i_orig, i_hard, best, best_k * step, log_noise, u, attenuation)


def fog_lidar_field(points: np.ndarray, field, rng: np.random.Generator, pose: np.ndarray, time: float = 0.0,
                    noise: float = 10.0, reflectance: float | None = None) -> np.ndarray:  # fmt: skip
    """Hahner et al. fog with a fog field (:mod:`fog_gym.fog.fields`) on LiDAR points ``(N, 4+)`` → the same shape.

    The generalisation of :func:`fog_lidar` to a local extinction β(r) along each beam (``docs/fog.md``): the hard
    target keeps ``round(i·e^{−2τ(R0)})``, τ the optical depth to the point in closed form; the fog's soft return is
    ``i_soft = min(255, max_{R ≤ R0} F(R)·i·R0²·π/Γ)`` with ``F(R) = ∫ P(t)·κβ(R′)·e^{−2τ(R′)}·ξ(R′)/R′² dt``
    (:func:`field_pulse_weights`; with constant β this is Hahner et al.'s ``I(R0, α)·β``), on a range grid of
    :data:`FIELD_STEP`. The same replace rule and noise. ``pose`` places the LiDAR in the field frame
    (:func:`fog_gym.fog.depth.field_pose`); ``time`` [s] moves drifting banks. A homogeneous field goes through
    :func:`fog_lidar`.
    """
    if field.is_homogeneous:
        from fog_gym.fog.physics import parse_fog

        return fog_lidar(points, parse_fog(field.visibility_m) if not isinstance(field, FogLevel) else field, rng,
                         noise, reflectance)  # fmt: skip
    pts = _checked_points(points, noise)
    pose = np.asarray(pose, np.float64)
    if pose.shape != (8,) or not np.isfinite(pose).all():
        raise ValueError(f"pose must be field_pose(sensor_to_world, frame): 8 finite numbers, got {pose!r}")
    u = rng.uniform(-1.0, 1.0, len(pts))
    out = np.empty_like(pts)
    terms = field.pack(time)
    log_noise, attenuation = math.log(max(1.0, noise / 5.0)) if noise > 0 else 0.0, -1.0 if reflectance is None else float(reflectance)
    if BANK not in terms[:, 0] and len(pts):  # β depends on height only: one soft-return curve per beam elevation
        node_dz, first, lo_key, best, where, stops = _elevation_curves(pts, pose, terms)
        _hahner_curves(pts, pose, terms, _height_constants(terms, float(pose[1])), node_dz, first, lo_key,
                       ELEVATION_ROUND, best, where, stops, FIELD_STEP, log_noise, u, out, attenuation)  # fmt: skip
        return out
    plan = _bank_plan(terms, pose)
    if plan is not None and len(pts):  # one bank (in homogeneous fog or none): curves per run along u, face-aligned
        side, align, nodes, background = plan
        runs = nodes if side == 0 else np.r_[side * nodes, 0.0]  # (before or past: and the background's curve)
        # every curve up to 200 m: each stops where its bound does (stops), and a point reads it no farther
        tops = np.full(len(runs), int(round(200.0 / FIELD_STEP)), np.int64)
        best, where, stops = _curves(terms, pose, runs, np.zeros(len(runs)), tops)
        _hahner_bank(pts, pose, terms, side, align, nodes, background == 0.0, best, where, stops, FIELD_STEP,
                     log_noise, u, out, attenuation)  # fmt: skip
        return out
    _hahner_field(pts, pose, terms, *field_pulse_weights(), *field_pulse_weights(FIELD_STEP * FIELD_COARSE),
                  FIELD_COARSE, FIELD_STEP, log_noise, u, out, attenuation, peak_extinction(terms))  # fmt: skip
    return out


#: Beam elevations closer than this (the run up per metre) share one soft-return curve; past ELEVATION_NODES distinct
#: elevations the curves lie on a uniform grid and a point's maximum is interpolated between the two around it.
ELEVATION_ROUND, ELEVATION_NODES = 1e-4, 64


def peak_extinction(terms: np.ndarray) -> float:
    """An upper bound of a packed field's extinction anywhere [1/m]: the sum of its terms' peaks."""
    peak = 0.0
    for row in np.asarray(terms, np.float64):
        peak += row[1] if row[0] != BANK else row[7] + max(row[1], 0.0) * row[6]
    return float(peak)


def _elevation_curves(pts: np.ndarray, pose: np.ndarray, terms: np.ndarray) -> tuple[np.ndarray, ...]:
    """The soft-return curves of a height-only field per beam elevation (``node_dz``; ``first`` and ``lo_key``, its
    lookup by rounded elevation; ``best``, ``where``): a rig's
    beams have few elevations (64 for the FogDrive LiDAR), each of which gets its own curve; arbitrary points get a
    grid of :data:`ELEVATION_NODES`."""
    node_dz, tops, first, lo_key = _elevation_nodes(pts, pose, ELEVATION_ROUND, ELEVATION_NODES, FIELD_STEP,
                                                    int(round(200.0 / FIELD_STEP)))  # fmt: skip
    horizontal = np.sqrt(np.maximum(1.0 - node_dz**2, 0.0))  # (a height-only field ignores the run along u)
    best, where, stops = _curves(terms, pose, horizontal, node_dz, tops)
    return node_dz, first, lo_key, best, where, stops


def _curves(terms: np.ndarray, pose: np.ndarray, dus: np.ndarray, dzs: np.ndarray, tops: np.ndarray):
    """:func:`_soft_curves` of these beam directions: ``best``, ``where`` (each row written up to its ``stops``)."""
    weights, ramp = field_pulse_weights()
    best = np.empty((len(dus), int(tops.max(initial=0)) + 1))
    where = np.empty(best.shape, np.int64)
    stops = np.zeros(len(dus), np.int64)
    _soft_curves(terms, pose[0], pose[1], dus, dzs, tops, weights, ramp, FIELD_STEP, best, where, stops,
                 peak_extinction(terms))
    return best, where, stops

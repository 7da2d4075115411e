"""The LiDAR fog of a single fog bank (with homogeneous terms): soft-return curves per beam run along the bank's axis,
aligned on its face (:mod:`fog_gym.fog.lidar_field` calls :func:`fog_lidar_bank`)."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

import fog_gym._numba  # noqa: F401  (numba's fork-safe threading layer, before any kernel runs)
from fog_gym._numba import SERIAL_BELOW, pick, serial_twin
from fog_gym.fog.depth import BANK, _ramp
from fog_gym.fog.lidar_pulse import FIELD_STEP, _curves, _field_rule


#: A single fog bank's curves: beam runs along u (the bank's axis) on a geometric grid of this ratio, face-aligned (a
#: point reads the two runs around its own at the same range past the bank's face); inside a bank the runs go down to
#: ±BANK_MIN_RUN on both sides of 0.
BANK_RATIO, BANK_MIN_RUN = 1.05, 0.02


class _BankPlan(NamedTuple):
    """How the points of a field of one bank (and homogeneous terms) read their soft-return curves (:func:`_bank_plan`)."""

    side: int  #: +1 before the bank, −1 past it, 0 inside
    dist: float  #: the distance along u from the sensor to the face its beams meet (0 inside)
    nodes: np.ndarray  #: the runs of the curves (side·du > 0), signed inside
    background: float  #: the extinction outside the bank [1/m]
    lut: np.ndarray  #: per bin of width 1/`inv_width` above the shallowest positive run, the run node at or below it
    inv_width: float
    inv_gap: np.ndarray  #: 1 / (nodes[j + 1] − nodes[j])
    faces: np.ndarray  #: the face's range on each node's ray (before or past the bank), and 0 for the background's curve
    depth: np.ndarray  #: _bank_depth's constants


def _bank_plan(terms: np.ndarray, pose: np.ndarray) -> _BankPlan | None:
    """The plan of a field of one bank and homogeneous terms (None for any other field): ``side`` +1 where the sensor
    lies before the bank (the beams that reach it run along +u and meet its face ``dist`` metres along u), −1 past it,
    0 inside it (every beam starts in fog; ``nodes`` the signed runs); else ``nodes`` the runs ``side·du`` > 0 of the
    curves, from the shallowest whose ray meets the face within the points' range."""
    kinds = terms[:, 0]
    if (kinds == BANK).sum() != 1 or not np.all((kinds == BANK) | (kinds == 0.0)):
        return None
    bank = terms[kinds == BANK][0]
    a, d = bank[[2, 5]]
    u0, r_max = float(pose[0]), 201.0  # (ranges are cut at 200 m)
    if a < u0 < d or (u0 == a == d):
        side, dist, low = 0, 0.0, BANK_MIN_RUN
    else:
        side, dist = (1, float(a) - u0) if u0 <= a else (-1, u0 - float(d))
        low = min(max(dist / r_max, BANK_MIN_RUN), 0.5)  # (a bank out of range: every point reads the background)
    nodes, lut, inv_width, inv_gap, faces = _run_tables(low, side, dist, BANK_RATIO)
    homogeneous = float(terms[kinds == 0.0, 1].sum())
    db, a, b, c, d, p, bg = bank[1:8]
    h_ab, h_dc = (0.5 / (b - a) if b > a else 0.0), (0.5 / (d - c) if d > c else 0.0)
    depth = np.array([homogeneous + bg, db, a, b, c, d, p, h_ab, h_dc, 0.0])
    depth[9] = _bank_integral(u0, depth)
    return _BankPlan(side, dist, nodes, homogeneous + float(bg), lut, inv_width, inv_gap, faces, depth)


@njit(cache=True, nogil=True)
def _run_tables(low, side, dist, ratio):
    # A bank plan's runs from `low` to 1 (geometric, of this ratio; the last cut at 1) and their lookup: the nodes
    # (signed inside: −runs reversed, then runs), per bin of the narrowest gap above `low` the run at or below the
    # bin's start (the bins' inverse width), 1 / each gap of the nodes, and before or past the bank the face's range on
    # each run's ray (then 0, the background's curve).
    n = int(math.ceil(math.log(1.0 / low) / math.log(ratio))) + 1
    runs = np.empty(n)
    for i in range(n):
        runs[i] = min(low * ratio**i, 1.0)
    width = low * (ratio - 1.0)  # (a bin holds at most one node, but for the last, cut at 1)
    lut = np.empty(int(math.ceil((1.0 - low) / width)) + 1, np.int64)
    i = 0
    for b in range(lut.shape[0]):
        while i + 1 < n and runs[i + 1] <= low + width * b:
            i += 1
        lut[b] = min(i, n - 2)
    nodes = np.concatenate((-runs[::-1], runs)) if side == 0 else runs
    faces = np.empty(n + 1 if side != 0 else 0)
    for i in range(faces.shape[0] - 1):
        faces[i] = dist / runs[i]
    if side != 0:
        faces[n] = 0.0
    return nodes, lut, 1.0 / width, 1.0 / (nodes[1:] - nodes[:-1]), faces


@njit(cache=True, inline="always")
def _bank_integral(u, depth):
    # ∫_{−∞}^{u} w of the bank's trapezoid (depth: _BankPlan.depth; fog_gym.fog.depth._ramp_integral with its
    # divisions done once)
    a, b, c, d = depth[2], depth[3], depth[4], depth[5]
    x = min(max(u, a), b) - a
    y = min(max(u, c), d) - c
    return depth[6] * (x * x * depth[7] + (min(max(u, b), c) - b) + (y - y * y * depth[8]))


@njit(cache=True, inline="always")
def _bank_depth(depth, u0, run, length):
    # τ from the sensor (at u0) along a beam `length` metres long that runs `run` metres along u: (β_hom + β_bg)·L +
    # Δβ·L·∫w du / run (segment_depth of one bank and homogeneous terms, with the constants of the frame: depth[9] = ∫w up
    # to u0)
    if abs(run) < 1e-6:
        return (depth[0] + depth[1] * _ramp(u0 + 0.5 * run, depth[2], depth[3], depth[4], depth[5], depth[6])) * length
    return (depth[0] + depth[1] * (_bank_integral(u0 + run, depth) - depth[9]) / run) * length


@njit(cache=True, inline="always")
def _run_node(g, nodes, off, count, lut, inv_width):
    # i ∈ [0, count − 2] with nodes[off + i] ≤ g < nodes[off + i + 1] among `count` geometric runs from nodes[off] ≤ g:
    # the table's node for g's bin, and a step up where g lies past the next node (no branch: a bin is no wider than
    # the gaps, but for the last, cut at 1)
    i = lut[min(int((g - nodes[off]) * inv_width), lut.shape[0] - 1)]
    i = min(i + int(nodes[off + i + 1] <= g), count - 2)
    while i < count - 2 and nodes[off + i + 1] <= g:
        i += 1
    return i


@njit(cache=True, inline="always")
def _bank_read(r0, du, side, dist, nodes, lut, inv_width, inv_gap, faces, step, last):
    # The two curves a point reads (j, j + 1; j = len(nodes): the background's curve only), the weight of j + 1, the
    # range node of each, and the face's range on the point's ray (before or past the bank). Before or past it (side
    # ±1) a curve is read at the point's range past the face: k = (R0 − s + s_j)/step, s = dist / run the face's range
    # on the point's ray, s_j the node's; a point whose ray meets no face before it reads the background's curve at its
    # range. Inside (side 0) the signed runs around du.
    n_nodes = nodes.shape[0]
    k0 = min(int(np.round(min(r0, 200.0) * (1.0 / step))), last)
    if side == 0:
        half = n_nodes // 2  # nodes: −runs reversed, then runs
        low = nodes[half]
        if abs(du) < low:
            return half - 1, (du + low) / (2.0 * low), k0, k0, 0.0
        i = _run_node(abs(du), nodes, half, half, lut, inv_width)
        j = half + i if du > 0.0 else half - 2 - i
        return j, min(max((du - nodes[j]) * inv_gap[j], 0.0), 1.0), k0, k0, 0.0
    g = side * du
    if g < nodes[0] or dist >= g * r0:
        return n_nodes, 0.0, k0, k0, 0.0
    j = _run_node(g, nodes, 0, n_nodes, lut, inv_width)
    face = dist / g
    k_j = min(max(int(np.round((r0 - face + faces[j]) * (1.0 / step))), 0), last)
    k_j1 = min(max(int(np.round((r0 - face + faces[j + 1]) * (1.0 / step))), 0), last)
    return j, min(max((g - nodes[j]) * inv_gap[j], 0.0), 1.0), k_j, k_j1, face


@njit(cache=True, nogil=True, parallel=True)
def _hahner_bank(pts, pose, side, dist, nodes, lut, inv_width, inv_gap, faces, depth, row, uniform, clear_outside, best,
                 where, stops, step, log_noise, u, out, attenuation):  # fmt: skip
    # Hahner et al. with one bank: per point τ in closed form (_bank_depth), the soft return's maximum interpolated
    # between the curves of the two runs around its own (_bank_read; row: each node's curve; uniform: all nodes read
    # row 0), then the rule (_field_rule). A point whose ray meets no face before it sees the homogeneous background
    # only: it reads the background's curve (the last), or is kept as in clear air when there is no background
    # (clear_outside).
    n_nodes = nodes.shape[0]
    last = best.shape[1] - 1
    for n in prange(pts.shape[0]):
        x, y, z = np.float64(pts[n, 0]), np.float64(pts[n, 1]), np.float64(pts[n, 2])
        r0 = np.sqrt(x * x + y * y + z * z)
        run = pose[2] * x + pose[3] * y + pose[4] * z  # (along u)
        if uniform:  # every node reads one curve
            k0 = min(int(np.round(min(r0, 200.0) * (1.0 / step))), last)
            j, t, k_j, k_j1, face = 0, 0.0, k0, k0, 0.0
        else:
            j, t, k_j, k_j1, face = _bank_read(r0, run * (1.0 / max(r0, 1e-12)), side, dist, nodes, lut, inv_width,
                                               inv_gap, faces, step, last)  # fmt: skip
        tau0 = 0.0 if j == n_nodes and clear_outside else _bank_depth(depth, pose[0], run, r0)
        if tau0 == 0.0:  # no fog on the ray: kept as in clear air
            for c in range(pts.shape[1]):
                out[n, c] = pts[n, c]
            continue
        i_orig = np.round(np.float64(pts[n, 3]) * 255.0)
        i_hard = np.round(i_orig * np.exp(-2.0 * tau0))
        j1 = min(j + 1, n_nodes)  # (the background's curve alone: weight 0)
        rj, rj1 = row[j], row[j1]
        k_j, k_j1 = min(k_j, stops[rj]), min(k_j1, stops[rj1])
        f = (1.0 - t) * best[rj, k_j] + t * best[rj1, k_j1]
        near, kn = (j1, k_j1) if t >= 0.5 else (j, k_j)
        r_tmp = where[row[near], kn] * step
        if side != 0 and near < n_nodes and r_tmp >= faces[near]:  # the maximum's range moves with the face (unless
            r_tmp += face - faces[near]  # it lies before it)
        scale, value = _field_rule(np.float64(pts[n, 3]), r0, i_orig, i_hard, f, r_tmp, log_noise, u[n],
                                   attenuation)  # fmt: skip
        for c in range(pts.shape[1]):  # (written here: numba counted references to arrays a helper writes to)
            out[n, c] = np.float32(np.float64(pts[n, c]) * scale) if c < 3 else (value if c == 3 else pts[n, c])


_hahner_bank_serial = serial_twin(_hahner_bank)


def _bank_curves(terms: np.ndarray, pose: np.ndarray, plan: _BankPlan, points: int = SERIAL_BELOW):
    """The curves of a bank's plan: ``best``, ``where``, ``stops`` and per node (and the background's, before or past
    the bank) its row. Inside the bank's plateau, a beam that stays on it up to its curve's last node sees homogeneous
    fog there: the curve of the beam across the bank (run 0) serves every run that shallow. ``points``, the sweep's
    size, picks the curves' kernel (``_curves``)."""
    top = int(round(200.0 / FIELD_STEP))
    if plan.side != 0:
        runs = np.r_[plan.side * plan.nodes, 0.0]
        return (*_curves(terms, pose, runs, np.zeros(len(runs)), np.full(len(runs), top, np.int64), points=points),
                np.arange(len(runs)))  # fmt: skip
    runs, u0 = plan.nodes, float(pose[0])
    b, c = plan.depth[3], plan.depth[4]
    row = np.zeros(len(runs) + 1, np.int64)
    if b <= u0 <= c:  # (on the plateau)
        across = _curves(terms, pose, np.zeros(1), np.zeros(1), np.full(1, top, np.int64), points=points)
        reach = (int(across[2][0]) + 1) * FIELD_STEP
        own = np.flatnonzero(np.abs(runs) * reach > min(u0 - b, c - u0))
        if not len(own):
            return (*across, row)
    else:
        own = np.arange(len(runs))
    best, where, stops = _curves(terms, pose, np.r_[0.0, runs[own]], np.zeros(len(own) + 1),
                                 np.full(len(own) + 1, top, np.int64), points=points)  # fmt: skip
    row[own] = np.arange(1, len(own) + 1)
    return best, where, stops, row


def fog_lidar_bank(pts: np.ndarray, terms: np.ndarray, pose: np.ndarray, log_noise: float, u: np.ndarray,
                   out: np.ndarray, attenuation: float) -> bool:
    """Hahner et al. with a packed field of one bank and homogeneous terms on ``pts`` (N ≥ 1) into ``out``; False (and
    nothing written) for any other field."""
    plan = _bank_plan(terms, pose)
    if plan is None:
        return False
    best, where, stops, row = _bank_curves(terms, pose, plan, len(pts))
    pick(_hahner_bank, _hahner_bank_serial, len(pts))(
        pts, pose, plan.side, plan.dist, plan.nodes, plan.lut, plan.inv_width, plan.inv_gap, plan.faces, plan.depth, row,
        not row.any(), plan.background == 0.0, best, where, stops, FIELD_STEP, log_noise, u, out, attenuation)
    return True

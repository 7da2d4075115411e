"""The LiDAR fog of a field whose β depends on height only (ground fog, with homogeneous terms): one soft-return curve
per beam elevation (:mod:`fog_gym.fog.lidar_field` calls :func:`fog_lidar_height`)."""

from __future__ import annotations

import numba
import numpy as np
from numba import njit, prange

import fog_gym._numba  # noqa: F401  (numba's fork-safe threading layer, before any kernel runs)
from fog_gym._numba import pick, serial_twin
from fog_gym.fog.depth import origin_constants, origin_depth
from fog_gym.fog.lidar_pulse import FIELD_STEP, _curves, _field_rule


#: Beam elevations closer than this (the run up per metre) share one soft-return curve; past ELEVATION_NODES distinct
#: elevations the curves lie on a uniform grid and a point's maximum is interpolated between the two around it.
ELEVATION_ROUND, ELEVATION_NODES = 1e-4, 64
#: The elevations' keys (rounded) lie in ±ELEVATION_KEYS.
ELEVATION_KEYS = int(round(1.0 / ELEVATION_ROUND))


@njit(cache=True, nogil=True, parallel=True)
def _beam_elevations(pts, pose, terms, consts, step, last, dzs, ks, keys, tau, spans, present):
    # Per point: its beam's elevation (run up per metre), its range node, the elevation rounded to ELEVATION_ROUND (its
    # key) and τ to it in closed form (origin_depth, with the sensor's constants). Per chunk c of the
    # points (spans and present have a row per chunk): the least and greatest key and elevation and the farthest range
    # node, and which keys occur (present[c, key + ELEVATION_KEYS]).
    n, chunks = pts.shape[0], spans.shape[0]
    for c in prange(chunks):
        lo_key, hi_key, low, high, top = ELEVATION_KEYS, -ELEVATION_KEYS, np.inf, -np.inf, 0
        for i in range(c * n // chunks, (c + 1) * n // chunks):
            x, y, z = np.float64(pts[i, 0]), np.float64(pts[i, 1]), np.float64(pts[i, 2])
            r0 = np.sqrt(x * x + y * y + z * z)
            dz = (pose[5] * x + pose[6] * y + pose[7] * z) * (1.0 / max(r0, 1e-12))
            key = min(max(int(np.round(dz * ELEVATION_KEYS)), -ELEVATION_KEYS), ELEVATION_KEYS)  # (· 1/ELEVATION_ROUND)
            k = min(int(np.round(min(r0, 200.0) * (1.0 / step))), last)
            dzs[i], ks[i], keys[i] = dz, k, key
            present[c, key + ELEVATION_KEYS] = 1
            tau[i] = origin_depth(terms, consts, 0.0, pose[1], 0.0, dz, r0)
            lo_key, hi_key, low, high, top = min(lo_key, key), max(hi_key, key), min(low, dz), max(high, dz), max(top, k)
        spans[c, 0], spans[c, 1], spans[c, 2], spans[c, 3], spans[c, 4] = lo_key, hi_key, low, high, top


_beam_elevations_serial = serial_twin(_beam_elevations)


@njit(cache=True, nogil=True)
def _elevation_nodes(spans, present, most):
    # The beam elevations of the points (_beam_elevations), rounded to ELEVATION_ROUND, when there are at most `most`
    # of them; else a uniform grid of `most` over their span (and 1 / its spacing, 0 for the elevations). Every node's
    # curve reaches the points' farthest range node (the soft-return bound stops it far sooner in fog).
    lo_key, hi_key = int(spans[:, 0].min()), int(spans[:, 1].max())
    low, high, top = spans[:, 2].min(), spans[:, 3].max(), int(spans[:, 4].max())
    keys = np.zeros(hi_key - lo_key + 1, np.bool_)
    for c in range(present.shape[0]):
        for key in range(lo_key, hi_key + 1):
            keys[key - lo_key] |= present[c, key + ELEVATION_KEYS] != 0
    count = int(keys.sum())
    if count <= most:  # a node per elevation, which reads its own points only
        nodes = np.empty(count)
        j = 0
        for key in range(keys.shape[0]):
            if keys[key]:
                nodes[j] = (key + lo_key) * ELEVATION_ROUND
                j += 1
        spacing = 0.0
    else:
        nodes = np.linspace(low, high, most)
        spacing = (most - 1) / (high - low) if high > low else 0.0
    return nodes, np.full(nodes.shape[0], top, np.int64), \
        _first_at_or_above(nodes, lo_key, keys.shape[0], ELEVATION_ROUND), lo_key, spacing  # fmt: skip


@njit(cache=True, nogil=True)
def _first_at_or_above(nodes, lo_key, keys, rounding):
    # per rounded elevation key (lo_key + c), the first node at or above (key − ½)·rounding: a point's searchsorted in
    # one read and at most one step (_hahner_height)
    first = np.empty(keys, np.int64)
    j = 0
    for c in range(keys):
        while j < nodes.shape[0] and nodes[j] < (lo_key + c - 0.5) * rounding:
            j += 1
        first[c] = j
    return first


@njit(cache=True, nogil=True, parallel=True)
def _hahner_height(pts, tau, dzs, ks, keys, node_dz, first, lo_key, inv_spacing, best, where, stops, step, log_noise, u,
                   out, attenuation):  # fmt: skip
    # Hahner et al. with a field whose β depends on height only, given each point's τ, elevation, range node and
    # elevation key (_beam_elevations): its soft return's maximum from the curves of the two beam elevations around
    # its own (node_dz ascending, a uniform grid where inv_spacing > 0; linear in dz, the range of the nearer), then the
    # rule (_field_rule); a point without fog on its ray (τ = 0) is kept as in clear air.
    n_nodes = node_dz.shape[0]
    for n in prange(pts.shape[0]):
        tau0 = tau[n]
        if tau0 == 0.0:
            for c in range(pts.shape[1]):
                out[n, c] = pts[n, c]
            continue
        dz, k = dzs[n], ks[n]
        if inv_spacing > 0.0:  # a uniform grid
            cell = (dz - node_dz[0]) * inv_spacing
            lo = min(max(int(cell), 0), n_nodes - 2)
            hi, t = lo + 1, min(max(cell - lo, 0.0), 1.0)
        else:  # the points' own elevations
            hi = first[min(max(keys[n] - lo_key, 0), first.shape[0] - 1)]
            while hi < n_nodes and node_dz[hi] < dz:  # (searchsorted: the first node at or above dz)
                hi += 1
            hi = min(max(hi, 1), n_nodes - 1) if n_nodes > 1 else 0
            lo = max(hi - 1, 0)
            span = node_dz[hi] - node_dz[lo]
            t = min(max((dz - node_dz[lo]) / span, 0.0), 1.0) if span > 0.0 else 0.0
        soft = (1.0 - t) * best[lo, min(k, stops[lo])] + t * best[hi, min(k, stops[hi])]
        near = hi if t >= 0.5 else lo
        x, y, z = np.float64(pts[n, 0]), np.float64(pts[n, 1]), np.float64(pts[n, 2])
        i_orig = np.round(np.float64(pts[n, 3]) * 255.0)
        i_hard = np.round(i_orig * np.exp(-2.0 * tau0))
        r0, r_tmp = np.sqrt(x * x + y * y + z * z), where[near, min(k, stops[near])] * step
        scale, value = _field_rule(np.float64(pts[n, 3]), r0, i_orig, i_hard, soft, r_tmp, log_noise, u[n],
                                   attenuation)  # fmt: skip
        for c in range(pts.shape[1]):  # (written here: numba counted references to arrays a helper writes to)
            out[n, c] = np.float32(np.float64(pts[n, c]) * scale) if c < 3 else (value if c == 3 else pts[n, c])


_hahner_height_serial = serial_twin(_hahner_height)


def fog_lidar_height(pts: np.ndarray, terms: np.ndarray, pose: np.ndarray, log_noise: float, u: np.ndarray,
                     out: np.ndarray, attenuation: float) -> None:
    """Hahner et al. with a packed field of height and homogeneous terms on ``pts`` (N ≥ 1) into ``out``: τ to each
    point in closed form, its soft return's maximum from the curves of the two beam elevations around its own, the
    rule (``fog_gym.fog.lidar_field.fog_lidar_field``'s arguments)."""
    n, chunks = len(pts), numba.get_num_threads()
    dzs, tau = np.empty((2, n))
    ks, keys = np.empty(n, np.int64), np.empty(n, np.int64)
    spans, present = np.empty((chunks, 5)), np.zeros((chunks, 2 * ELEVATION_KEYS + 1), np.uint8)
    consts = origin_constants(terms, 0.0, float(pose[1]))
    pick(_beam_elevations, _beam_elevations_serial, n)(pts, pose, terms, consts, FIELD_STEP,
                                                       int(round(200.0 / FIELD_STEP)), dzs, ks, keys, tau, spans, present)
    node_dz, tops, first, lo_key, inv_spacing = _elevation_nodes(spans, present, ELEVATION_NODES)
    horizontal = np.sqrt(np.maximum(1.0 - node_dz**2, 0.0))  # (a height-only field ignores the run along u)
    best, where, stops = _curves(terms, pose, horizontal, node_dz, tops, consts, n)  # (u0 is moot: no bank here)
    pick(_hahner_height, _hahner_height_serial, n)(pts, tau, dzs, ks, keys, node_dz, first, lo_key, inv_spacing, best,
                                                   where, stops, FIELD_STEP, log_noise, u, out, attenuation)

"""The LiDAR fog of any other field — sums of banks, ground fog under a bank — from soft-return curves on a grid of
beam directions, each point checked against its neighbours' and integrated on its own where they disagree
(:mod:`fog_gym.fog.lidar_field` calls :func:`fog_lidar_grid`).

A field's extinction depends on the run along its axis ``u`` and the height ``z``, so a beam's soft return depends on
its direction only through ``du`` (its run along ``u`` per metre) and ``dz`` (its rise per metre). The points'
directions span a small rectangle of that plane: a grid of directions over it (:func:`grid_shape`: about one node
per :data:`POINTS_PER_NODE` points, 16 × 4 or 16 × 8 for a field with height terms, 16 × 1 up to 64 × 1 without),
each with the running maximum of its soft return over the range nodes up to the
farthest point that reads it (a node no point reads costs nothing; :func:`fog_gym.fog.lidar_pulse._curves`). A
point reads the curves of the grid cell around its direction at its range: when the cell's corners all make the
same decision (fog return or hard target), the point takes it, with the soft return interpolated in the cell and,
for a fog return, the range of the nearest corner's maximum (where two banks' faces hold nearly equal maxima, it
may lie at the other face than the point's own beam puts it: a few metres, well within the model's range noise);
where they disagree — near a bank's face, where the maximum jumps with the direction — the point's own beam is
integrated (``beam_soft_maximum``, the per-beam path). The decisions are the per-beam path's (tested on random
scenes and fields); the cost is the grid's curves plus the few points near a face.

Example:
    >>> from fog_gym.fog.fields import FogBank
    >>> from fog_gym.fog.depth import field_pose
    >>> pts = np.array([[30.0, 0, 0, 0.5], [120.0, 0, 0, 0.5]], np.float32)
    >>> out = np.empty_like(pts)
    >>> n_exact = fog_lidar_grid(pts, (FogBank(20.0, 60.0, 30.0) + FogBank(90.0, 100.0, 40.0)).pack(0.0),
    ...                          field_pose(np.eye(4), (0, 0, 0)), 0.0, np.zeros(2), out, -1.0)
    >>> out[0].tolist() == pts[0].tolist(), bool(50.0 < out[1, 0] < 70.0)  # kept before the first bank; behind: its face
    (True, True)
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

import fog_gym._numba  # noqa: F401  (numba's fork-safe threading layer, before any kernel runs)
from fog_gym._numba import pick, serial_twin
from fog_gym.fog.depth import origin_constants, origin_depth
from fog_gym.fog.lidar import GAMMA, REFERENCE_REFLECTIVITY
from fog_gym.fog.lidar_pulse import (FIELD_COARSE, FIELD_STEP, _curves, _field_rule, beam_soft_maximum,
                                     field_pulse_weights, peak_extinction)  # fmt: skip

#: Points per grid node :func:`grid_shape` aims at: a curve costs about what 40 points' own reading of the grid does.
POINTS_PER_NODE = 40
#: The grids (nodes along ``du``, along ``dz``) :func:`grid_shape` chooses from, coarsest first, for fields with and
#: without height terms. With height terms the soft return's maximum follows the rise ``dz`` (ground fog near the
#: sensor, a bank's face above it) and 16 nodes along ``du`` give what 64 do (the same output bit for bit on 100 000
#: points of the three fields with height terms of the grid test; the curves a quarter); without them a bank's face is
#: where the maximum moves, and two banks' faces hold nearly equal maxima along a line of directions whose points may
#: take the other face's range (up to 3.4 m with 64 nodes, 6.3 m with 32, 16 m with 16, on 100 000 points).
_LADDER = {True: ((16, 4), (16, 8)), False: ((16, 1), (32, 1), (64, 1))}


def grid_shape(n_points: int, heights: bool) -> tuple[int, int]:
    """Nodes along ``du`` and ``dz`` for a sweep of ``n_points`` points: the finest grid of the ladder with no more
    than one node per :data:`POINTS_PER_NODE` points (the coarsest one below that). A coarser grid leaves more cells
    whose corners disagree (their points integrated on their own beam, with the same decisions), so a small sweep —
    an RL agent's 5 000 points — reads 64 curves where 100 000 points read 128 (:data:`_LADDER`).

    >>> grid_shape(5_000, True), grid_shape(100_000, True), grid_shape(100_000, False), grid_shape(10, True)
    ((16, 4), (16, 8), (64, 1), (16, 4))
    """
    ladder = _LADDER[bool(heights)]
    fits = [s for s in ladder if s[0] * s[1] * POINTS_PER_NODE <= n_points]
    return fits[-1] if fits else ladder[0]
#: Height terms of a packed field (fog_gym.fog.fields): a field without them depends on ``u`` only.
HEIGHT = 1.0


@njit(cache=True, nogil=True, parallel=True)
def _directions(pts, pose, step, last, r0s, dus, dzs, ks, spans):
    # Per point: range, run along u and rise per metre and range node; per chunk of the points (a row of spans): the
    # least and greatest run and rise.
    n, chunks = pts.shape[0], spans.shape[0]
    for c in prange(chunks):
        lo_u, hi_u, lo_z, hi_z = np.inf, -np.inf, np.inf, -np.inf
        for i in range(c * n // chunks, (c + 1) * n // chunks):
            x, y, z = np.float64(pts[i, 0]), np.float64(pts[i, 1]), np.float64(pts[i, 2])
            r0 = np.sqrt(x * x + y * y + z * z)
            inv = 1.0 / max(r0, 1e-12)
            du = (pose[2] * x + pose[3] * y + pose[4] * z) * inv
            dz = (pose[5] * x + pose[6] * y + pose[7] * z) * inv
            k = min(int(np.round(min(r0, 200.0) * (1.0 / step))), last)
            r0s[i], dus[i], dzs[i], ks[i] = r0, du, dz, k
            lo_u, hi_u, lo_z, hi_z = min(lo_u, du), max(hi_u, du), min(lo_z, dz), max(hi_z, dz)
        spans[c, 0], spans[c, 1], spans[c, 2], spans[c, 3] = lo_u, hi_u, lo_z, hi_z


_directions_serial = serial_twin(_directions)


@njit(cache=True, inline="always")
def _cell(du, dz, du0, du_inv, n_du, dz0, dz_inv, n_dz):
    # The grid cell around a direction: its lower corner's indices along du and dz and the position within the cell.
    a = min(max((du - du0) * du_inv, 0.0), n_du - 1.0)
    ia = min(int(a), n_du - 2) if n_du > 1 else 0
    b = min(max((dz - dz0) * dz_inv, 0.0), n_dz - 1.0)
    ib = min(int(b), n_dz - 2) if n_dz > 1 else 0
    return ia, (a - ia if n_du > 1 else 0.0), ib, (b - ib if n_dz > 1 else 0.0)


@njit(cache=True, nogil=True, parallel=True)
def _node_tops(dus, dzs, ks, du0, du_inv, n_du, dz0, dz_inv, n_dz, tops):
    # Per chunk of the points (a row of tops) and grid node, the farthest range node of the points whose cell it is a
    # corner of (0 where none); the caller takes the greatest over the chunks. The curves need go no farther (a
    # curve's values up to a range do not depend on how far it goes), and a node no point reads costs nothing.
    # Each point updates its cell's maximum (indexed by the cell's lower corner), each cell then its corners: the
    # same maxima as every point updating its four corners, with one scattered write a point instead of four.
    n, chunks, nodes = dus.shape[0], tops.shape[0], tops.shape[1]
    for c in prange(chunks):
        cells = np.zeros(nodes, np.int64)
        for m in range(c * n // chunks, (c + 1) * n // chunks):
            ia, _, ib, _ = _cell(dus[m], dzs[m], du0, du_inv, n_du, dz0, dz_inv, n_dz)
            i = ib * n_du + ia
            cells[i] = max(cells[i], ks[m])
        for i in range(nodes):
            ia, ib = i % n_du, i // n_du
            for q in range(4):
                da, db = q & 1, q >> 1
                if (da and n_du == 1) or (db and n_dz == 1) or ia + da >= n_du or ib + db >= n_dz:
                    continue
                j = (ib + db) * n_du + ia + da
                tops[c, j] = max(tops[c, j], cells[i])


_node_tops_serial = serial_twin(_node_tops)


@njit(cache=True, inline="always")
def _i_soft(best, i_orig, r0, ratio):
    return min(255.0, best * i_orig * r0 * r0 * ratio)


@njit(cache=True, nogil=True, parallel=True)
def _hahner_grid(pts, pose, terms, consts, r0s, dus, dzs, ks, du0, du_inv, n_du, dz0, dz_inv, n_dz, best, where,
                 stops, weights, ramp, weights5, ramp5, coarse, step, beta_max, log_noise, u, out, attenuation,
                 exact):  # fmt: skip
    # Each point from its grid cell's four curves where their decisions agree, else from its own beam (exact[n] = 1).
    for n in prange(pts.shape[0]):
        r0 = r0s[n]
        tau0 = origin_depth(terms, consts, pose[0], pose[1], dus[n], dzs[n], r0)
        if tau0 == 0.0:  # no fog on the ray: the point as in clear air
            for c in range(pts.shape[1]):
                out[n, c] = pts[n, c]
            continue
        k = ks[n]
        i_orig = np.round(np.float64(pts[n, 3]) * 255.0)
        i_hard = np.round(i_orig * np.exp(-2.0 * tau0))
        ratio = np.pi / GAMMA
        if attenuation >= 0.0:
            rho = min(max(np.float64(pts[n, 3]) / np.exp(-attenuation * r0), 1e-3), 1.0)
            ratio = ratio * REFERENCE_REFLECTIVITY / rho
        ia, ta, ib, tb = _cell(dus[n], dzs[n], du0, du_inv, n_du, dz0, dz_inv, n_dz)
        soft = 0.0
        wins = 0
        corners = 0
        near, near_w = -1, -1.0
        for q in range(4):
            da, db = q & 1, q >> 1
            if (da and n_du == 1) or (db and n_dz == 1):
                continue
            i = (ib + db) * n_du + ia + da
            kk = min(k, stops[i])
            v = best[i, kk]
            w = (ta if da else 1.0 - ta) * (tb if db else 1.0 - tb)
            soft += w * v
            corners += 1
            if _i_soft(v, i_orig, r0, ratio) > i_hard:
                wins += 1
            if w > near_w:
                near, near_w = i, w
        if wins == 0 or wins == corners:  # the cell agrees: its interpolated soft return decides as each corner does
            r_tmp = where[near, min(k, stops[near])] * step
        else:  # near a face: the point's own beam (the per-beam path)
            soft, kk = beam_soft_maximum(terms, pose[0], pose[1], dus[n], dzs[n], r0, weights, ramp, weights5, ramp5,
                                         coarse, step, beta_max)  # fmt: skip
            r_tmp = kk * step
            exact[n] = 1
        scale, value = _field_rule(np.float64(pts[n, 3]), r0, i_orig, i_hard, soft, r_tmp, log_noise, u[n],
                                   attenuation)  # fmt: skip
        for c in range(pts.shape[1]):  # (written here: numba counted references to arrays a helper writes to)
            out[n, c] = np.float32(np.float64(pts[n, c]) * scale) if c < 3 else (value if c == 3 else pts[n, c])


_hahner_grid_serial = serial_twin(_hahner_grid)


def fog_lidar_grid(pts: np.ndarray, terms: np.ndarray, pose: np.ndarray, log_noise: float, u: np.ndarray,
                   out: np.ndarray, attenuation: float) -> int:
    """Hahner et al. with any packed field on ``pts`` into ``out`` (``fog_gym.fog.lidar_field.fog_lidar_field``'s
    arguments): the module docstring's grid of curves; returns how many points were integrated on their own beam."""
    import numba

    n = len(pts)
    last = int(round(200.0 / FIELD_STEP))
    r0s, dus, dzs = np.empty((3, n))
    ks = np.empty(n, np.int64)
    spans = np.empty((max(1, min(numba.get_num_threads(), n)), 4))
    pick(_directions, _directions_serial, n)(pts, pose, FIELD_STEP, last, r0s, dus, dzs, ks, spans)
    du_lo, du_hi = float(spans[:, 0].min()), float(spans[:, 1].max())
    heights = bool(np.any(terms[:, 0] == HEIGHT))
    shape = grid_shape(n, heights)
    n_du = shape[0] if du_hi > du_lo else 1
    dz_lo, dz_hi = (float(spans[:, 2].min()), float(spans[:, 3].max())) if heights else (0.0, 0.0)
    n_dz = shape[1] if heights and dz_hi > dz_lo else 1
    grid_du = np.linspace(du_lo, du_hi, n_du)
    grid_dz = np.linspace(dz_lo, dz_hi, n_dz) if heights else np.zeros(1)
    node_du = np.tile(grid_du, n_dz)
    node_dz = np.repeat(grid_dz, n_du)
    cell = (du_lo, (n_du - 1) / (du_hi - du_lo) if n_du > 1 else 0.0, n_du, dz_lo,
            (n_dz - 1) / (dz_hi - dz_lo) if n_dz > 1 else 0.0, n_dz)  # fmt: skip
    tops = np.zeros((len(spans), len(node_du)), np.int64)
    pick(_node_tops, _node_tops_serial, n)(dus, dzs, ks, *cell, tops)
    tops = tops.max(axis=0)
    consts = origin_constants(terms, float(pose[0]), float(pose[1]))
    best, where, stops = _curves(terms, pose, node_du, node_dz, tops, consts, n)
    weights, ramp = field_pulse_weights()
    weights5, ramp5 = field_pulse_weights(FIELD_STEP * FIELD_COARSE)
    exact = np.zeros(n, np.uint8)
    pick(_hahner_grid, _hahner_grid_serial, n)(pts, pose, terms, consts, r0s, dus, dzs, ks, *cell, best, where, stops,
                                               weights, ramp, weights5, ramp5, FIELD_COARSE, FIELD_STEP,
                                               peak_extinction(terms), log_noise, u, out, attenuation, exact)
    return int(exact.sum())

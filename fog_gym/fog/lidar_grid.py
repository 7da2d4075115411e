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
integrated (``beam_soft_maximum_from``, the per-beam path's integration). The decisions are the per-beam path's (tested
on random scenes and fields); the cost is the grid's curves plus the few points near a face. Both passes over the
points take a block of :data:`_BLOCK` points at a time in loops the compiler vectorises where it can — the directions,
τ term by term and the hard return (:func:`fog_gym.fog.vexp.vexp`) in :func:`_directions`; the cells and weights, then
the rule in :func:`_hahner_grid` — with the same output bit for bit as scalar passes (digests pinned by a test).

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
from fog_gym.fog.depth import _height_term, _ramp, _ramp_integral, origin_constants
from fog_gym.fog.lidar import GAMMA, REFERENCE_REFLECTIVITY
from fog_gym.fog.lidar_pulse import (FIELD_COARSE, FIELD_STEP, _curves, beam_soft_maximum_from,
                                     field_pulse_weights, peak_extinction)  # fmt: skip
from fog_gym.fog.vexp import round_int, vexp

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


#: Points whose per-point values both passes compute together (:func:`_directions`, :func:`_hahner_grid`): loops over a
#: block vectorise.
_BLOCK = 256


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def _directions(pts, pose, terms, consts, step, last, r0s, dus, dzs, ks, hards, spans):
    # Per point: range, run along u and rise per metre, range node and hard return round(i·e^{−2τ}) (−1 where the ray
    # sees no fog, τ = 0); per chunk of the points (a row of spans): the least and greatest run and rise. A block of
    # points at a time in loops the compiler vectorises: the geometry, τ one term of the field at a time (the terms of
    # origin_depth, in its order, with vexp), then the hard return. (Division by zero in a lane whose value is not
    # taken gives inf or nan, not an exception: error_model="numpy".)
    n, chunks = pts.shape[0], spans.shape[0]
    u0, z0 = pose[0], pose[1]
    for c in prange(chunks):
        lo_u, hi_u, lo_z, hi_z = np.inf, -np.inf, np.inf, -np.inf
        tau, means = np.empty(_BLOCK), np.empty(_BLOCK)
        stop = (c + 1) * n // chunks
        for b0 in range(c * n // chunks, stop, _BLOCK):
            m = min(_BLOCK, stop - b0)
            pb, r0b, dub, dzb, kb, hb = (pts[b0:b0 + m], r0s[b0:b0 + m], dus[b0:b0 + m], dzs[b0:b0 + m], ks[b0:b0 + m],
                                         hards[b0:b0 + m])  # fmt: skip
            for j in range(m):
                x, y, z = np.float64(pb[j, 0]), np.float64(pb[j, 1]), np.float64(pb[j, 2])
                r0 = np.sqrt(x * x + y * y + z * z)
                inv = 1.0 / max(r0, 1e-12)
                r0b[j] = r0
                dub[j] = (pose[2] * x + pose[3] * y + pose[4] * z) * inv
                dzb[j] = (pose[5] * x + pose[6] * y + pose[7] * z) * inv
                kb[j] = min(round_int(min(r0, 200.0) * (1.0 / step)), last)
                tau[j] = 0.0
            for j in range(m):
                lo_u, hi_u, lo_z, hi_z = min(lo_u, dub[j]), max(hi_u, dub[j]), min(lo_z, dzb[j]), max(hi_z, dzb[j])
            for t in range(terms.shape[0]):
                kind, b = terms[t, 0], terms[t, 1]
                if kind == 0.0:
                    for j in range(m):
                        tau[j] += b * r0b[j]
                elif kind == 1.0 and consts[t, 3] != 0.0:  # origin_depth's height term seen from above the road
                    c0, c1, c2 = consts[t, 0], consts[t, 1], consts[t, 2]
                    for j in range(m):
                        length = r0b[j]
                        z1 = z0 + dzb[j] * length
                        below = length * (-z1) / (z0 - z1)
                        x = (z0 - z1) * c2
                        mean = 1.0 + x * (0.5 + x * (1.0 / 6.0 + x / 24.0)) if abs(x) < 1e-3 else (vexp(x) - 1.0) / x
                        tau[j] += b * (below + (length - below) * c1) if z1 < 0.0 else b * c0 * length * mean
                elif kind == 1.0:  # from at or below the road: the general form
                    for j in range(m):
                        tau[j] += _height_term(b, terms[t, 2], z0, dzb[j], r0b[j])
                else:  # a bank: origin_depth's (a beam across the bank's axis, whose run is under 1 µm, after)
                    a, bb, cc, d, p, bg = terms[t, 2], terms[t, 3], terms[t, 4], terms[t, 5], terms[t, 6], terms[t, 7]
                    w0 = consts[t, 0]
                    across = False
                    for j in range(m):
                        span = dub[j] * r0b[j]
                        means[j] = (_ramp_integral(u0 + span, a, bb, cc, d, p) - w0) / span
                        across |= abs(span) < 1e-6
                    if across:
                        for j in range(m):
                            span = dub[j] * r0b[j]
                            if abs(span) < 1e-6:
                                means[j] = _ramp(u0 + 0.5 * span, a, bb, cc, d, p)
                    for j in range(m):
                        tau[j] += (bg + b * means[j]) * r0b[j]
            for j in range(m):
                i_orig = np.rint(np.float64(pb[j, 3]) * 255.0)
                hard = np.rint(i_orig * vexp(-2.0 * tau[j]))
                hb[j] = -1.0 if tau[j] == 0.0 else hard
        spans[c, 0], spans[c, 1], spans[c, 2], spans[c, 3] = lo_u, hi_u, lo_z, hi_z


_directions_serial = serial_twin(_directions)


@njit(cache=True, inline="always")
def _cell(du, dz, du0, du_inv, n_du, dz0, dz_inv, n_dz):
    # The grid cell around a direction: its lower corner's indices along du and dz (held in floats: AVX2 converts no
    # int64 to float) and the position within the cell. An axis of one node has inverse spacing 0, so a = ia = ta = 0
    # there without a branch (in a vector loop a branch had the directions loaded under masks, slow on AVX2).
    a = min(max((du - du0) * du_inv, 0.0), n_du - 1.0)
    ia = max(min(np.floor(a), n_du - 2.0), 0.0)
    b = min(max((dz - dz0) * dz_inv, 0.0), n_dz - 1.0)
    ib = max(min(np.floor(b), n_dz - 2.0), 0.0)
    return ia, a - ia, ib, b - ib


@njit(cache=True, inline="always")
def corner_steps(n_du, n_dz):
    """A grid cell's steps from its lower corner's node to the next along ``du`` and along ``dz`` (0 along an axis of
    one node: its cells read the same corner twice).

    >>> corner_steps(16, 8), corner_steps(64, 1)
    ((1, 16), (1, 0))
    """
    return (1 if n_du > 1 else 0), (n_du if n_dz > 1 else 0)


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
            i = round_int(ib * n_du + ia)
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


#: Points a parallel task of :func:`_hahner_grid` takes (in blocks of :data:`_BLOCK`).
_GRID_SPAN = 2048


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def _hahner_grid(pts, pose, terms, consts, r0s, dus, dzs, ks, hards, du0, du_inv, n_du, dz0, dz_inv, n_dz, best, where,
                 stops, finals, reach, weights, ramp, weights5, ramp5, coarse, step, beta_max, log_noise, u, out,
                 attenuation, exact):  # fmt: skip
    # Each point from its grid cell's four curves where their decisions agree, else from its own beam (counted in
    # exact, a row per task); its hard return from _directions (< 0: no fog on the ray, the point as in clear air). A
    # block of points at a time, in five loops: per point its cell, corner weights, nearest corner and the factor g of
    # a corner's fog return min(255, v·g) (a loop that vectorises); the corners' curves (one point at a time: a point
    # at or beyond the range where its cell's four curves have all stopped, `reach`, reads the cell's row of `finals`,
    # finals_cell), whose decisions agree when the least or the greatest corner decides for all (the decision grows
    # with v), kept as a flag: a branch on it, which goes either way from point to point, cost more than the loop's
    # reads; the points whose corners disagree; Hahner et al.'s rule (_field_rule's, with vexp for the range noise;
    # it vectorises); the rows. A grid of one row or column reads its corners twice (the second with weight 0).
    n_pts = pts.shape[0]
    step_a, step_b = corner_steps(n_du, n_dz)
    for c in prange((n_pts + _GRID_SPAN - 1) // _GRID_SPAN):
        softs, r_tmps, gs, ratios, scales = (np.empty(_BLOCK), np.empty(_BLOCK), np.empty(_BLOCK), np.empty(_BLOCK),
                                             np.empty(_BLOCK))  # fmt: skip
        w00s, w10s, w01s, w11s = np.empty(_BLOCK), np.empty(_BLOCK), np.empty(_BLOCK), np.empty(_BLOCK)
        cells, qs = np.empty(_BLOCK, np.int64), np.empty(_BLOCK, np.int64)
        values = np.empty(_BLOCK, np.float32)
        agree = np.empty(_BLOCK, np.bool_)
        stop = min((c + 1) * _GRID_SPAN, n_pts)
        for b0 in range(c * _GRID_SPAN, stop, _BLOCK):
            m = min(_BLOCK, stop - b0)
            pb, r0b, hb, ub, ob = pts[b0:b0 + m], r0s[b0:b0 + m], hards[b0:b0 + m], u[b0:b0 + m], out[b0:b0 + m]
            dub, dzb, kb = dus[b0:b0 + m], dzs[b0:b0 + m], ks[b0:b0 + m]
            if attenuation >= 0.0:  # reflectance intensities: the point's own reflectivity stands in for Γ
                for j in range(m):
                    rho = min(max(np.float64(pb[j, 3]) / vexp(-attenuation * r0b[j]), 1e-3), 1.0)
                    ratios[j] = np.pi / GAMMA * REFERENCE_REFLECTIVITY / rho
            else:
                ratios[:m] = np.pi / GAMMA
            for j in range(m):
                r0 = r0b[j]
                gs[j] = np.rint(np.float64(pb[j, 3]) * 255.0) * r0 * r0 * ratios[j]
                ia, ta, ib, tb = _cell(dub[j], dzb[j], du0, du_inv, n_du, dz0, dz_inv, n_dz)
                cells[j] = round_int(ib * n_du + ia)
                w00, w10, w01, w11 = (1.0 - ta) * (1.0 - tb), ta * (1.0 - tb), (1.0 - ta) * tb, ta * tb
                w00s[j], w10s[j], w01s[j], w11s[j] = w00, w10, w01, w11
                q = 1 if w10 > w00 else 0  # the heaviest corner, the first of equals
                near_w = max(w10, w00)
                q = 2 if w01 > near_w else q
                qs[j] = 3 if w11 > max(w01, near_w) else q
            for j in range(m):
                i_hard, k, i00, g = hb[j], kb[j], cells[j], gs[j]
                if i_hard < 0.0:  # no fog on the ray (the rule keeps the point)
                    softs[j], r_tmps[j], agree[j] = 0.0, 0.0, True
                    continue
                q = qs[j]
                if k >= reach[i00]:
                    v00, v10, v01, v11 = finals[i00, 0], finals[i00, 1], finals[i00, 2], finals[i00, 3]
                    lo, hi, r_near = finals[i00, 8], finals[i00, 9], finals[i00, 4 + q]
                else:
                    i10, i01 = i00 + step_a, i00 + step_b
                    i11 = i01 + step_a
                    v00, v10 = best[i00, min(k, stops[i00])], best[i10, min(k, stops[i10])]
                    v01, v11 = best[i01, min(k, stops[i01])], best[i11, min(k, stops[i11])]
                    lo, hi = min(min(v00, v10), min(v01, v11)), max(max(v00, v10), max(v01, v11))
                    near = i00 + (q & 1) * step_a + (q >> 1) * step_b
                    r_near = where[near, min(k, stops[near])]
                soft = 0.0 + w00s[j] * v00
                soft += w10s[j] * v10
                soft += w01s[j] * v01
                soft += w11s[j] * v11
                softs[j], r_tmps[j] = soft, r_near * step
                agree[j] = (min(255.0, lo * g) > i_hard) | (not min(255.0, hi * g) > i_hard)
            for j in range(m):
                if not agree[j]:  # near a face: the point's own beam (the per-beam path)
                    soft, kk = beam_soft_maximum_from(terms, consts, pose[0], pose[1], dub[j], dzb[j], r0b[j],
                                                      weights, ramp, weights5, ramp5, coarse, step, beta_max)
                    softs[j], r_tmps[j] = soft, kk * step
                    exact[c] += 1
            for j in range(m):  # the rule: every value computed, then selected (the loop vectorises)
                r0, i_hard, intensity = r0b[j], hb[j], pb[j, 3]
                i_soft = _i_soft(softs[j], np.rint(np.float64(intensity) * 255.0), r0, ratios[j])
                fog = (i_hard >= 0.0) & (i_soft > i_hard)
                moved = r_tmps[j] / max(r0, 1e-12) * vexp(log_noise * ub[j])
                scales[j] = moved if fog else 1.0
                value = np.float32((i_soft if fog else i_hard) / 255.0)
                values[j] = value if i_hard >= 0.0 else intensity
            for j in range(m):  # the rows (a loop of its own: the compiler cannot tell pts from out)
                scale = scales[j]
                ob[j, 0] = np.float32(np.float64(pb[j, 0]) * scale)
                ob[j, 1] = np.float32(np.float64(pb[j, 1]) * scale)
                ob[j, 2] = np.float32(np.float64(pb[j, 2]) * scale)
                ob[j, 3] = values[j]
            for j in range(m):
                for col in range(4, pts.shape[1]):
                    ob[j, col] = pb[j, col]


_hahner_grid_serial = serial_twin(_hahner_grid)


@njit(cache=True, nogil=True)
def finals_cell(best, where, stops, step_a, step_b):
    """Per grid cell (indexed by its lower corner ``i``; corners ``i``, ``i + step_a``, ``i + step_b``,
    ``i + step_a + step_b``): its four curves' final values, the nodes where they lie and the least and greatest of
    the four values (``finals (nodes, 10)``), and the range node from which all four are final (``reach``: the greatest
    of their ``stops``; a curve is constant beyond its stop). Rows of lower corners that are no cell's are not read.

    >>> best, where = np.array([[1.0, 2.0, 2.0], [3.0, 5.0, 5.0]]), np.array([[0, 1, 1], [0, 1, 1]])
    >>> finals, reach = finals_cell(best, where, np.array([1, 1]), 1, 0)
    >>> finals[0].tolist(), reach.tolist()
    ([2.0, 5.0, 2.0, 5.0, 1.0, 1.0, 1.0, 1.0, 2.0, 5.0], [1, 1])
    """
    nodes = stops.shape[0]
    finals = np.empty((nodes, 10))
    reach = np.empty(nodes, np.int64)
    for i in range(nodes):
        lo, hi, top = np.inf, -np.inf, 0
        for q in range(4):
            j = min(i + (q & 1) * step_a + (q >> 1) * step_b, nodes - 1)
            v = best[j, stops[j]]
            finals[i, q], finals[i, 4 + q] = v, where[j, stops[j]]
            lo, hi, top = min(lo, v), max(hi, v), max(top, stops[j])
        finals[i, 8], finals[i, 9], reach[i] = lo, hi, top
    return finals, reach


@njit(cache=True, nogil=True)
def _grid(spans, heights, n_du, n_dz):
    # The grid of directions over the points' spans (rows of spans: per chunk, least and greatest run and rise) with up
    # to n_du × n_dz nodes (one along an axis the points do not spread over, or along the rise without height terms):
    # the nodes' runs and rises and the cell parameters (_node_tops' and _hahner_grid's).
    du_lo, du_hi, dz_lo, dz_hi = np.inf, -np.inf, np.inf, -np.inf
    for c in range(spans.shape[0]):
        du_lo, du_hi = min(du_lo, spans[c, 0]), max(du_hi, spans[c, 1])
        dz_lo, dz_hi = min(dz_lo, spans[c, 2]), max(dz_hi, spans[c, 3])
    n_du = n_du if du_hi > du_lo else 1
    if not heights:
        dz_lo, dz_hi = 0.0, 0.0
    n_dz = n_dz if heights and dz_hi > dz_lo else 1
    grid_du = np.linspace(du_lo, du_hi, n_du)  # (numpy's nodes: start + i·step, the last the stop)
    grid_dz = np.linspace(dz_lo, dz_hi, n_dz) if heights else np.zeros(1)
    node_du, node_dz = np.empty(n_du * n_dz), np.empty(n_du * n_dz)
    for b in range(n_dz):
        for a in range(n_du):
            node_du[b * n_du + a], node_dz[b * n_du + a] = grid_du[a], grid_dz[b]
    cell = (du_lo, (n_du - 1) / (du_hi - du_lo) if n_du > 1 else 0.0, n_du, dz_lo,
            (n_dz - 1) / (dz_hi - dz_lo) if n_dz > 1 else 0.0, n_dz)  # fmt: skip
    return node_du, node_dz, cell


def fog_lidar_grid(pts: np.ndarray, terms: np.ndarray, pose: np.ndarray, log_noise: float, u: np.ndarray,
                   out: np.ndarray, attenuation: float) -> int:
    """Hahner et al. with any packed field on ``pts`` into ``out`` (``fog_gym.fog.lidar_field.fog_lidar_field``'s
    arguments): the module docstring's grid of curves; returns how many points were integrated on their own beam."""
    import numba

    n = len(pts)
    last = int(round(200.0 / FIELD_STEP))
    r0s, dus, dzs = np.empty((3, n))
    ks = np.empty(n, np.int64)
    hards = np.empty(n)
    spans = np.empty((max(1, min(numba.get_num_threads(), n)), 4))
    consts = origin_constants(terms, float(pose[0]), float(pose[1]))
    pick(_directions, _directions_serial, n)(pts, pose, terms, consts, FIELD_STEP, last, r0s, dus, dzs, ks, hards,
                                             spans)
    heights = any(kind == HEIGHT for kind in terms[:, 0].tolist())
    node_du, node_dz, cell = _grid(spans, heights, *grid_shape(n, heights))
    tops = np.zeros((len(spans), len(node_du)), np.int64)
    pick(_node_tops, _node_tops_serial, n)(dus, dzs, ks, *cell, tops)
    tops = tops.max(axis=0)
    best, where, stops = _curves(terms, pose, node_du, node_dz, tops, consts, n)
    weights, ramp = field_pulse_weights()
    weights5, ramp5 = field_pulse_weights(FIELD_STEP * FIELD_COARSE)
    n_du, n_dz = cell[2], cell[5]
    finals, reach = finals_cell(best, where, stops, *corner_steps(n_du, n_dz))
    exact = np.zeros((n + _GRID_SPAN - 1) // _GRID_SPAN, np.int64)
    pick(_hahner_grid, _hahner_grid_serial, n)(pts, pose, terms, consts, r0s, dus, dzs, ks, hards, *cell, best,
                                               where, stops, finals, reach, weights, ramp, weights5, ramp5,
                                               FIELD_COARSE, FIELD_STEP, peak_extinction(terms), log_noise, u, out,
                                               attenuation, exact)  # fmt: skip
    return int(exact.sum())

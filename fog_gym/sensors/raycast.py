"""Ray casting from one origin against upright boxes and the ground plane ``z = 0`` (numba kernels).

Used by the LiDAR, semantic LiDAR and radar models (:mod:`fog_gym.sensors.lidar`). Cost scales with the rays and the
boxes near each ray, never with rays × boxes:

1. boxes whose nearest point lies beyond ``max_range`` from the origin are dropped;
2. the others are sorted by that nearest distance and binned into a grid of *direction cells* as seen from the
   origin: azimuth (a monotone "diamond" pseudo-angle, no trigonometry) × sin(elevation) over the rays'
   elevation span (sampled; rays and boxes beyond it clamp to the edge bins). A box goes into every cell its
   azimuth and elevation intervals touch (exact, conservative bounds); a box whose footprint holds the origin,
   or comes within :data:`NEAR_ALL` of it, spans every azimuth;
3. each ray (in parallel) starts from its ground-plane hit, then tests only the boxes of its cell, nearest
   first, with an exact ray/oriented-box slab test, and stops at the first box that lies farther than the
   current hit.

Hits from inside a box are ignored (as a line trace that starts inside a mesh), so a sensor mounted inside
its own vehicle's boxes sees through them.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, NamedTuple

import numpy as np
from numba import njit, prange

import fog_gym._numba  # noqa: F401  (numba's fork-safe threading layer, before any kernel runs)
from fog_gym._numba import pick, readonly, serial_twin
from fog_gym.world.mesh import MATERIAL_IDS
from fog_gym.sensors.mesh_hit import _mesh_hit
from fog_gym.world.meshlib import LIBRARY
from fog_gym.world.motion import SliceWorlds
from fog_gym.world.primitives import Primitives


#: ``index`` of a ray that hit the ground plane.
GROUND = -1
#: ``index`` of a ray that hit nothing within ``max_range`` (its distance is ``inf``).
MISS = -2
#: ``material`` of a ray that hit the ground or nothing.
NO_MATERIAL = 255
#: ``material`` of a ray that hit a plain box (its tag and reflectivity are the primitive's).
BOX_MATERIAL = MATERIAL_IDS["box"]
#: Rays from which :func:`cast_rays` runs its parallel kernel (below, its serial twin). A ray costs far more than a
#: pixel (60–70 ns against a mesh town), so the cast pays a parallel launch from fewer items than
#: :data:`~fog_gym._numba.SERIAL_BELOW`: on two cores the RL presets' 10 016-ray sweep took 0.47 against 0.71 ms
#: (meshes) and 0.28 against 0.44 ms (boxes), while 2 048 rays lost (0.41 against 0.26 ms; docs/performance.md).
CAST_SERIAL_BELOW = 8192
#: A box whose footprint comes this close (metres, horizontally) to the origin is put in every azimuth bin.
NEAR_ALL = 0.05
_PAD = 1e-9  # widening of every box's bin interval against rounding at cell borders
_T_MIN = 1e-6  # hits nearer than this (origin on or inside a box) do not count
_SPAN_SAMPLES = 2048  # rays sampled for the elevation span of the bins
#: Rays sampled for the azimuth sector and the elevation span of ``sector=True`` (a sweep's slice): the sector is
#: widened by ``_SECTOR_MARGIN`` of its width and every ray checked against it; should one lie outside, the cast is
#: done again from the exact sector (the same hits either way).
_SECTOR_SAMPLES = 128
_SECTOR_MARGIN = 0.05
_CHUNK = 512  # rays a task of the parallel cast traces


@njit(cache=True, inline="always")
def _pseudo_azimuth(x, y):
    """Diamond angle of (x, y): monotone in atan2(y, x) mapped from [0, 2π) to [0, 4); 0 for the zero vector."""
    if y >= 0.0:
        if x >= 0.0:
            s = x + y
            return y / s if s > 0.0 else 0.0
        return 1.0 - x / (y - x)
    if x < 0.0:
        return 2.0 - y / (-x - y)
    return 3.0 + x / (x - y)


@njit(cache=True, inline="always")
def _pseudo_azimuth_select(x, y):
    """:func:`_pseudo_azimuth` with one division and no branch (each quadrant's ``base ± num / den``; negating a
    quotient is exact, so the same number as :func:`_pseudo_azimuth`'s own expression, tested).

    >>> from numba import njit
    >>> f = njit(lambda x, y: _pseudo_azimuth_select(x, y))
    >>> [f(1.0, 1.0), f(-1.0, 1.0), f(-1.0, -1.0), f(1.0, -1.0), f(0.0, 0.0)]
    [0.5, 1.5, 2.5, 3.5, 0.0]
    """
    up = y >= 0.0
    right = x >= 0.0
    num = y if up == right else x
    den = (x + y) if (up and right) else ((y - x) if up else ((-x - y) if not right else (x - y)))
    q = num / (den if den > 0.0 else 1.0)  # (only x + y can be 0, at x = y = 0)
    if up and right:
        return q if den > 0.0 else 0.0
    if up:
        return 1.0 - q
    if not right:
        return 2.0 - q
    return 3.0 + q


@njit(cache=True, inline="always")
def _sin_elevation(z, r):
    """z / sqrt(z² + r²) (sine of the elevation of a point at height z, horizontal distance r)."""
    n = np.sqrt(z * z + r * r)
    if n < 1e-12:
        return 0.0
    return z / n


@njit(cache=True, inline="always")
def _wrap(a):
    """A pseudo-azimuth difference in [−2, 2) (half a turn either way)."""
    return a - 4.0 * np.floor((a + 2.0) * 0.25)


@njit(cache=True, nogil=True)
def _sector(rotation, directions, stride):
    """The rays' azimuth sector: ``(a_ref, a_lo, a_hi)``, pseudo-azimuths relative to the first ray's over every
    ``stride``-th ray and the last (exact for stride 1; else widened by :data:`_SECTOR_MARGIN` of its width, and the
    cast checks every ray against it); ``a_lo = a_hi = 0`` when it spans more than a quarter turn (then the bins
    cover the full turn)."""
    R = rotation
    n = directions.shape[0]
    a_ref = 0.0
    a_lo = 0.0
    a_hi = 0.0
    i = 0
    while i < n:
        ax, ay, az = directions[i, 0], directions[i, 1], directions[i, 2]
        inv_n = 1.0 / np.sqrt(ax * ax + ay * ay + az * az)  # the unit world direction, as the cast computes it
        a = _pseudo_azimuth((R[0, 0] * ax + R[0, 1] * ay + R[0, 2] * az) * inv_n,
                            (R[1, 0] * ax + R[1, 1] * ay + R[1, 2] * az) * inv_n)  # fmt: skip
        if i == 0:
            a_ref = a
        rel = _wrap(a - a_ref)
        a_lo = min(a_lo, rel)
        a_hi = max(a_hi, rel)
        if a_hi - a_lo > 1.0:
            return 0.0, 0.0, 0.0
        i = n - 1 if i < n - 1 and i + stride >= n else i + stride
    if stride > 1:
        pad = _SECTOR_MARGIN * (a_hi - a_lo) + 1e-9
        a_lo -= pad
        a_hi += pad
        if a_hi - a_lo > 1.0:
            return 0.0, 0.0, 0.0
    return a_ref, a_lo, a_hi


@njit(cache=True, nogil=True)
def _bin_boxes(ox, oy, oz, max_range, centers, halves, yaws, n_az, n_el, s_lo, s_hi, a_ref, a_lo, a_hi):
    """Cull, sort and bin the boxes. Returns (box table (K, 8), near distance (K,), prim index (K,), cell offsets
    (n_az * n_el + 1,), cell entries) with cell = az_bin * n_el + el_bin and each cell's entries nearest first.
    With ``a_hi > a_lo`` the azimuth bins cover the rays' sector only (pseudo-azimuths ``a_lo … a_hi`` from
    ``a_ref``, :func:`_sector`) and boxes wholly outside it are dropped; else they cover the full turn."""
    n = centers.shape[0]
    sector = a_hi > a_lo
    near = np.empty(n)
    keep = np.zeros(n, dtype=np.bool_)
    local = np.empty((n, 8))  # origin in the box frame (3), halves (3), cos, sin of yaw
    for p in range(n):
        if sector:  # a box whose bounding circle's azimuths miss the sector: no ray can meet it
            rx, ry = centers[p, 0] - ox, centers[p, 1] - oy
            rho = np.sqrt(rx * rx + ry * ry)
            r = np.sqrt(halves[p, 0] * halves[p, 0] + halves[p, 1] * halves[p, 1])
            if rho > r + NEAR_ALL:
                w = 0.5 * np.pi * r / rho + _PAD  # ≥ asin(r / ρ), the circle's half-angle; |d pseudo-azimuth| ≤ |d angle|
                if w < 0.5:
                    pc = _wrap(_pseudo_azimuth(rx, ry) - a_ref)
                    if pc + w < a_lo or pc - w > a_hi:
                        continue
        c = np.cos(yaws[p])
        s = np.sin(yaws[p])
        rx = ox - centers[p, 0]
        ry = oy - centers[p, 1]
        lx = c * rx + s * ry
        ly = -s * rx + c * ry
        lz = oz - centers[p, 2]
        hx, hy, hz = halves[p, 0], halves[p, 1], halves[p, 2]
        ex = max(abs(lx) - hx, 0.0)
        ey = max(abs(ly) - hy, 0.0)
        ez = max(abs(lz) - hz, 0.0)
        d = np.sqrt(ex * ex + ey * ey + ez * ez)
        near[p] = d
        keep[p] = d < max_range
        local[p, 0] = lx
        local[p, 1] = ly
        local[p, 2] = lz
        local[p, 3] = hx
        local[p, 4] = hy
        local[p, 5] = hz
        local[p, 6] = c
        local[p, 7] = s
    cand = np.flatnonzero(keep)
    order = cand[np.argsort(near[cand], kind="mergesort")]
    k_n = order.shape[0]
    # per kept box: azimuth bin range [a0, a1] (may run past n_az: wrap) and elevation bin range [e0, e1]
    a0 = np.zeros(k_n, dtype=np.int64)
    a1 = np.zeros(k_n, dtype=np.int64)
    e0 = np.zeros(k_n, dtype=np.int64)
    e1 = np.zeros(k_n, dtype=np.int64)
    inv_ds = n_el / (s_hi - s_lo) if s_hi > s_lo else 0.0
    inv_da = n_az / (a_hi - a_lo) if sector else 0.0
    for k in range(k_n):
        p = order[k]
        lx, ly, lz = local[p, 0], local[p, 1], local[p, 2]
        hx, hy, hz = local[p, 3], local[p, 4], local[p, 5]
        c, s = local[p, 6], local[p, 7]
        ex = max(abs(lx) - hx, 0.0)
        ey = max(abs(ly) - hy, 0.0)
        r_min = np.sqrt(ex * ex + ey * ey)
        fx = abs(lx) + hx
        fy = abs(ly) + hy
        r_max = np.sqrt(fx * fx + fy * fy)
        # elevation: sin(elev) rises with height and, above the origin, falls with horizontal distance
        z_top = -lz + hz
        z_bot = -lz - hz
        sv_hi = _sin_elevation(z_top, r_min if z_top > 0.0 else r_max)
        sv_lo = _sin_elevation(z_bot, r_max if z_bot > 0.0 else r_min)
        if r_min < 1e-12:  # origin above or below the footprint: straight up / down is inside
            if z_top >= 0.0:
                sv_hi = 1.0
            if z_bot <= 0.0:
                sv_lo = -1.0
        # clamp to the edge bins (never drop): rays outside the sampled span clamp the same way
        e0[k] = min(max(int(np.floor((sv_lo - _PAD - s_lo) * inv_ds)), 0), n_el - 1)
        e1[k] = min(max(int(np.floor((sv_hi + _PAD - s_lo) * inv_ds)), 0), n_el - 1)
        if r_min < NEAR_ALL:
            a0[k] = 0
            a1[k] = n_az - 1
            continue
        # azimuth: pseudo-angles of the four footprint corners relative to the centre's (span < π here)
        pcx = centers[p, 0] - ox
        pcy = centers[p, 1] - oy
        pc = _pseudo_azimuth(pcx, pcy)
        lo = 0.0
        hi = 0.0
        for sx in (-1.0, 1.0):
            for sy in (-1.0, 1.0):
                qx = sx * hx
                qy = sy * hy
                dq = _pseudo_azimuth(pcx + c * qx - s * qy, pcy + s * qx + c * qy) - pc
                if dq > 2.0:
                    dq -= 4.0
                elif dq < -2.0:
                    dq += 4.0
                lo = min(lo, dq)
                hi = max(hi, dq)
        if sector:  # the interval's copy nearest the sector (which lies within ±1 of a_ref; the interval spans < 2)
            mid = _wrap(pc + 0.5 * (lo + hi) - a_ref)
            b0 = int(np.floor((mid - 0.5 * (hi - lo) - _PAD - a_lo) * inv_da))
            b1 = int(np.floor((mid + 0.5 * (hi - lo) + _PAD - a_lo) * inv_da))
            b0 = min(max(b0, 0), n_az - 1)  # beyond the sector: the edge bins (rays there clamp the same way)
            b1 = min(max(b1, 0), n_az - 1)
        else:
            b0 = int(np.floor((pc + lo - _PAD) * (n_az / 4.0)))
            b1 = int(np.floor((pc + hi + _PAD) * (n_az / 4.0)))
            if b1 - b0 + 1 >= n_az:
                b0 = 0
                b1 = n_az - 1
        a0[k] = b0
        a1[k] = b1
    # CSR fill: count, prefix sum, fill in nearest-first order
    n_cells = n_az * n_el
    offsets = np.zeros(n_cells + 1, dtype=np.int64)
    for k in range(k_n):
        for b in range(a0[k], a1[k] + 1):
            base = (b % n_az) * n_el
            for e in range(e0[k], e1[k] + 1):
                offsets[base + e + 1] += 1
    for i in range(n_cells):
        offsets[i + 1] += offsets[i]
    fill = offsets[:-1].copy()
    entries = np.empty(offsets[n_cells], dtype=np.int32)
    for k in range(k_n):
        for b in range(a0[k], a1[k] + 1):
            base = (b % n_az) * n_el
            for e in range(e0[k], e1[k] + 1):
                entries[fill[base + e]] = k
                fill[base + e] += 1
    table = np.empty((k_n, 8))
    near_sorted = np.empty(k_n)
    for k in range(k_n):
        table[k] = local[order[k]]
        near_sorted[k] = near[order[k]]
    return table, near_sorted, order.astype(np.int32), offsets, entries


@njit(cache=True, inline="always")
def _slab(o, d, h, t0, t1):
    """One slab of the box: returns the narrowed (entry, exit) interval and whether the entry moved."""
    if abs(d) < 1e-15:
        if abs(o) > h:
            return 1.0, -1.0, False  # parallel and outside: empty
        return t0, t1, False
    inv = 1.0 / d
    ta = (-h - o) * inv
    tb = (h - o) * inv
    if ta > tb:
        ta, tb = tb, ta
    moved = ta > t0
    if moved:
        t0 = ta
    if tb < t1:
        t1 = tb
    return t0, t1, moved


@njit(cache=True, nogil=True)
def _trace(t_lo, t_hi, half, ox, oy, oz, R, directions, max_range, table, near, prim, offsets, entries, meshes, n_az,
           n_el, s_lo, inv_ds, a_ref, a_lo, a_hi, inv_da, tri_geom, lib_m, node_start, node_lo, node_hi, node_skip,
           node_first, node_count, radius, dist, index, cosine, material):  # fmt: skip
    """The cast of tasks ``t_lo … t_hi`` of :func:`_cast` (one thread's share: a parallel kernel's chunk, or all of
    them); returns how many of their rays lie outside the sector ``a_lo … a_hi`` (when it is one). A function of its
    own, so that the parallel kernel and its serial twin run the same compiled loop (inline, the serial twin's ran
    1.5× slower)."""
    outside = 0
    # first every ray's unit world direction and pseudo-azimuth, in a loop without branches (the rays' chains of
    # divisions overlap; the same operations on the same numbers as one ray at a time: the same bits)
    wd = np.empty((4, t_hi - t_lo))
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = (R[0, 0], R[0, 1], R[0, 2], R[1, 0], R[1, 1], R[1, 2], R[2, 0],
                                                   R[2, 1], R[2, 2])  # fmt: skip
    for task in range(t_lo, t_hi):
        # rays 0, 2, 4, … then 1, 3, …: the threads' contiguous shares each hold every part of the sweep
        i = 2 * np.int64(task) if np.int64(task) < half else 2 * (np.int64(task) - half) + 1
        ax, ay, az = directions[i, 0], directions[i, 1], directions[i, 2]
        inv_n = 1.0 / np.sqrt(ax * ax + ay * ay + az * az)
        x = (r00 * ax + r01 * ay + r02 * az) * inv_n
        y = (r10 * ax + r11 * ay + r12 * az) * inv_n
        j = task - t_lo
        wd[0, j], wd[1, j], wd[2, j] = x, y, (r20 * ax + r21 * ay + r22 * az) * inv_n
        wd[3, j] = _pseudo_azimuth_select(x, y)
    for task in range(t_lo, t_hi):
        i = 2 * np.int64(task) if np.int64(task) < half else 2 * (np.int64(task) - half) + 1
        j = task - t_lo
        dx, dy, dz, azimuth = wd[0, j], wd[1, j], wd[2, j], wd[3, j]
        best = max_range
        hit = MISS
        cos_hit = 0.0
        mat = NO_MATERIAL
        if dz < -1e-12 and oz > 0.0:
            tg = -oz / dz
            if tg < best:
                best = tg
                hit = GROUND
                cos_hit = -dz
        if a_hi > a_lo:  # bins over the rays' sector
            rel = _wrap(azimuth - a_ref)
            if rel < a_lo or rel > a_hi:
                outside += 1
            b = min(max(int((rel - a_lo) * inv_da), 0), n_az - 1)
        else:
            b = int(azimuth * (n_az / 4.0))
            if b >= n_az:
                b = n_az - 1
        e = min(max(int((dz - s_lo) * inv_ds), 0), n_el - 1)
        cell = b * n_el + e
        for j in range(offsets[cell], offsets[cell + 1]):
            k = entries[j]
            if near[k] >= best:
                break  # cell entries are nearest first: nothing further can be nearer than the current hit
            c, s = table[k, 6], table[k, 7]
            lx = c * dx + s * dy
            ly = -s * dx + c * dy
            t0 = -np.inf
            t1 = np.inf
            t0, t1, mx = _slab(table[k, 0], lx, table[k, 3], t0, t1)
            t0, t1, my = _slab(table[k, 1], ly, table[k, 4], t0, t1)
            t0, t1, mz = _slab(table[k, 2], dz, table[k, 5], t0, t1)
            m = meshes[prim[k]]
            if m != 0:  # a mesh in the box: its nearest front triangle within the box's interval
                if t0 > t1 or t1 < _T_MIN or t0 >= best:
                    continue
                tm, tri, cm = _mesh_hit(table[k, 0], table[k, 1], table[k, 2], lx, ly, dz, 2.0 * table[k, 3],
                                        2.0 * table[k, 4], 2.0 * table[k, 5], m, tri_geom, node_start, node_lo,
                                        node_hi, node_skip, node_first, node_count, max(t0 - 1e-9, _T_MIN),
                                        min(t1 + 1e-9, best), radius[m])  # fmt: skip
                if tri >= 0:
                    best = tm
                    hit = prim[k]
                    cos_hit = cm
                    mat = lib_m[tri]
                continue
            if t0 > t1 or t0 < _T_MIN or t0 >= best:
                continue
            best = t0
            hit = prim[k]
            mat = BOX_MATERIAL
            # the entry face is the slab that moved the entry last (z, then y, then x in test order)
            cos_hit = abs(dz) if mz else (abs(ly) if my else abs(lx))
        if hit == MISS:
            dist[i] = np.inf
        else:
            dist[i] = best
        index[i] = hit
        cosine[i] = cos_hit
        material[i] = mat
    return outside


@njit(cache=True, nogil=True, parallel=True)
def _cast(origin, rotation, directions, max_range, centers, halves, yaws, meshes, n_az, n_el, sector,
          tri_geom, lib_t, lib_m, node_start, node_lo, node_hi, node_skip, node_first, node_count, radius):  # fmt: skip
    n_rays = directions.shape[0]
    ox, oy, oz = origin[0], origin[1], origin[2]
    R = rotation
    # span of sin(elevation) over a sample of the rays, for the elevation bins. Rays and boxes outside it
    # clamp to the edge bins, so the sample only tunes the binning; results never depend on it.
    stride = max(1, n_rays // (_SECTOR_SAMPLES if sector else _SPAN_SAMPLES))
    s_lo = 1.0
    s_hi = -1.0
    for i in range(0, n_rays, stride):
        ax, ay, az = directions[i, 0], directions[i, 1], directions[i, 2]
        sz = (R[2, 0] * ax + R[2, 1] * ay + R[2, 2] * az) / np.sqrt(ax * ax + ay * ay + az * az)
        s_lo = min(s_lo, sz)
        s_hi = max(s_hi, sz)
    inv_ds = n_el / (s_hi - s_lo) if s_hi > s_lo else 0.0
    dist = np.empty(n_rays, dtype=np.float32)
    index = np.empty(n_rays, dtype=np.int32)
    cosine = np.empty(n_rays, dtype=np.float32)
    material = np.empty(n_rays, dtype=np.uint8)
    half = (n_rays + 1) // 2
    # a sector from a sample of the rays (widened): should a ray lie outside it, once more from the exact sector
    for attempt in range(2 if sector and stride > 1 else 1):
        a_ref, a_lo, a_hi = _sector(R, directions, stride if attempt == 0 else 1) if sector else (0.0, 0.0, 0.0)
        table, near, prim, offsets, entries = _bin_boxes(
            ox, oy, oz, max_range, centers, halves, yaws, n_az, n_el, s_lo, s_hi, a_ref, a_lo, a_hi
        )
        inv_da = n_az / (a_hi - a_lo) if a_hi > a_lo else 0.0
        outside = 0
        n_chunks = (n_rays + _CHUNK - 1) // _CHUNK
        for c in prange(n_chunks):
            outside += _trace(c * _CHUNK, min((c + 1) * _CHUNK, n_rays), half, ox, oy, oz, R, directions, max_range,
                              table, near, prim, offsets, entries, meshes, n_az, n_el, s_lo, inv_ds, a_ref, a_lo, a_hi,
                              inv_da, tri_geom, lib_m, node_start, node_lo, node_hi, node_skip, node_first, node_count,
                              radius, dist, index, cosine, material)  # fmt: skip
        if outside == 0:
            break
    return dist, index, cosine, material


_cast_serial = serial_twin(_cast)


@njit(cache=True, nogil=True, parallel=True)
def _cast_slices(origins, rotations, directions, bounds, max_range, centers, halves, yaws, meshes, n_az, n_el,
                 tri_geom, lib_t, lib_m, node_start, node_lo, node_hi, node_skip, node_first, node_count, radius,
                 order, dist, index, cosine, material):  # fmt: skip
    # Slice s: rays bounds[s]:bounds[s + 1] of directions, from origins[s] with rotations[s], against the boxes at
    # centers[s] and yaws[s] (halves and meshes shared), as cast_rays(..., sector=True) casts it, ray j's hit into
    # row order[j]; the slices in parallel, each one thread's serial cast.
    for s in prange(bounds.shape[0] - 1):
        lo, hi = bounds[s], bounds[s + 1]
        if lo == hi:
            continue
        d, i, c, m = _cast_serial(origins[s], rotations[s], directions[lo:hi], max_range, centers[s], halves, yaws[s],
                                  meshes, n_az, n_el, True, tri_geom, lib_t, lib_m, node_start, node_lo, node_hi,
                                  node_skip, node_first, node_count, radius)  # fmt: skip
        for j in range(hi - lo):
            r = order[lo + j]
            dist[r], index[r], cosine[r], material[r] = d[j], i[j], c[j], m[j]


_cast_slices_serial = serial_twin(_cast_slices)



class RayHits(NamedTuple):
    """Per-ray result of :func:`cast_rays`."""

    distance: np.ndarray  # (N,) float32 metres along the ray; inf for a miss
    index: np.ndarray  # (N,) int32 primitive index, GROUND (-1) or MISS (-2)
    cos_incidence: np.ndarray  # (N,) float32 |cos| of the angle between ray and surface normal; 0 for a miss
    material: np.ndarray  # (N,) uint8 material id of the surface hit (fog_gym.world.mesh), NO_MATERIAL for ground/miss


def cast_rays(
    origin: np.ndarray,
    directions: np.ndarray,
    max_range: float,
    prims: Primitives | Mapping[str, Any],
    rotation: np.ndarray | None = None,
    n_azimuth_bins: int = 512,
    n_elevation_bins: int = 16,
    sector: bool = False,
) -> RayHits:
    """Cast rays from one world point against the boxes of ``prims`` and the ground plane ``z = 0``.

    ``directions`` (N, 3) need not be unit length (but non-zero); with ``rotation`` (3×3) they are in a local
    frame and the world direction is ``rotation @ direction`` (pass a sensor's rotation and its own ray pattern).
    Distances are metres along the ray.
    ``prims`` is a :class:`~fog_gym.world.primitives.Primitives` (or a mapping with at least ``centers`` (P, 3),
    ``halves`` (P, 3) and ``yaws`` (P,)); only the geometry is used. A hit counts when it lies strictly nearer than ``max_range``; hits from inside a box do not
    count. The bin counts only trade set-up time against per-ray work; results do not depend on them. ``sector``
    (for rays that span a narrow sector of azimuths, as one slice of a sweep that takes time): the azimuth bins
    cover the rays' sector only and boxes outside it are never binned — the same hits, less set-up; rays that span
    more than a quarter turn fall back to the full turn.

    >>> prims = {"centers": np.array([[10.0, 0.0, 1.0]]), "halves": np.array([[1.0, 1.0, 1.0]]),
    ...          "yaws": np.zeros(1)}
    >>> hits = cast_rays(np.array([0.0, 0.0, 1.0]), np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 0, 1.0]]), 50.0, prims)
    >>> hits.distance.tolist(), hits.index.tolist(), hits.cos_incidence.tolist()
    ([9.0, 1.0, inf], [0, -1, -2], [1.0, 1.0, 0.0])
    """
    if not (np.isfinite(max_range) and max_range > 0):
        raise ValueError(f"max_range must be a positive finite number, got {max_range!r}")
    if int(n_azimuth_bins) < 1 or int(n_elevation_bins) < 1:
        raise ValueError(f"bin counts must be >= 1, got {n_azimuth_bins!r}, {n_elevation_bins!r}")
    prims = Primitives.coerce(prims)
    directions = readonly(np.ascontiguousarray(directions, np.float64).reshape(-1, 3))  # one signature for both
    n = directions.shape[0]
    if n == 0:
        return RayHits(np.zeros(0, np.float32), np.zeros(0, np.int32), np.zeros(0, np.float32), np.zeros(0, np.uint8))
    rotation = np.eye(3) if rotation is None else np.ascontiguousarray(rotation, np.float64).reshape(3, 3)
    lib = LIBRARY.arrays()
    dist, index, cosine, material = pick(_cast, _cast_serial, n, CAST_SERIAL_BELOW)(
        np.ascontiguousarray(origin, np.float64).reshape(3),
        rotation,
        directions,
        float(max_range),
        prims.centers,
        prims.halves,
        prims.yaws,
        prims.meshes,
        int(n_azimuth_bins),
        int(n_elevation_bins),
        bool(sector),
        lib.tri_geom, lib.triangles, lib.materials, lib.node_start, lib.node_lo, lib.node_hi, lib.node_skip,
        lib.node_first, lib.node_count, lib.radius,
    )
    return RayHits(dist, index, cosine, material)


def cast_ray_slices(origins: np.ndarray, rotations: np.ndarray, directions: np.ndarray, bounds: np.ndarray,
                    max_range: float, worlds: list[Primitives] | SliceWorlds, n_azimuth_bins: int = 512,
                    n_elevation_bins: int = 16, order: np.ndarray | None = None) -> RayHits:  # fmt: skip
    """Slices of rays, each cast from its own place against its own world, in one kernel call (a sweep that takes
    time: :func:`fog_gym.sensors.lidar.simulate_lidar`): slice ``s`` is rays ``bounds[s]:bounds[s + 1]`` of
    ``directions`` (their own frame), from ``origins[s]`` with ``rotations[s]``, against ``worlds[s]`` — the same
    boxes and meshes in every world, only their ``centers`` and ``yaws`` differ (or a
    :class:`~fog_gym.world.motion.SliceWorlds`: those as arrays, without a copy). The hits of each slice are
    :func:`cast_rays`'s with ``sector=True`` bit for bit (tested); the slices run in parallel. ``order``: the row of
    the result each ray's hit goes to (default: its own), a permutation of the rows (only checked to lie within them:
    a row that no ray names is left unset).

    >>> box = Primitives.coerce({"centers": np.array([[10.0, 0, 1]]), "halves": np.ones((1, 3)), "yaws": np.zeros(1)})
    >>> moved = Primitives.coerce({"centers": np.array([[20.0, 0, 1]]), "halves": np.ones((1, 3)), "yaws": np.zeros(1)})
    >>> hits = cast_ray_slices(np.array([[0.0, 0, 1], [0.0, 0, 1]]), np.stack([np.eye(3)] * 2),
    ...                        np.array([[1.0, 0, 0], [1.0, 0, 0]]), np.array([0, 1, 2]), 50.0, [box, moved])
    >>> hits.distance.tolist()
    [9.0, 19.0]
    """
    directions = readonly(np.ascontiguousarray(directions, np.float64).reshape(-1, 3))
    bounds = np.ascontiguousarray(bounds, np.int64)
    n_slices = len(bounds) - 1
    if not (np.isfinite(max_range) and max_range > 0):
        raise ValueError(f"max_range must be a positive finite number, got {max_range!r}")
    if isinstance(worlds, SliceWorlds):
        first, centers, yaws = worlds
        n_worlds = len(centers)
        if centers.shape != (n_worlds, len(first), 3) or yaws.shape != (n_worlds, len(first)):
            raise ValueError(f"worlds: centers and yaws must be (S, {len(first)}, 3) and (S, {len(first)}), got "
                             f"{centers.shape} and {yaws.shape}")  # fmt: skip
    else:
        worlds = [Primitives.coerce(w) for w in worlds]
        first, n_worlds = worlds[0] if worlds else Primitives.empty(), len(worlds)
        if any(len(w) != len(first) for w in worlds):
            raise ValueError("every slice's world must hold the same primitives (only their centers and yaws move)")
        centers = np.stack([w.centers for w in worlds]) if worlds else np.zeros((0, 0, 3))
        yaws = np.stack([w.yaws for w in worlds]) if worlds else np.zeros((0, 0))
    if n_slices < 0 or n_worlds != n_slices or bounds[0] != 0 or bounds[-1] != len(directions) or \
            np.any(np.diff(bounds) < 0):  # fmt: skip
        raise ValueError(f"bounds must rise from 0 to the {len(directions)} rays with one slice per world "
                         f"({n_worlds}), got {bounds.tolist()}")  # fmt: skip
    order = np.arange(len(directions)) if order is None else np.ascontiguousarray(order, np.int64)
    if order.shape != (len(directions),) or (len(order) and not 0 <= order.min() <= order.max() < len(order)):
        raise ValueError(f"order must be a permutation of the {len(directions)} rays' rows")
    n = len(directions)
    dist, index = np.empty(n, np.float32), np.empty(n, np.int32)
    cosine, material = np.empty(n, np.float32), np.empty(n, np.uint8)
    if n == 0:
        return RayHits(dist, index, cosine, material)
    centers = np.ascontiguousarray(centers, np.float64)
    yaws = np.ascontiguousarray(yaws, np.float64)
    lib = LIBRARY.arrays()
    pick(_cast_slices, _cast_slices_serial, n)(
        np.ascontiguousarray(origins, np.float64).reshape(n_slices, 3),
        np.ascontiguousarray(rotations, np.float64).reshape(n_slices, 3, 3), directions, bounds, float(max_range),
        centers, first.halves, yaws, first.meshes, int(n_azimuth_bins), int(n_elevation_bins),
        lib.tri_geom, lib.triangles, lib.materials, lib.node_start, lib.node_lo, lib.node_hi, lib.node_skip,
        lib.node_first, lib.node_count, lib.radius, order, dist, index, cosine, material,
    )  # fmt: skip
    return RayHits(dist, index, cosine, material)


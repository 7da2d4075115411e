"""A ray against one library mesh drawn in its box (:mod:`fog_gym.world.meshlib`): the nearest front-facing
triangle, found by walking the mesh's bounding-volume hierarchy without a stack and testing its triangles with
Möller–Trumbore. The ray caster (:mod:`fog_gym.sensors.raycast`) calls it for each box with a mesh that a ray's
interval meets; pure numba over the library's arrays.
"""

from __future__ import annotations

import numpy as np
from numba import njit

import fog_gym._numba  # noqa: F401  (numba's fork-safe threading layer, before any kernel runs)
from fog_gym.world.meshlib import OCTANTS

#: A mesh's bounding sphere is tested first when its radius (normalised frame) is below this (the unit box's is
#: ≈ 0.87): round crowns. The sphere is widened by ``_SPHERE_PAD`` (relative), far more than rounding, so a ray it
#: turns away meets no triangle.
_SPHERE_TIGHT = 0.8
_SPHERE_PAD = 1e-6


@njit(cache=True, inline="always")
def _box_entry(ox, oy, oz, ix, iy, iz, lo, hi, k, t_lo, t_hi):
    """Entry distance of the ray (origin o, inverse direction i) into node ``k``'s bounds within (t_lo, t_hi), or
    ``inf`` when it misses them there."""
    ta = (lo[k, 0] - ox) * ix
    tb = (hi[k, 0] - ox) * ix
    t0 = min(ta, tb)
    t1 = max(ta, tb)
    ta = (lo[k, 1] - oy) * iy
    tb = (hi[k, 1] - oy) * iy
    t0 = max(t0, min(ta, tb))
    t1 = min(t1, max(ta, tb))
    ta = (lo[k, 2] - oz) * iz
    tb = (hi[k, 2] - oz) * iz
    t0 = max(t0, min(ta, tb))
    t1 = min(t1, max(ta, tb))
    t0 = max(t0, t_lo)
    t1 = min(t1, t_hi)
    return t0 if t0 <= t1 else np.inf


@njit(cache=True, nogil=True)
def _mesh_hit(ox, oy, oz, dx, dy, dz, sx, sy, sz, m, tri_geom, node_start, node_lo, node_hi, node_skip,
              node_first, node_count, t_lo, best, radius):  # fmt: skip
    """Nearest front-facing triangle of library mesh ``m`` (scaled by ``s`` = the box's size, in its box frame) that
    the ray o + t·d (box frame, d unit) meets with ``t_lo < t < best``: (t, triangle, |cos incidence|), triangle −1
    for none. A ray that misses the mesh's bounding sphere (``radius`` in the normalised frame, widened by
    ``_SPHERE_PAD``) within that interval misses the mesh (tested where the sphere is tighter than the box: crowns).
    Walks the mesh's hierarchy depth first without a stack, past every subtree whose bounds the ray meets only beyond
    ``best``; each triangle's vertex, edges and normal come precomputed (``tri_geom``)."""
    # the ray in the mesh's normalised frame (v / size): same t
    nox, noy, noz = ox / sx, oy / sy, oz / sz
    ndx, ndy, ndz = dx / sx, dy / sy, dz / sz
    if radius < _SPHERE_TIGHT:  # |no + t·nd| ≤ radius at every point of every triangle
        r = radius * (1.0 + _SPHERE_PAD)
        a = ndx * ndx + ndy * ndy + ndz * ndz
        b = nox * ndx + noy * ndy + noz * ndz
        disc = b * b - a * (nox * nox + noy * noy + noz * noz - r * r)
        if disc < 0.0:
            return best, -1, 0.0
        root = np.sqrt(disc)
        if (-b + root) / a < t_lo or (-b - root) / a > best:
            return best, -1, 0.0
    ix = 1.0 / ndx if abs(ndx) > 1e-300 else 1e300
    iy = 1.0 / ndy if abs(ndy) > 1e-300 else 1e300
    iz = 1.0 / ndz if abs(ndz) > 1e-300 else 1e300
    hit = -1
    cos_hit = 0.0
    octant = (1 if ndx < 0.0 else 0) + (2 if ndy < 0.0 else 0) + (4 if ndz < 0.0 else 0)  # the near-first order
    k = node_start[OCTANTS * m + octant]
    end = node_start[OCTANTS * m + octant + 1]
    while k < end:
        if _box_entry(nox, noy, noz, ix, iy, iz, node_lo, node_hi, k, t_lo, best) == np.inf:
            k = node_skip[k]
            continue
        if node_count[k] == 0:
            k += 1  # into the first child
            continue
        for t in range(node_first[k], node_first[k] + node_count[k]):
            nx, ny, nz = tri_geom[t, 9], tri_geom[t, 10], tri_geom[t, 11]
            if ndx * nx + ndy * ny + ndz * nz >= 0.0:
                continue  # a back face: seen from inside the solid, or edge-on
            e1x, e1y, e1z = tri_geom[t, 3], tri_geom[t, 4], tri_geom[t, 5]
            e2x, e2y, e2z = tri_geom[t, 6], tri_geom[t, 7], tri_geom[t, 8]
            # Möller–Trumbore
            px = ndy * e2z - ndz * e2y
            py = ndz * e2x - ndx * e2z
            pz = ndx * e2y - ndy * e2x
            det = e1x * px + e1y * py + e1z * pz
            if abs(det) < 1e-18:
                continue
            inv = 1.0 / det
            qx0 = nox - tri_geom[t, 0]
            qy0 = noy - tri_geom[t, 1]
            qz0 = noz - tri_geom[t, 2]
            u = (qx0 * px + qy0 * py + qz0 * pz) * inv
            if u < 0.0 or u > 1.0:
                continue
            qx = qy0 * e1z - qz0 * e1y
            qy = qz0 * e1x - qx0 * e1z
            qz = qx0 * e1y - qy0 * e1x
            v = (ndx * qx + ndy * qy + ndz * qz) * inv
            if v < 0.0 or u + v > 1.0:
                continue
            tt = (e2x * qx + e2y * qy + e2z * qz) * inv
            if tt <= t_lo or tt >= best:
                continue
            best = tt
            hit = t
            # the normal in the box's metric frame: the normalised one over the scale (inverse transpose)
            mx, my, mz = nx / sx, ny / sy, nz / sz
            cos_hit = abs(dx * mx + dy * my + dz * mz) / np.sqrt(mx * mx + my * my + mz * mz)
        k += 1
    return best, hit, cos_hit

"""Night lighting for the RGB cameras: street lamps, headlight beams and histogram auto-exposure (numba kernels).

Pure functions over numpy arrays; nothing here imports the environment. :func:`render_night` draws a night
frame in one raster pass that lights, exposes and encodes each pixel as it is drawn (the surface map and face
colours hold albedo; the ground's irradiance comes from light maps, the faces' from small irradiance grids
over each lit box face); the per-pixel kernels live in :mod:`fog_gym.render.shading`. Depth, semantics and instance ids are never touched.

Light model (all in linear "albedo × irradiance" units, in which the day renderer's sun gives ≈ 0.45–1.05):

* irradiance of a point ``p`` with normal ``n`` from a light at ``q``:
  ``E = I · P(ω) · max(n·ω, 0) / max(d², 1 m²) · W(d)``, ``ω = (q − p)/d``, with Unreal's windowed inverse
  square ``W(d) = clamp(1 − (d/R)⁴, 0, 1)²`` that brings each light to exactly zero at its radius ``R``;
* street lamp (full cut-off luminaire): ``P = clamp(ω_z / 0.15, 0, 1)`` (light only below the lamp head);
* low beam, along the vehicle's heading: horizontally 1 within ±12° fading to 0 at ±22°; vertically a sharp
  cut-off above the horizon (``0.1·exp(−(φ/1.5°)²)`` for rays rising by φ), rising linearly from 0.1 at the
  horizon to 1 at the hot spot ``φ_h`` and ``(φ_h/φ)²`` below it, with
  ``φ_h = atan(h/45 m)``: the hot spot just under the cut-off reaches the road at 45 m and the pool fades out
  by ≈ 60 m (the road's irradiance ∝ I·h/d³ stays nearly flat from 10 to 45 m, as real beam patterns do);
* radiance ``L = albedo · (A + Σ E_l · colour_l)`` with the night ambient ``A``; emissive faces (lamps) emit
  ``albedo · EMISSIVE_GAIN``, the sky its colour × ``SKY_GAIN``; street-lamp heads are drawn as emissive discs
  (RGB only: they are not geometry, so depth and semantics stay unchanged).

No shadows: a light reaches every point within its radius that faces it (documented limitation).

Auto-exposure (in the spirit of CARLA's default ``exposure_mode = "histogram"``): per camera and frame (measured
on the view rendered :data:`EXPOSURE_DOWNSCALE`× smaller), a histogram of ``log2`` luminance over ``[LOG_MIN, LOG_MAX]``; the mean log luminance of the pixels between the
``LOW_PERCENT`` and ``HIGH_PERCENT`` of that histogram (the darkest half and the brightest 2 % — black sky,
lamp heads — do not steer it) is mapped to ``KEY``: ``gain = KEY / 2^mean``, clamped to ``[GAIN_MIN,
GAIN_MAX]`` (0 to +4 EV). Encoding: ``round(tone(L · gain) · 255)`` with a filmic-like shoulder (:func:`tone`)
that keeps headlit cars from clipping flat.

Example (one lamp 7 m above a grey floor point, straight down):
    >>> import numpy as np
    >>> e = irradiance(np.array([0.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]), street_lamp_lights(np.array([[0.0, 0.0, 7.0]])))
    >>> bool(round(float(e[0]), 4) == round(LAMP_INTENSITY / 49 * (1 - (7 / LAMP_RADIUS) ** 4) ** 2 * LAMP_COLOR[0], 4))
    True
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from typing import Any, NamedTuple

import numpy as np
from numba import njit, prange

import fog_gym._numba  # noqa: F401  (numba's fork-safe threading layer, before any kernel runs)
from fog_gym._numba import launch
from fog_gym.render.exposure import (GAIN_MAX, GAIN_MIN, HIGH_PERCENT, KEY, LOG_MAX, LOG_MIN, LOW_PERCENT, N_BINS,
                                     exposure_gains, gains_from_histograms)  # noqa: F401  (part of this module's API)
from fog_gym.world.meshlib import LIBRARY
from fog_gym.world.primitives import Primitives
from fog_gym.world.scene import lamp_heights
from fog_gym.render.shading import FACE_AXES, KNEE, draw_heads, face_irradiance, ground_irradiance, tone, tone_curve

LAMP, HEADLIGHT = 0, 1
#: Street lamp: luminous intensity in albedo·m² units, radius of influence [m], colour (warm white LED).
LAMP_INTENSITY, LAMP_RADIUS = 40.0, 40.0
LAMP_COLOR = np.array([1.0, 0.88, 0.70])
LAMP_HEAD_RADIUS = 0.3  # drawn disc [m]
LAMP_HEAD_RADIANCE = 6.0
#: Low beam: peak intensity (both lamps together), radius of influence [m], colour, hot-spot distance [m].
BEAM_INTENSITY, BEAM_RADIUS, BEAM_HOTSPOT = 4000.0, 60.0, 45.0
BEAM_COLOR = np.array([1.0, 0.97, 0.90])
BEAM_HALF_ANGLE, BEAM_FADE_ANGLE, BEAM_CUTOFF = math.radians(12.0), math.radians(22.0), math.radians(1.5)
#: Night ambient (sky glow) irradiance, emissive and sky radiance scales.
NIGHT_AMBIENT = 0.02
EMISSIVE_GAIN = 4.0
SKY_GAIN = 0.1
TILE = 32
MAX_LIGHTS = 4096


class Lights(NamedTuple):
    """Point lights: position (L, 3), unit axis (L, 3), colour (L, 3), intensity (L,), radius (L,), kind (L,) int64.

    ``kind`` is :data:`LAMP` (axis unused, emits downwards) or :data:`HEADLIGHT` (axis = horizontal heading).
    ``height`` (L,) is the lamp's height above the road (sets the beam's hot spot).
    """

    pos: np.ndarray
    axis: np.ndarray
    color: np.ndarray
    intensity: np.ndarray
    radius: np.ndarray
    kind: np.ndarray
    height: np.ndarray

    def __len__(self) -> int:
        return len(self.kind)


def _lights(pos, axis, color, intensity, radius, kind, height) -> Lights:
    n = len(pos)
    return Lights(
        np.ascontiguousarray(np.reshape(pos, (n, 3)), np.float64),
        np.ascontiguousarray(np.reshape(axis, (n, 3)), np.float64),
        np.ascontiguousarray(np.broadcast_to(color, (n, 3)), np.float64),
        np.ascontiguousarray(np.broadcast_to(intensity, (n,)), np.float64),
        np.ascontiguousarray(np.broadcast_to(radius, (n,)), np.float64),
        np.full(n, kind, np.int64),
        np.ascontiguousarray(np.broadcast_to(height, (n,)), np.float64),
    )


def street_lamp_lights(heads: np.ndarray) -> Lights:
    """Street lamps at the given head positions (N, 3)."""
    heads = np.asarray(heads, np.float64).reshape(-1, 3)
    axis = np.tile([0.0, 0.0, -1.0], (len(heads), 1))
    return _lights(heads, axis, LAMP_COLOR, LAMP_INTENSITY, LAMP_RADIUS, LAMP, heads[:, 2])


def headlight_lights(centers: np.ndarray, sizes: np.ndarray, yaws: np.ndarray, lamp_z: np.ndarray) -> Lights:
    """One low-beam source per vehicle, 0.3 m ahead of the front face at lamp height ``lamp_z`` (N,)."""
    centers, sizes = np.asarray(centers, np.float64).reshape(-1, 3), np.asarray(sizes, np.float64).reshape(-1, 3)
    yaws = np.asarray(yaws, np.float64).reshape(-1)
    fwd = np.c_[np.cos(yaws), np.sin(yaws), np.zeros_like(yaws)]
    pos = centers + fwd * (sizes[:, :1] / 2 + 0.3)
    pos[:, 2] = lamp_z
    return _lights(pos, fwd, BEAM_COLOR, BEAM_INTENSITY, BEAM_RADIUS, HEADLIGHT, lamp_z)


def headlights(state: Any) -> Lights:
    """Low beams of every vehicle of a :class:`~fog_gym.world.fleet.VehicleState` (the ego included) at its
    lamp height, pointing along its heading."""
    return headlight_lights(state.centers, state.sizes, state.yaws, lamp_heights(state))


def concat_lights(*groups: Lights) -> Lights:
    return Lights(*(np.ascontiguousarray(np.concatenate([getattr(g, f) for g in groups])) for f in Lights._fields))


def cull_lights(lights: Lights, center: np.ndarray, radius: float) -> Lights:
    """Lights whose sphere of influence comes within ``radius`` of ``center`` (at most :data:`MAX_LIGHTS`)."""
    d = np.linalg.norm(lights.pos - np.asarray(center, np.float64)[None, :], axis=1) - lights.radius
    keep = np.flatnonzero(d <= radius)[:MAX_LIGHTS]
    return Lights(*(np.ascontiguousarray(getattr(lights, f)[keep]) for f in Lights._fields))


@njit(cache=True, inline="always")
def _light_at(px, py, pz, nx, ny, nz, k, lpos, laxis, lint, lrad, lkind, lheight):
    """Irradiance weight (before colour) of light ``k`` at point p with normal n."""
    dx = lpos[k, 0] - px
    dy = lpos[k, 1] - py
    dz = lpos[k, 2] - pz
    d2 = dx * dx + dy * dy + dz * dz
    r2 = lrad[k] * lrad[k]
    if d2 >= r2:
        return 0.0
    d = math.sqrt(d2)
    if d < 1e-6:
        return 0.0
    wx, wy, wz = dx / d, dy / d, dz / d
    cosn = nx * wx + ny * wy + nz * wz
    if cosn <= 0.0:
        return 0.0
    q = d2 / r2
    win = 1.0 - q * q
    win *= win
    if lkind[k] == 0:  # street lamp: light below the head only
        prof = min(max(wz / 0.15, 0.0), 1.0)
    else:  # low beam: emission direction is -w
        ax, ay = laxis[k, 0], laxis[k, 1]
        fwd = -(wx * ax + wy * ay)
        if fwd <= 1e-6:
            return 0.0
        lat = abs(-(wx * -ay + wy * ax))
        psi = math.atan2(lat, fwd)
        if psi >= 0.3839724354387525:  # BEAM_FADE_ANGLE
            return 0.0
        h = 1.0
        if psi > 0.20943951023931953:  # BEAM_HALF_ANGLE
            h = (0.3839724354387525 - psi) / (0.3839724354387525 - 0.20943951023931953)
        # elevation of the emitted ray: positive = downwards (the point lies below the lamp)
        phi = math.atan2(wz, math.sqrt(fwd * fwd + lat * lat))
        if phi <= 0.0:
            v = 0.1 * math.exp(-(phi / 0.02617993877991494) ** 2)  # BEAM_CUTOFF
        else:
            ph = math.atan2(max(lheight[k], 0.1), 45.0)  # BEAM_HOTSPOT
            if phi >= ph:
                v = (ph / phi) ** 2
            else:  # between the cut-off and the hot spot: from a tenth up to full intensity
                v = 0.1 + 0.9 * phi / ph
        prof = h * v
    return lint[k] * prof * cosn / max(d2, 1.0) * win


def irradiance(point: np.ndarray, normal: np.ndarray, lights: Lights) -> np.ndarray:
    """RGB irradiance at one world point with unit ``normal`` from ``lights`` (no ambient): reference for tests."""
    e = np.zeros(3)
    for k in range(len(lights)):
        w = _light_at(float(point[0]), float(point[1]), float(point[2]), float(normal[0]), float(normal[1]),
                      float(normal[2]), k, lights.pos, lights.axis, lights.intensity, lights.radius, lights.kind,
                      lights.height)  # fmt: skip
        e += w * lights.color[k]
    return e


@njit(cache=True, nogil=True, parallel=True)
def _splat_ground(out, origin_x, origin_y, res, lpos, laxis, lcol, lint, lrad, lkind, lheight, add):
    """Ground (z = 0, normal up) irradiance of each light, splatted over its footprint into ``out`` (rows, cols, 3)."""
    rows, cols, _ = out.shape
    n_l = lpos.shape[0]
    # rows are split across threads; each thread visits every light's footprint rows it owns (no write races)
    n_tasks = min(rows, 64)
    for t in prange(n_tasks):
        for k in range(n_l):
            r = lrad[k]
            bx0, bx1 = lpos[k, 0] - r, lpos[k, 0] + r
            by0, by1 = lpos[k, 1] - r, lpos[k, 1] + r
            if lkind[k] == 1:  # a beam lights only its sector: bound the apex and the arc's extreme points
                bx0, bx1, by0, by1 = lpos[k, 0], lpos[k, 0], lpos[k, 1], lpos[k, 1]
                yaw = math.atan2(laxis[k, 1], laxis[k, 0])
                for q in range(9):
                    a = yaw + (q / 4.0 - 1.0) * 0.3839724354387525  # BEAM_FADE_ANGLE
                    ex = lpos[k, 0] + r * math.cos(a)
                    ey = lpos[k, 1] + r * math.sin(a)
                    bx0, bx1 = min(bx0, ex), max(bx1, ex)
                    by0, by1 = min(by0, ey), max(by1, ey)
            i0 = max(int((by0 - origin_y) / res), 0)
            i1 = min(int((by1 - origin_y) / res) + 1, rows)
            j0 = max(int((bx0 - origin_x) / res), 0)
            j1 = min(int((bx1 - origin_x) / res) + 1, cols)
            for i in range(i0, i1):
                if i % n_tasks != t:
                    continue
                y = origin_y + (i + 0.5) * res
                for j in range(j0, j1):
                    x = origin_x + (j + 0.5) * res
                    w = _light_at(x, y, 0.01, 0.0, 0.0, 1.0, k, lpos, laxis, lint, lrad, lkind, lheight)
                    if w > 0.0:
                        out[i, j, 0] += w * lcol[k, 0]
                        out[i, j, 1] += w * lcol[k, 1]
                        out[i, j, 2] += w * lcol[k, 2]


@njit(cache=True, nogil=True)
def _prim_lights(centers, halves, lpos, lrad, max_per):
    """For each primitive, the lights whose sphere of influence touches its bounding sphere (at most ``max_per``)."""
    n_p = centers.shape[0]
    idx = np.zeros((max(n_p, 1), max_per), np.int32)
    cnt = np.zeros(max(n_p, 1), np.int32)
    for p in range(n_p):
        rp = math.sqrt(halves[p, 0] ** 2 + halves[p, 1] ** 2 + halves[p, 2] ** 2)
        for k in range(lpos.shape[0]):
            dx = lpos[k, 0] - centers[p, 0]
            dy = lpos[k, 1] - centers[p, 1]
            dz = lpos[k, 2] - centers[p, 2]
            rr = lrad[k] + rp
            if dx * dx + dy * dy + dz * dz < rr * rr and cnt[p] < max_per:
                idx[p, cnt[p]] = k
                cnt[p] += 1
    return idx, cnt


@njit(cache=True, inline="always")
def _placed(v, center, sx, sy, sz, c, s):
    return center[0] + v[0] * sx * c - v[1] * sy * s, center[1] + v[0] * sx * s + v[1] * sy * c, center[2] + v[2] * sz


@njit(cache=True, nogil=True, parallel=True)
def _triangle_irradiance(centers, halves, yaws, meshes, emissive, prim_l, prim_n, lib_v, lib_t, tri_start, tri_base,
                         total, lpos, laxis, lcol, lint, lrad, lkind, lheight):  # fmt: skip
    """Irradiance (RGB, float32) at the centroid of every triangle of every lit mesh primitive, on its normal: row
    ``tri_base[p] + k`` for triangle k of primitive p (a mesh's triangles are small: one value each)."""
    out = np.zeros((max(total, 1), 3), np.float32)
    for p in prange(centers.shape[0]):
        m = meshes[p]
        if m == 0 or prim_n[p] == 0:
            continue
        c = math.cos(yaws[p])
        s = math.sin(yaws[p])
        sx, sy, sz = 2.0 * halves[p, 0], 2.0 * halves[p, 1], 2.0 * halves[p, 2]
        for t in range(tri_start[m], tri_start[m + 1]):
            ax, ay, az = _placed(lib_v[lib_t[t, 0]], centers[p], sx, sy, sz, c, s)
            bx, by, bz = _placed(lib_v[lib_t[t, 1]], centers[p], sx, sy, sz, c, s)
            dx, dy, dz = _placed(lib_v[lib_t[t, 2]], centers[p], sx, sy, sz, c, s)
            e1x, e1y, e1z = bx - ax, by - ay, bz - az
            e2x, e2y, e2z = dx - ax, dy - ay, dz - az
            nx = e1y * e2z - e1z * e2y
            ny = e1z * e2x - e1x * e2z
            nz = e1x * e2y - e1y * e2x
            inv = 1.0 / max(math.sqrt(nx * nx + ny * ny + nz * nz), 1e-30)
            nx *= inv
            ny *= inv
            nz *= inv
            px = (ax + bx + dx) / 3.0 + 0.01 * nx
            py = (ay + by + dy) / 3.0 + 0.01 * ny
            pz = (az + bz + dz) / 3.0 + 0.01 * nz
            e0 = e1 = e2 = 0.0
            for k in range(prim_n[p]):
                li = prim_l[p, k]
                w = _light_at(px, py, pz, nx, ny, nz, li, lpos, laxis, lint, lrad, lkind, lheight)
                if w > 0.0:
                    e0 += w * lcol[li, 0]
                    e1 += w * lcol[li, 1]
                    e2 += w * lcol[li, 2]
            o = tri_base[p] + t - tri_start[m]
            out[o, 0] = e0
            out[o, 1] = e1
            out[o, 2] = e2
    return out


_FACE_AXES = FACE_AXES
_FACE_SIGN = np.array([1.0, -1.0, 1.0, -1.0, 1.0, -1.0])


@njit(cache=True, nogil=True, parallel=True)
def _face_grids(centers, halves, yaws, emissive, prim_l, prim_n, lpos, laxis, lcol, lint, lrad, lkind, lheight,
                cell, max_cells):  # fmt: skip
    """Irradiance on a grid of points over each lit box face (bilinear between cell centres when shading).

    Returns offsets (P, 6) into ``data`` (−1: unlit face), dims (P, 6, 2) and ``data`` (N, 3) float32.
    """
    n_p = centers.shape[0]
    offsets = np.full((max(n_p, 1), 6), -1, np.int64)
    dims = np.ones((max(n_p, 1), 6, 2), np.int64)
    total = 0
    for p in range(n_p):
        if prim_n[p] == 0 or emissive[p]:
            continue
        for f in range(5):  # the bottom face (−z) is never seen from above the ground
            a1 = _FACE_AXES[f, 1]
            a2 = _FACE_AXES[f, 2]
            n1 = min(max(int(math.ceil(2.0 * halves[p, a1] / cell)), 1), max_cells)
            n2 = min(max(int(math.ceil(2.0 * halves[p, a2] / cell)), 1), max_cells)
            dims[p, f, 0] = n1
            dims[p, f, 1] = n2
            offsets[p, f] = total
            total += n1 * n2
    data = np.zeros((max(total, 1), 3), np.float32)
    for p in prange(n_p):
        if offsets[p, 0] < 0:
            continue
        cy = math.cos(yaws[p])
        sy = math.sin(yaws[p])
        for f in range(5):
            a0 = _FACE_AXES[f, 0]
            a1 = _FACE_AXES[f, 1]
            a2 = _FACE_AXES[f, 2]
            sign = _FACE_SIGN[f]
            n1 = dims[p, f, 0]
            n2 = dims[p, f, 1]
            loc = np.zeros(3)
            nl = np.zeros(3)
            nl[a0] = sign
            nx = nl[0] * cy - nl[1] * sy
            ny = nl[0] * sy + nl[1] * cy
            nz = nl[2]
            for u in range(n1):
                for v in range(n2):
                    loc[a0] = sign * halves[p, a0]
                    loc[a1] = ((u + 0.5) / n1 * 2.0 - 1.0) * halves[p, a1]
                    loc[a2] = ((v + 0.5) / n2 * 2.0 - 1.0) * halves[p, a2]
                    wx = centers[p, 0] + loc[0] * cy - loc[1] * sy + 0.01 * nx
                    wy = centers[p, 1] + loc[0] * sy + loc[1] * cy + 0.01 * ny
                    wz = centers[p, 2] + loc[2] + 0.01 * nz
                    e0, e1, e2 = 0.0, 0.0, 0.0
                    for s in range(prim_n[p]):
                        k = prim_l[p, s]
                        w = _light_at(wx, wy, wz, nx, ny, nz, k, lpos, laxis, lint, lrad, lkind, lheight)
                        if w > 0.0:
                            e0 += w * lcol[k, 0]
                            e1 += w * lcol[k, 1]
                            e2 += w * lcol[k, 2]
                    o = offsets[p, f] + u * n2 + v
                    data[o, 0] = e0
                    data[o, 1] = e1
                    data[o, 2] = e2
    return offsets, dims, data


@njit(cache=True, nogil=True, parallel=True, fastmath=False)
def _shade_pass(
    cam_rot, cam_trans, cam_k, far, rgb, depth, face, face_emis, face_prim, face_side,
    centers, halves, yaws, g_off, g_dims, g_data, tri_base, tri_irr,
    smap, s_ox, s_oy, s_inv, wmap, w_ox, w_oy, w_inv,
    ambient, emissive_gain, sky_gain, step, gains, knee, encode, hist, log_min, log_max,
):  # fmt: skip
    n_cam, height, width = depth.shape
    n_rows = (height + step - 1) // step
    n_bins = hist.shape[2]
    scale = n_bins / (log_max - log_min)
    for task in prange(n_cam * n_rows):
        c = task // n_rows
        i = (task % n_rows) * step
        R = cam_rot[c]
        T = cam_trans[c]
        fx, fy, cx, cy = cam_k[c, 0], cam_k[c, 1], cam_k[c, 2], cam_k[c, 3]
        yn = (i + 0.5 - cy) / fy
        g = gains[c]
        for j in range(0, width, step):
            z = depth[c, i, j]
            a0 = rgb[c, i, j, 0] * 0.00392156862745098
            a1 = rgb[c, i, j, 1] * 0.00392156862745098
            a2 = rgb[c, i, j, 2] * 0.00392156862745098
            if z >= far:
                l0, l1, l2 = a0 * sky_gain, a1 * sky_gain, a2 * sky_gain
            else:
                f = face[c, i, j]
                if f >= 0 and face_emis[c, f]:
                    l0, l1, l2 = a0 * emissive_gain, a1 * emissive_gain, a2 * emissive_gain
                else:
                    xc = (j + 0.5 - cx) / fx * z - T[0]
                    yc = yn * z - T[1]
                    zc = z - T[2]
                    wx = R[0, 0] * xc + R[1, 0] * yc + R[2, 0] * zc
                    wy = R[0, 1] * xc + R[1, 1] * yc + R[2, 1] * zc
                    if f < 0:  # ground: light maps (window near the ego, bilinear, with the beams; lamps beyond it)
                        e0, e1, e2 = ground_irradiance(wx, wy, ambient, wmap, w_ox, w_oy, w_inv, smap, s_ox,
                                                               s_oy, s_inv)
                    else:  # a face: bilinear in its irradiance grid
                        e0, e1, e2 = ambient, ambient, ambient
                        p = face_prim[c, f]
                        fs = face_side[c, f]
                        wz = R[0, 2] * xc + R[1, 2] * yc + R[2, 2] * zc
                        if fs < 0:  # a mesh's triangle: one value
                            q = tri_base[p] - 1 - fs
                            f0, f1, f2 = tri_irr[q, 0], tri_irr[q, 1], tri_irr[q, 2]
                        else:
                            f0, f1, f2 = face_irradiance(p, fs, wx, wy, wz, centers, halves, yaws, g_off, g_dims,
                                                         g_data)  # fmt: skip
                        e0 += f0
                        e1 += f1
                        e2 += f2
                    l0, l1, l2 = a0 * e0, a1 * e1, a2 * e2
            if encode:
                rgb[c, i, j, 0] = np.uint8(tone_curve(l0 * g, knee) * 255.0 + 0.5)
                rgb[c, i, j, 1] = np.uint8(tone_curve(l1 * g, knee) * 255.0 + 0.5)
                rgb[c, i, j, 2] = np.uint8(tone_curve(l2 * g, knee) * 255.0 + 0.5)
            else:
                y = 0.2126 * l0 + 0.7152 * l1 + 0.0722 * l2
                b = 0
                if y > 0.0:
                    b = min(max(int((math.log2(y) - log_min) * scale), 0), n_bins - 1)
                hist[c, task % n_rows, b] += 1


class GroundLightMap(NamedTuple):
    """Ground irradiance (rows, cols, 3) float32 on a grid: cell (0, 0)'s corner at ``origin``, ``resolution`` m."""

    irradiance: np.ndarray
    origin: tuple[float, float]
    resolution: float

    @classmethod
    def empty(cls) -> GroundLightMap:
        return cls(np.zeros((1, 1, 3), np.float32), (0.0, 0.0), 1.0)


#: Ground light maps: cell size [m]; half-width of the per-frame window (beams) around the ego [m].
MAP_RESOLUTION, WINDOW_HALF = 0.5, 120.0


def lamp_light_map(lamps: Lights, extent: tuple[float, float, float, float], resolution: float = MAP_RESOLUTION) -> GroundLightMap:
    """Street lamps' ground irradiance over ``extent`` = (x_min, x_max, y_min, y_max): built once per static world."""
    x0, x1, y0, y1 = extent
    rows, cols = max(1, int(math.ceil((y1 - y0) / resolution))), max(1, int(math.ceil((x1 - x0) / resolution)))
    out = np.zeros((rows, cols, 3), np.float32)
    if len(lamps):
        launch(_splat_ground)(out, float(x0), float(y0), float(resolution), *_light_args(lamps), True)
    return GroundLightMap(out, (float(x0), float(y0)), float(resolution))


def beam_window(static: GroundLightMap, beams: Lights, center: np.ndarray, half: float = WINDOW_HALF) -> GroundLightMap:
    """A window of ``static`` around ``center`` (snapped to its grid) with the low beams added."""
    res = static.resolution
    ox, oy = static.origin
    j0 = int(math.floor((center[0] - half - ox) / res))
    i0 = int(math.floor((center[1] - half - oy) / res))
    n = int(math.ceil(2 * half / res))
    out = np.zeros((n, n, 3), np.float32)
    rows, cols = static.irradiance.shape[:2]
    si0, sj0, si1, sj1 = max(i0, 0), max(j0, 0), min(i0 + n, rows), min(j0 + n, cols)
    if si1 > si0 and sj1 > sj0:
        out[si0 - i0 : si1 - i0, sj0 - j0 : sj1 - j0] = static.irradiance[si0:si1, sj0:sj1]
    origin = (ox + j0 * res, oy + i0 * res)
    if len(beams):
        launch(_splat_ground)(out, origin[0], origin[1], res, *_light_args(beams), True)
    return GroundLightMap(out, origin, res)


def _light_args(lights: Lights):
    return lights.pos, lights.axis, lights.color, lights.intensity, lights.radius, lights.kind, lights.height


#: Face irradiance grids: cell size [m] and at most this many cells along each side of a face.
FACE_CELL, FACE_MAX_CELLS = 1.0, 8
#: Lights per primitive at most (the nearest are not preferred: the first found are kept).
MAX_PRIM_LIGHTS = 16
#: The exposure histogram samples every ``EXPOSURE_STEP``-th pixel in each direction.
EXPOSURE_STEP = 4


#: The exposure of :func:`render_night` is measured on a render this many times smaller in each direction.
EXPOSURE_DOWNSCALE = 8


def render_night(
    cam_rot: np.ndarray, cam_trans: np.ndarray, cam_k: np.ndarray, width: int, height: int, far: float,
    prims: Primitives | Mapping[str, Any], surface, albedo_lut: np.ndarray, surface_tag: np.ndarray,
    sky_horizon: np.ndarray, sky_zenith: np.ndarray, lights: Lights, ground: tuple[GroundLightMap, GroundLightMap],
    heads: np.ndarray, ambient: float = NIGHT_AMBIENT, timings: dict[str, float] | None = None,
) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Render night frames in one lit pass; returns (buffers as :func:`~fog_gym.render.raster.render`, gains).

    ``timings``, when given, receives the process CPU time [ms] of each phase: ``"light set-up"`` (lights per
    primitive, face irradiance grids), ``"exposure"`` (step 1), ``"lit render"`` (step 2), ``"lamp heads"`` (step 3).

    1. the exposure: an albedo render :data:`EXPOSURE_DOWNSCALE`× smaller, lit by :func:`shade_night`'s
       kernel, gives the histogram and so the gain of each camera;
    2. the full-size render lights, exposes and encodes every pixel as it is drawn (ground from the light maps,
       faces from their irradiance grids, both read every few pixels and interpolated in between; see
       :mod:`fog_gym.render.raster`), so the night costs one raster pass plus small set-ups;
    3. the lamp heads are drawn on top.
    """
    from fog_gym.render.raster import render

    clock = [time.process_time()]

    def lap(phase: str) -> None:
        if timings is not None:
            now = time.process_time()
            timings[phase] = timings.get(phase, 0.0) + (now - clock[0]) * 1e3
            clock[0] = now

    n_cam = len(cam_rot)
    prims = Primitives.coerce(prims)
    prim_l, prim_n = _prim_lights(prims.centers, prims.halves, lights.pos, lights.radius, MAX_PRIM_LIGHTS)
    g_off, g_dims, g_data = launch(_face_grids)(prims.centers, prims.halves, prims.yaws, prims.emissive, prim_l,
                                        prim_n, *_light_args(lights), FACE_CELL, FACE_MAX_CELLS)  # fmt: skip
    cossin = np.ascontiguousarray(np.c_[np.cos(prims.yaws), np.sin(prims.yaws)])
    lib = LIBRARY.arrays()
    counts = np.where(prims.meshes > 0, lib.tri_start[prims.meshes + 1] - lib.tri_start[prims.meshes], 0)
    tri_base = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64) if len(counts) else np.zeros(1, np.int64)
    tri_irr = launch(_triangle_irradiance)(prims.centers, prims.halves, prims.yaws, prims.meshes, prims.emissive,
                                           prim_l, prim_n, lib.vertices, lib.triangles, lib.tri_start, tri_base,
                                           int(counts.sum()), *_light_args(lights))  # fmt: skip
    smap, wmap = ground
    lap("light set-up")
    # 1. exposure on a small render
    lw, lh = max(8, width // EXPOSURE_DOWNSCALE), max(8, height // EXPOSURE_DOWNSCALE)
    scale = np.array([lw / width, lh / height, lw / width, lh / height])
    k_low = np.asarray(cam_k, np.float64) * scale
    sun = np.array([0.0, 0.0, -1.0])
    low = render(cam_rot, cam_trans, k_low, lw, lh, far, prims, surface, albedo_lut, surface_tag, sky_horizon,
                 sky_zenith, sun, 1.0, 0.0, face_ids=True)  # fmt: skip
    hist = np.zeros((n_cam, lh, N_BINS), np.int64)
    launch(_shade_pass)(
        np.ascontiguousarray(cam_rot, np.float64), np.ascontiguousarray(cam_trans, np.float64), k_low, float(far),
        low["rgb"], low["depth"], low["face"], low["face_emissive"], low["face_prim"], low["face_side"],
        prims.centers, prims.halves, cossin, g_off, g_dims, g_data, tri_base, tri_irr,
        smap.irradiance, smap.origin[0], smap.origin[1], 1.0 / smap.resolution,
        wmap.irradiance, wmap.origin[0], wmap.origin[1], 1.0 / wmap.resolution,
        float(ambient), float(EMISSIVE_GAIN), float(SKY_GAIN), 1, np.ones(n_cam), float(KNEE), False, hist,
        LOG_MIN, LOG_MAX,
    )  # fmt: skip
    gains = gains_from_histograms(hist.sum(axis=1))
    lap("exposure")
    # 2. the lit full-size render
    night = {"gains": gains, "knee": KNEE, "ambient": ambient, "emissive_gain": EMISSIVE_GAIN, "sky_gain": SKY_GAIN,
             "window": wmap, "static": smap, "centers": prims.centers, "halves": prims.halves,
             "cossin": cossin, "g_off": g_off, "g_dims": g_dims, "g_data": g_data, "tri_base": tri_base,
             "tri_irr": tri_irr}  # fmt: skip
    out = render(cam_rot, cam_trans, cam_k, width, height, far, prims, surface, albedo_lut, surface_tag,
                 sky_horizon, sky_zenith, sun, 1.0, 0.0, night=night)  # fmt: skip
    lap("lit render")
    # 3. lamp heads
    heads = np.ascontiguousarray(np.reshape(heads, (-1, 3)), np.float64)
    rot, trans, ks = (np.ascontiguousarray(a, np.float64) for a in (cam_rot, cam_trans, cam_k))
    for c in range(n_cam):
        color = np.round(tone(LAMP_COLOR * LAMP_HEAD_RADIANCE * gains[c]) * 255).astype(np.uint8)
        draw_heads(rot[c : c + 1], trans[c : c + 1], ks[c : c + 1], out["depth"][c : c + 1], out["rgb"][c : c + 1],
                    heads, float(LAMP_HEAD_RADIUS), color)  # fmt: skip
    lap("lamp heads")
    return out, gains

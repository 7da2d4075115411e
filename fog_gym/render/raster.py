"""Multi-camera rasteriser for upright boxes over a textured ground plane (numba kernels).

Cost scales with the pixels each primitive covers, not with pixels × primitives:

1. per camera, every box is reduced to at most three front faces, clipped against the near plane and
   projected to convex screen polygons with an affine inverse-depth plane (``_setup_faces``);
2. the image is cut into row bands; each (camera, band) task, in parallel, first fills its rows with the
   analytic ground plane (ray/plane intersection + a road-surface map lookup) or the sky, then scan-converts
   the faces whose screen bounds touch the band, span by span, with a depth test.

At night (``night=``, built by :mod:`fog_gym.render.lights`) the same pass lights, exposes and encodes each pixel
as it is drawn: a ground row samples its light map every few pixels (at most half a map cell apart, every pixel
across a beam's edge) and a lit face span its irradiance grid every :data:`FACE_STEP` pixels, linear in between;
albedo × irradiance × gain is encoded through one tone table (:func:`night_tone_table`).

Outputs follow CARLA: planar depth (metres along the optical axis), sky at ``far``.
Pixel ``(i, j)`` is sampled at its centre ``(j + 0.5, i + 0.5)``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from numba import njit, prange

import fog_gym._numba  # noqa: F401  (numba's fork-safe threading layer, before any kernel runs)
from fog_gym._numba import pick, serial_twin
from fog_gym.render.shading import (FACE_AXES, FACE_STEP, TONE_STEPS, encode_tone, face_sample, fix_irradiance, grid_axis,
                                    grid_bilinear, light_ground, night_ground_row, night_tone_table, tone_at)  # fmt: skip
from fog_gym.render.surface import TiledSurface, surface_cell
from fog_gym.render.setup import setup_faces, setup_faces_serial
from fog_gym.render.shadows import ShadowMap
from fog_gym.world.mesh import MATERIAL_ALBEDO, MATERIAL_EMISSIVE, MATERIAL_PAINT, MATERIAL_TAG
from fog_gym.world.meshlib import LIBRARY
from fog_gym.world.primitives import Primitives

MAX_VERTS = 8
BAND_ROWS = 32


@njit(cache=True, inline="always")
def _surface_colour(fxw, fyw, surface, s_rows, s_cols, tiles_x, surf_lut, shadow_lut, shaded, surf_tag):
    """The colour (r, g, b) and semantic tag of the ground at surface-grid coordinates (fxw, fyw): from
    ``shadow_lut`` where ``shaded``, else from ``surf_lut``. It returns them and its callers write the pixel: a helper
    that wrote into the frame made numba count a reference to the frame's arrays at every pixel (two atomic operations
    each). The day's ground rows (:func:`_ground_row`, nearly every ground pixel) write their pixels in place."""
    cls, k = surface_cell(fxw, fyw, surface, s_rows, s_cols, tiles_x)
    if shaded:
        return shadow_lut[k, 0], shadow_lut[k, 1], shadow_lut[k, 2], surf_tag[cls]
    return surf_lut[k, 0], surf_lut[k, 1], surf_lut[k, 2], surf_tag[cls]


@njit(cache=True, inline="always")
def _in_map(shx, shy, shadow):
    """Whether shadow-map coordinates (shx, shy) lie in the map ``shadow`` (rows = y)."""
    return shx >= 0.0 and shy >= 0.0 and shy < shadow.shape[0] and shx < shadow.shape[1]


@njit(cache=True, inline="always")
def _ground_colour(fxw, fyw, surface, s_rows, s_cols, tiles_x, surf_lut, surf_tag, shadow, shx, shy, shadow_lut):
    """:func:`_surface_colour` of one ground pixel at surface-grid coordinates (fxw, fyw); in the sun's shadow
    (shadow-map cell (shx, shy) set) the ambient-only colours."""
    shaded = _in_map(shx, shy, shadow) and shadow[int(shy), int(shx)] != 0
    return _surface_colour(fxw, fyw, surface, s_rows, s_cols, tiles_x, surf_lut, shadow_lut, shaded, surf_tag)


@njit(cache=True, inline="always")
def _in_cell(shx, shy, shadow, ix, iy):
    """Whether shadow-map coordinates (shx, shy) lie in the map, in cell (ix, iy)."""
    return _in_map(shx, shy, shadow) and int(shx) == ix and int(shy) == iy


@njit(cache=True, inline="always")
def _ground_row(out_rgb, out_sem, out_depth, c, i, width, tf, fxw, fyw, kx, ky, surface, s_rows, s_cols, tiles_x,
                surf_lut, surf_tag, shadow, sh_x0, sh_y0, sh_k, shadow_lut):  # fmt: skip
    """A ground row by day: pixel j at surface-grid coordinates (fxw + kx·j, fyw + ky·j), at depth ``tf``, each as
    :func:`_ground_colour` colours it, but the shadow map read once per run of pixels in one of its cells. The map
    coordinates are monotone in j (every operation of ``sh_x0 + sh_k · (fxw + kx · j)`` rounds monotonically), so
    when a run's first and last pixels lie in the same cell, every pixel between does: a run's length is estimated
    from the distance to the cell's edges and its last pixel checked exactly (shortened until it holds)."""
    ax = sh_k * kx  # cells per pixel
    ay = sh_k * ky
    j = 0
    while j < width:
        shx = sh_x0 + sh_k * (fxw + kx * j)
        shy = sh_y0 + sh_k * (fyw + ky * j)
        n = 0  # pixels j … j + n form the run
        shaded = False
        if _in_map(shx, shy, shadow):
            ix = int(shx)
            iy = int(shy)
            shaded = shadow[iy, ix] != 0
            m = float(width - 1 - j)  # (a float until bounded: a near-zero slope gives no integer)
            if ax > 0.0:
                m = min(m, (ix + 1 - shx) / ax)
            elif ax < 0.0:
                m = min(m, (shx - ix) / -ax)
            if ay > 0.0:
                m = min(m, (iy + 1 - shy) / ay)
            elif ay < 0.0:
                m = min(m, (shy - iy) / -ay)
            n = int(m)
            tries = 0
            while n > 0:
                e = j + n
                if _in_cell(sh_x0 + sh_k * (fxw + kx * e), sh_y0 + sh_k * (fyw + ky * e), shadow, ix, iy):
                    break
                n = n - 1 if tries < 2 else n // 2
                tries += 1
        for jj in range(j, j + n + 1):  # the pixels written here, not through a helper that takes the tables: numba
            # counted a reference to each table at every pixel then (half of a 64 × 64 frame's raster)
            cls, k = surface_cell(fxw + kx * jj, fyw + ky * jj, surface, s_rows, s_cols, tiles_x)
            if shaded:
                out_rgb[c, i, jj, 0] = shadow_lut[k, 0]
                out_rgb[c, i, jj, 1] = shadow_lut[k, 1]
                out_rgb[c, i, jj, 2] = shadow_lut[k, 2]
            else:
                out_rgb[c, i, jj, 0] = surf_lut[k, 0]
                out_rgb[c, i, jj, 1] = surf_lut[k, 1]
                out_rgb[c, i, jj, 2] = surf_lut[k, 2]
            out_sem[c, i, jj] = surf_tag[cls]
            out_depth[c, i, jj] = tf
        j += n + 1


@njit(cache=True, nogil=True, parallel=True, fastmath=False)
def _raster_bands(
    cam_rot, cam_trans, cam_k, width, height, far,
    surface, s_rows, s_cols, tiles_x, surf_x0, surf_y0, surf_res, surf_lut, surf_tag,
    sky_horizon, sky_zenith,
    verts, nverts, planes, face_rgb, face_tag, face_inst, bounds, counts,
    out_rgb, out_depth, out_sem, out_inst, want_face, out_face,
    night, gains, knee, ambient, emis_gain, sky_gain, wmap, w_ox, w_oy, w_inv, smap, s_ox, s_oy, s_inv,
    face_emis, face_prim, face_side, centers, halves, cossin, g_off, g_dims, g_data, tri_base, tri_irr, tone,
    shadow, sh_ox, sh_oy, sh_inv, shadow_lut,
):  # fmt: skip
    n_cam = cam_rot.shape[0]
    # shadow-map cell coordinates as affine functions of surface-grid coordinates
    sh_k = surf_res * sh_inv
    sh_x0 = (surf_x0 - sh_ox) * sh_inv
    sh_y0 = (surf_y0 - sh_oy) * sh_inv
    n_bands = (height + BAND_ROWS - 1) // BAND_ROWS
    inv_res = 1.0 / surf_res
    for task in prange(n_cam * n_bands):
        c = task // n_bands
        r0 = (task % n_bands) * BAND_ROWS
        r1 = min(r0 + BAND_ROWS, height)
        escale = gains[c] * (TONE_STEPS / 255.0)
        R = cam_rot[c]
        T = cam_trans[c]
        fx, fy, cx, cy = cam_k[c, 0], cam_k[c, 1], cam_k[c, 2], cam_k[c, 3]
        ccx = -(R[0, 0] * T[0] + R[1, 0] * T[1] + R[2, 0] * T[2])
        ccy = -(R[0, 1] * T[0] + R[1, 1] * T[1] + R[2, 1] * T[2])
        ccz = -(R[0, 2] * T[0] + R[1, 2] * T[1] + R[2, 2] * T[2])
        # world direction of the camera ray r = ((u-cx)/fx, (v-cy)/fy, 1): d = R^T r, affine in u
        sx = R[0, 0] / fx
        sy = R[0, 1] / fx
        sz = R[0, 2] / fx
        out_inst[c, r0:r1] = 0
        if want_face:
            out_face[c, r0:r1] = -1
        for i in range(r0, r1):
            ry = (i + 0.5 - cy) / fy
            bx = R[2, 0] + R[1, 0] * ry
            by = R[2, 1] + R[1, 1] * ry
            bz = R[2, 2] + R[1, 2] * ry
            # sky colour for this row, from the ray through the image centre column (cosmetic gradient)
            mx = bx + sx * (0.5 * width + 0.5 - cx)
            my = by + sy * (0.5 * width + 0.5 - cx)
            mz = bz + sz * (0.5 * width + 0.5 - cx)
            e = max(mz / np.sqrt(mx * mx + my * my + mz * mz), 0.0)
            w = np.sqrt(e)
            s0 = np.uint8(sky_horizon[0] * (1.0 - w) + sky_zenith[0] * w)
            s1 = np.uint8(sky_horizon[1] * (1.0 - w) + sky_zenith[1] * w)
            s2 = np.uint8(sky_horizon[2] * (1.0 - w) + sky_zenith[2] * w)
            if night:
                ks = sky_gain * gains[c] * (1.0 / 255.0)
                s0 = encode_tone(s0 * ks, knee)
                s1 = encode_tone(s1 * ks, knee)
                s2 = encode_tone(s2 * ks, knee)
            if abs(sz) < 1e-15:
                # no roll: the ray's height component is constant along the row, so is the ground distance
                if bz < -1e-12 and -ccz / bz < far and -ccz / bz > 0.0:
                    t = -ccz / bz
                    fxw = (ccx + t * (bx + sx * (0.5 - cx)) - surf_x0) * inv_res
                    fyw = (ccy + t * (by + sy * (0.5 - cx)) - surf_y0) * inv_res
                    kx = t * sx * inv_res
                    ky = t * sy * inv_res
                    tf = np.float32(t)
                    if night:
                        night_ground_row(out_rgb, out_sem, out_depth, c, i, width, tf, fxw, fyw, kx, ky, surface,
                                          s_rows, s_cols, tiles_x, surf_lut, surf_tag, surf_x0, surf_y0, surf_res,
                                          escale, ambient, wmap, w_ox, w_oy, w_inv, smap, s_ox, s_oy, s_inv, tone)
                    else:
                        _ground_row(out_rgb, out_sem, out_depth, c, i, width, tf, fxw, fyw, kx, ky, surface, s_rows,
                                    s_cols, tiles_x, surf_lut, surf_tag, shadow, sh_x0, sh_y0, sh_k, shadow_lut)
                else:
                    for j in range(width):
                        out_rgb[c, i, j, 0] = s0
                        out_rgb[c, i, j, 1] = s1
                        out_rgb[c, i, j, 2] = s2
                    out_depth[c, i] = far
                    out_sem[c, i] = 11
                continue
            for j in range(width):
                u = j + 0.5 - cx
                dz = bz + sz * u
                t = far
                if dz < -1e-12:
                    t = -ccz / dz
                if t > 0.0 and t < far:
                    gx = (ccx + t * (bx + sx * u) - surf_x0) * inv_res
                    gy = (ccy + t * (by + sy * u) - surf_y0) * inv_res
                    r, g, b, tag = _ground_colour(gx, gy, surface, s_rows, s_cols, tiles_x, surf_lut, surf_tag, shadow,
                                                  sh_x0 + sh_k * gx, sh_y0 + sh_k * gy, shadow_lut)  # fmt: skip
                    out_rgb[c, i, j, 0], out_rgb[c, i, j, 1], out_rgb[c, i, j, 2], out_sem[c, i, j] = r, g, b, tag
                    out_depth[c, i, j] = t
                    if night:
                        light_ground(out_rgb, c, i, j, ccx + t * (bx + sx * u), ccy + t * (by + sy * u), gains[c],
                                      knee, ambient, wmap, w_ox, w_oy, w_inv, smap, s_ox, s_oy, s_inv)
                else:
                    out_rgb[c, i, j, 0] = s0
                    out_rgb[c, i, j, 1] = s1
                    out_rgb[c, i, j, 2] = s2
                    out_depth[c, i, j] = far
                    out_sem[c, i, j] = 11
        for f in range(counts[c]):
            fy0 = max(bounds[c, f, 0], r0)
            fy1 = min(bounds[c, f, 1], r1 - 1)
            if fy1 < fy0:
                continue
            m = nverts[c, f]
            fr0 = face_rgb[c, f, 0]
            fr1 = face_rgb[c, f, 1]
            fr2 = face_rgb[c, f, 2]
            lit = False
            p_f = 0
            s_f = 0
            g_o = 0
            gn1 = 1
            gn2 = 1
            g1x = g1y = g1z = go1 = g2x = g2y = g2z = go2 = 0.0
            fa0 = fa1 = fa2 = np.uint8(0)
            if night:
                p_f = face_prim[c, f]
                s_f = face_side[c, f]
                kf = gains[c] * (1.0 / 255.0)
                if face_emis[c, f]:
                    fr0 = encode_tone(face_rgb[c, f, 0] * kf * emis_gain, knee)
                    fr1 = encode_tone(face_rgb[c, f, 1] * kf * emis_gain, knee)
                    fr2 = encode_tone(face_rgb[c, f, 2] * kf * emis_gain, knee)
                elif s_f < 0:  # a mesh's triangle: its irradiance is one value (small triangles)
                    q = tri_base[p_f] - 1 - s_f
                    fr0 = encode_tone(face_rgb[c, f, 0] * kf * (ambient + tri_irr[q, 0]), knee)
                    fr1 = encode_tone(face_rgb[c, f, 1] * kf * (ambient + tri_irr[q, 1]), knee)
                    fr2 = encode_tone(face_rgb[c, f, 2] * kf * (ambient + tri_irr[q, 2]), knee)
                else:
                    lit = g_off[p_f, s_f] >= 0
                    fr0 = encode_tone(face_rgb[c, f, 0] * kf * ambient, knee)
                    fr1 = encode_tone(face_rgb[c, f, 1] * kf * ambient, knee)
                    fr2 = encode_tone(face_rgb[c, f, 2] * kf * ambient, knee)
                if lit:
                    # grid coordinates (s1, s2) of the face's irradiance grid are affine in the camera-frame point
                    # P = z·(xn, yn, 1): s = g·P + o (see face_irradiance for the same map from world points)
                    g_o = g_off[p_f, s_f]
                    gn1 = g_dims[p_f, s_f, 0]
                    gn2 = g_dims[p_f, s_f, 1]
                    g1x, g1y, g1z, go1 = grid_axis(R, ccx, ccy, ccz, p_f, FACE_AXES[s_f, 1], gn1, centers, halves, cossin)
                    g2x, g2y, g2z, go2 = grid_axis(R, ccx, ccy, ccz, p_f, FACE_AXES[s_f, 2], gn2, centers, halves, cossin)
                    fa0 = face_rgb[c, f, 0]
                    fa1 = face_rgb[c, f, 1]
                    fa2 = face_rgb[c, f, 2]
            pa = planes[c, f, 0]
            pb = planes[c, f, 1]
            pc = planes[c, f, 2]
            for i in range(fy0, fy1 + 1):
                v = i + 0.5
                lo = -1e30
                hi = 1e30
                empty = False
                for k in range(m):
                    k1 = (k + 1) % m
                    pu = verts[c, f, k, 0]
                    pv = verts[c, f, k, 1]
                    ex = verts[c, f, k1, 0] - pu
                    ey = verts[c, f, k1, 1] - pv
                    A = -ey
                    B = ex * (v - pv) + ey * pu
                    if A > 1e-12:
                        lo = max(lo, -B / A)
                    elif A < -1e-12:
                        hi = min(hi, -B / A)
                    elif B < 0.0:
                        empty = True
                        break
                if empty or hi < lo:
                    continue
                j0 = max(int(np.ceil(lo - 0.5)), bounds[c, f, 2])
                j1 = min(int(np.floor(hi - 0.5)), bounds[c, f, 3])
                rowz = pb * v + pc
                yn = (v - cy) / fy
                rb1 = g1y * yn + g1z
                rb2 = g2y * yn + g2z
                if lit:  # irradiance sampled every FACE_STEP pixels of the span, linear in between
                    ja = j0
                    sa1, sa2, a0, a1, a2 = face_sample(ja, pa, rowz, cx, fx, g1x, rb1, go1, g2x, rb2, go2, g_o, gn1,
                                                        gn2, g_data, ambient, escale)  # fmt: skip
                    while ja <= j1:
                        jb = min(ja + FACE_STEP, j1)
                        b0, b1, b2 = a0, a1, a2
                        sb1, sb2 = sa1, sa2
                        d0 = d1 = d2 = np.float32(0.0)
                        if jb > ja:
                            sb1, sb2, b0, b1, b2 = face_sample(jb, pa, rowz, cx, fx, g1x, rb1, go1, g2x, rb2, go2, g_o,
                                                                gn1, gn2, g_data, ambient, escale)  # fmt: skip
                            inv = np.float32(1.0 / (jb - ja))
                            d0 = (b0 - a0) * inv
                            d1 = (b1 - a1) * inv
                            d2 = (b2 - a2) * inv
                        last = jb == j1
                        exact = max(abs(sb1 - sa1), abs(sb2 - sa2)) > 1.0  # more than a grid cell: every pixel
                        for j in range(ja, jb + 1 if last else jb):
                            invz = pa * (j + 0.5) + rowz
                            if invz * out_depth[c, i, j] > 1.0:  # nearer than what is there (no division)
                                out_depth[c, i, j] = 1.0 / invz
                                t = np.float32(j - ja)
                                q0 = a0 + d0 * t
                                q1 = a1 + d1 * t
                                q2 = a2 + d2 * t
                                if exact and t > 0:
                                    zz = 1.0 / invz
                                    xn = (j + 0.5 - cx) / fx
                                    e0, e1, e2 = grid_bilinear(g_o, gn1, gn2, zz * (g1x * xn + rb1) + go1,
                                                                zz * (g2x * xn + rb2) + go2, g_data)  # fmt: skip
                                    q0 = fix_irradiance(ambient + e0, escale)
                                    q1 = fix_irradiance(ambient + e1, escale)
                                    q2 = fix_irradiance(ambient + e2, escale)
                                out_rgb[c, i, j, 0] = tone_at(tone, fa0, q0)
                                out_rgb[c, i, j, 1] = tone_at(tone, fa1, q1)
                                out_rgb[c, i, j, 2] = tone_at(tone, fa2, q2)
                                out_sem[c, i, j] = face_tag[c, f]
                                out_inst[c, i, j] = face_inst[c, f]
                                if want_face:
                                    out_face[c, i, j] = f
                        if last:
                            break
                        ja = jb
                        a0, a1, a2 = b0, b1, b2
                        sa1, sa2 = sb1, sb2
                    continue
                for j in range(j0, j1 + 1):
                    invz = pa * (j + 0.5) + rowz
                    if invz * out_depth[c, i, j] > 1.0:  # nearer than what is there (no division)
                        out_depth[c, i, j] = 1.0 / invz
                        out_rgb[c, i, j, 0] = fr0
                        out_rgb[c, i, j, 1] = fr1
                        out_rgb[c, i, j, 2] = fr2
                        out_sem[c, i, j] = face_tag[c, f]
                        out_inst[c, i, j] = face_inst[c, f]
                        if want_face:
                            out_face[c, i, j] = f


_raster_bands_serial = serial_twin(_raster_bands)


_NO_MAP = np.zeros((1, 1, 3), np.float32)


def _night_args(night: dict | None, n_cam: int) -> tuple:
    if night is None:
        return (False, np.ones(n_cam), 0.6, 0.0, 1.0, 1.0, _NO_MAP, 0.0, 0.0, 1.0, _NO_MAP, 0.0, 0.0, 1.0)
    w, s = night["window"], night["static"]
    return (True, np.ascontiguousarray(night["gains"], np.float64), float(night["knee"]), float(night["ambient"]),
            float(night["emissive_gain"]), float(night["sky_gain"]), w.irradiance, w.origin[0], w.origin[1],
            1.0 / w.resolution, s.irradiance, s.origin[0], s.origin[1], 1.0 / s.resolution)  # fmt: skip


_NO_TONE = np.zeros(1, np.uint8)
_TONE_TABLES: dict[float, np.ndarray] = {}


def _night_tone(night: dict | None) -> np.ndarray:
    if night is None:
        return _NO_TONE
    knee = float(night["knee"])
    if knee not in _TONE_TABLES:
        _TONE_TABLES[knee] = night_tone_table(knee)
    return _TONE_TABLES[knee]


#: A day frame's stand-ins for the night's arrays (read by no pixel of a day frame; made once).
_DAY_PRIMS = (np.zeros((1, 3)), np.zeros((1, 3)), np.zeros((1, 2)), np.full((1, 6), -1, np.int64),
              np.ones((1, 6, 2), np.int64), np.zeros((1, 3), np.float32), np.zeros(1, np.int64),
              np.zeros((1, 3), np.float32))  # fmt: skip


def _night_prims(night: dict | None) -> tuple:
    if night is None:
        return _DAY_PRIMS
    return (night["centers"], night["halves"], night["cossin"], night["g_off"], night["g_dims"], night["g_data"],
            night["tri_base"], night["tri_irr"])  # fmt: skip


def render(
    cam_rot: np.ndarray,
    cam_trans: np.ndarray,
    cam_k: np.ndarray,
    width: int,
    height: int,
    far: float,
    prims: Primitives | Mapping[str, Any],
    surface: TiledSurface,
    surface_lut_rgb: np.ndarray,
    surface_tag: np.ndarray,
    sky_horizon: np.ndarray,
    sky_zenith: np.ndarray,
    sun_dir: np.ndarray,
    ambient: float,
    sun_intensity: float,
    out: dict[str, np.ndarray] | None = None,
    face_ids: bool = False,
    night: dict | None = None,
    shadows: ShadowMap | None = None,
    shadow_lut: np.ndarray | None = None,
) -> dict[str, np.ndarray]:
    """Render ``C`` cameras of one resolution.

    ``cam_rot`` (C, 3, 3) and ``cam_trans`` (C, 3) map world to camera frame (``p_c = R p_w + t``);
    ``cam_k`` (C, 4) holds fx, fy, cx, cy. ``prims`` is a :class:`~fog_gym.world.primitives.Primitives` (or a mapping
    :meth:`~fog_gym.world.primitives.Primitives.coerce` accepts): ``centers`` (P, 3), ``halves`` (P, 3), ``yaws`` (P,),
    ``colors`` (P, 3) albedo in [0, 1], ``tags`` (P,) uint8, ``insts`` (P,) uint16, ``emissive`` (P,) bool.
    ``surface_lut_rgb`` comes from :func:`surface_lut`, ``surface_tag`` maps surface class → semantic tag.
    Returns ``rgb`` (C, H, W, 3) uint8, ``depth`` (C, H, W) float32, ``sem`` (C, H, W) uint8,
    ``inst`` (C, H, W) uint16. With ``face_ids`` (for lighting passes) also ``face`` (C, H, W) int32, the index of
    the face seen at each pixel (−1: ground or sky), ``face_normal`` (C, F, 3) float32 world-frame normals and
    ``face_emissive`` (C, F) bool, ``face_prim`` (C, F) int32 (the primitive each face belongs to) and
    ``face_side`` (C, F) int32 (a mesh's triangle k: −1 − k; a box: which of its
    six faces: +x, −x, +y, −y, +z, −z in the primitive's frame).

    ``night`` (from :func:`fog_gym.render.lights.night_inputs`) lights, exposes and encodes the RGB in the same
    pass (the surface map and face colours then hold albedo); depth, semantics and instances are unaffected.
    ``shadows`` (a :class:`~fog_gym.render.shadows.ShadowMap`) and ``shadow_lut`` (the ground's colours in shade)
    darken the ground where the sun's shadows fall.
    """
    prims = Primitives.coerce(prims)
    n_cam = cam_rot.shape[0]
    if out is None:
        out = {
            "rgb": np.empty((n_cam, height, width, 3), np.uint8),
            "depth": np.empty((n_cam, height, width), np.float32),
            "sem": np.empty((n_cam, height, width), np.uint8),
            "inst": np.empty((n_cam, height, width), np.uint16),
        }
    cam_rot = np.ascontiguousarray(cam_rot, np.float64)
    cam_trans = np.ascontiguousarray(cam_trans, np.float64)
    cam_k = np.ascontiguousarray(cam_k, np.float64)
    sm = ShadowMap.empty() if shadows is None else shadows
    lib = LIBRARY.arrays()
    faces = pick(setup_faces, setup_faces_serial, n_cam * int(width) * int(height) if n_cam > 1 else 0)(
        cam_rot, cam_trans, cam_k, int(width), int(height), float(far),
        prims.centers, prims.halves, prims.yaws, prims.colors, prims.tags, prims.insts, prims.emissive, prims.meshes,
        lib.vertices, lib.triangles, lib.materials, lib.tri_start, lib.tri_geom, MATERIAL_ALBEDO, MATERIAL_PAINT,
        MATERIAL_TAG, MATERIAL_EMISSIVE, np.asarray(sun_dir, np.float64), float(ambient), float(sun_intensity),
    )  # fmt: skip
    face = np.empty((n_cam, height, width), np.int32) if face_ids else np.empty((1, 1, 1), np.int32)
    pick(_raster_bands, _raster_bands_serial, n_cam * int(width) * int(height))(
        cam_rot, cam_trans, cam_k, int(width), int(height), float(far),
        surface.flat, surface.rows, surface.cols, surface.tiles_x, surface.origin[0], surface.origin[1],
        surface.resolution, surface_lut_rgb, np.asarray(surface_tag, np.uint8),
        np.asarray(sky_horizon, np.float64), np.asarray(sky_zenith, np.float64),
        *faces[:8], out["rgb"], out["depth"], out["sem"], out["inst"], bool(face_ids), face,
        *_night_args(night, n_cam), faces[9], faces[10], faces[11], *_night_prims(night),
        _night_tone(night), sm.grid, sm.origin[0], sm.origin[1], 1.0 / sm.resolution,
        surface_lut_rgb if shadow_lut is None else shadow_lut,
    )  # fmt: skip
    if face_ids:
        out = {**out, "face": face, "face_normal": faces[8], "face_emissive": faces[9], "face_prim": faces[10],
               "face_side": faces[11]}
    return out

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
from typing import Any, NamedTuple

import numpy as np
from numba import njit, prange

import fog_gym._numba  # noqa: F401  (numba's fork-safe threading layer, before any kernel runs)
from fog_gym.primitives import Primitives

# Box faces: corner indices (geometry.BOX_CORNER_SIGNS order) and local outward normals.
_FACE_CORNERS = np.array(
    [[0, 1, 5, 4], [2, 3, 7, 6], [0, 4, 7, 3], [1, 2, 6, 5], [4, 5, 6, 7], [0, 3, 2, 1]], dtype=np.int64
)
_FACE_NORMALS = np.array(
    [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=np.float64
)
_CORNER_SIGNS = np.array(
    [[1, 1, -1], [1, -1, -1], [-1, -1, -1], [-1, 1, -1], [1, 1, 1], [1, -1, 1], [-1, -1, 1], [-1, 1, 1]],
    dtype=np.float64,
)
MAX_VERTS = 8
NEAR = 0.05
BAND_ROWS = 32


@njit(cache=True, parallel=True, fastmath=False)
def _setup_faces(
    cam_rot, cam_trans, cam_k, width, height, far,
    centers, halves, yaws, colors, tags, insts, emissive,
    sun_dir, ambient, sun_intensity,
):  # fmt: skip
    n_cam = cam_rot.shape[0]
    n_prim = centers.shape[0]
    max_faces = 3 * n_prim
    verts = np.zeros((n_cam, max_faces, MAX_VERTS, 2))
    nverts = np.zeros((n_cam, max_faces), dtype=np.int64)
    planes = np.zeros((n_cam, max_faces, 3))
    face_rgb = np.zeros((n_cam, max_faces, 3), dtype=np.uint8)
    face_tag = np.zeros((n_cam, max_faces), dtype=np.uint8)
    face_inst = np.zeros((n_cam, max_faces), dtype=np.uint16)
    bounds = np.zeros((n_cam, max_faces, 4), dtype=np.int64)  # y0, y1, x0, x1 inclusive
    face_nrm = np.zeros((n_cam, max_faces, 3), dtype=np.float32)  # world-frame outward normal
    face_emis = np.zeros((n_cam, max_faces), dtype=np.bool_)
    face_prim = np.zeros((n_cam, max_faces), dtype=np.int32)
    face_side = np.zeros((n_cam, max_faces), dtype=np.int8)
    counts = np.zeros(n_cam, dtype=np.int64)
    for c in prange(n_cam):
        R = cam_rot[c]
        T = cam_trans[c]
        fx, fy, cx, cy = cam_k[c, 0], cam_k[c, 1], cam_k[c, 2], cam_k[c, 3]
        # camera centre in world: -R^T T
        ccx = -(R[0, 0] * T[0] + R[1, 0] * T[1] + R[2, 0] * T[2])
        ccy = -(R[0, 1] * T[0] + R[1, 1] * T[1] + R[2, 1] * T[2])
        ccz = -(R[0, 2] * T[0] + R[1, 2] * T[1] + R[2, 2] * T[2])
        n_out = 0
        corners_c = np.empty((8, 3))
        poly = np.empty((MAX_VERTS, 3))
        clipped = np.empty((MAX_VERTS, 3))
        for p in range(n_prim):
            cyaw = np.cos(yaws[p])
            syaw = np.sin(yaws[p])
            # quick reject: whole box beyond far or behind camera (bounding sphere)
            hx, hy, hz = halves[p, 0], halves[p, 1], halves[p, 2]
            radius = np.sqrt(hx * hx + hy * hy + hz * hz)
            pcx = R[0, 0] * centers[p, 0] + R[0, 1] * centers[p, 1] + R[0, 2] * centers[p, 2] + T[0]
            pcy = R[1, 0] * centers[p, 0] + R[1, 1] * centers[p, 1] + R[1, 2] * centers[p, 2] + T[1]
            pcz = R[2, 0] * centers[p, 0] + R[2, 1] * centers[p, 1] + R[2, 2] * centers[p, 2] + T[2]
            if pcz + radius < NEAR or pcz - radius > far:
                continue
            for k in range(8):
                lx = _CORNER_SIGNS[k, 0] * hx
                ly = _CORNER_SIGNS[k, 1] * hy
                wx = centers[p, 0] + lx * cyaw - ly * syaw
                wy = centers[p, 1] + lx * syaw + ly * cyaw
                wz = centers[p, 2] + _CORNER_SIGNS[k, 2] * hz
                corners_c[k, 0] = R[0, 0] * wx + R[0, 1] * wy + R[0, 2] * wz + T[0]
                corners_c[k, 1] = R[1, 0] * wx + R[1, 1] * wy + R[1, 2] * wz + T[1]
                corners_c[k, 2] = R[2, 0] * wx + R[2, 1] * wy + R[2, 2] * wz + T[2]
            for f in range(6):
                ln = _FACE_NORMALS[f]
                nwx = ln[0] * cyaw - ln[1] * syaw
                nwy = ln[0] * syaw + ln[1] * cyaw
                nwz = ln[2]
                # face centre in world
                fcx = centers[p, 0] + (ln[0] * hx) * cyaw - (ln[1] * hy) * syaw
                fcy = centers[p, 1] + (ln[0] * hx) * syaw + (ln[1] * hy) * cyaw
                fcz = centers[p, 2] + ln[2] * hz
                if nwx * (ccx - fcx) + nwy * (ccy - fcy) + nwz * (ccz - fcz) <= 1e-9:
                    continue  # back face
                # camera-frame normal and plane offset
                ncx = R[0, 0] * nwx + R[0, 1] * nwy + R[0, 2] * nwz
                ncy = R[1, 0] * nwx + R[1, 1] * nwy + R[1, 2] * nwz
                ncz = R[2, 0] * nwx + R[2, 1] * nwy + R[2, 2] * nwz
                c0 = corners_c[_FACE_CORNERS[f, 0]]
                d0 = ncx * c0[0] + ncy * c0[1] + ncz * c0[2]
                if d0 > -1e-9:
                    continue
                for k in range(4):
                    ck = corners_c[_FACE_CORNERS[f, k]]
                    poly[k, 0] = ck[0]
                    poly[k, 1] = ck[1]
                    poly[k, 2] = ck[2]
                # clip against z >= NEAR (Sutherland-Hodgman, one plane)
                m = 0
                zmin = 1e30
                for k in range(4):
                    a0 = poly[k]
                    a1 = poly[(k + 1) % 4]
                    in0 = a0[2] >= NEAR
                    in1 = a1[2] >= NEAR
                    if in0:
                        clipped[m, 0] = a0[0]
                        clipped[m, 1] = a0[1]
                        clipped[m, 2] = a0[2]
                        m += 1
                    if in0 != in1:
                        s = (NEAR - a0[2]) / (a1[2] - a0[2])
                        clipped[m, 0] = a0[0] + s * (a1[0] - a0[0])
                        clipped[m, 1] = a0[1] + s * (a1[1] - a0[1])
                        clipped[m, 2] = NEAR
                        m += 1
                if m < 3:
                    continue
                umin = 1e30
                umax = -1e30
                vmin = 1e30
                vmax = -1e30
                area = 0.0
                for k in range(m):
                    zk = clipped[k, 2]
                    if zk < zmin:
                        zmin = zk
                    u = fx * clipped[k, 0] / zk + cx
                    v = fy * clipped[k, 1] / zk + cy
                    verts[c, n_out, k, 0] = u
                    verts[c, n_out, k, 1] = v
                    umin = min(umin, u)
                    umax = max(umax, u)
                    vmin = min(vmin, v)
                    vmax = max(vmax, v)
                if zmin > far:
                    continue
                for k in range(m):
                    k1 = (k + 1) % m
                    area += verts[c, n_out, k, 0] * verts[c, n_out, k1, 1] - verts[c, n_out, k1, 0] * verts[c, n_out, k, 1]
                if area < 0.0:  # make orientation positive (interior where every edge function >= 0)
                    for k in range(m // 2):
                        k2 = m - 1 - k
                        tu = verts[c, n_out, k, 0]
                        tv = verts[c, n_out, k, 1]
                        verts[c, n_out, k, 0] = verts[c, n_out, k2, 0]
                        verts[c, n_out, k, 1] = verts[c, n_out, k2, 1]
                        verts[c, n_out, k2, 0] = tu
                        verts[c, n_out, k2, 1] = tv
                y0 = int(np.ceil(vmin - 0.5))
                y1 = int(np.floor(vmax - 0.5))
                x0 = int(np.ceil(umin - 0.5))
                x1 = int(np.floor(umax - 0.5))
                if y1 < 0 or x1 < 0 or y0 > height - 1 or x0 > width - 1 or y1 < y0 or x1 < x0:
                    continue
                bounds[c, n_out, 0] = max(y0, 0)
                bounds[c, n_out, 1] = min(y1, height - 1)
                bounds[c, n_out, 2] = max(x0, 0)
                bounds[c, n_out, 3] = min(x1, width - 1)
                nverts[c, n_out] = m
                # inverse depth as an affine function of (u, v)
                planes[c, n_out, 0] = ncx / fx / d0
                planes[c, n_out, 1] = ncy / fy / d0
                planes[c, n_out, 2] = (ncz - ncx * cx / fx - ncy * cy / fy) / d0
                if emissive[p]:
                    shade = 1.0
                else:
                    lam = nwx * sun_dir[0] + nwy * sun_dir[1] + nwz * sun_dir[2]
                    shade = ambient + sun_intensity * max(lam, 0.0)
                for ch in range(3):
                    val = colors[p, ch] * shade * 255.0
                    face_rgb[c, n_out, ch] = np.uint8(min(max(val, 0.0), 255.0))
                face_tag[c, n_out] = tags[p]
                face_inst[c, n_out] = insts[p]
                face_nrm[c, n_out, 0] = nwx
                face_nrm[c, n_out, 1] = nwy
                face_nrm[c, n_out, 2] = nwz
                face_emis[c, n_out] = emissive[p]
                face_prim[c, n_out] = p
                face_side[c, n_out] = f
                n_out += 1
        counts[c] = n_out
    return verts, nverts, planes, face_rgb, face_tag, face_inst, bounds, counts, face_nrm, face_emis, face_prim, face_side


@njit(cache=True, inline="always")
def _hash_noise(ix, iy):
    h = (ix * 73856093) ^ (iy * 19349663)
    h = (h ^ (h >> 13)) * 1274126177
    return (h >> 7) & 15


@njit(cache=True, inline="always")
def _surface_cell(fxw, fyw, surface, s_rows, s_cols, tiles_x):
    """Surface class at surface-grid coordinates (fxw, fyw) (0 off the map) and its colour-table row."""
    cls = 0
    gx = 0
    gy = 0
    if fxw >= 0.0 and fyw >= 0.0 and fxw < s_cols and fyw < s_rows:
        gx = int(fxw)
        gy = int(fyw)
        cls = surface[(((gy >> 3) * tiles_x + (gx >> 3)) << 6) + ((gy & 7) << 3) + (gx & 7)]
    return cls, cls * 16 + _hash_noise(gx, gy)


@njit(cache=True, inline="always")
def _ground_pixel(out_rgb, out_sem, c, i, j, fxw, fyw, surface, s_rows, s_cols, tiles_x, surf_lut, surf_tag):
    cls, k = _surface_cell(fxw, fyw, surface, s_rows, s_cols, tiles_x)
    out_rgb[c, i, j, 0] = surf_lut[k, 0]
    out_rgb[c, i, j, 1] = surf_lut[k, 1]
    out_rgb[c, i, j, 2] = surf_lut[k, 2]
    out_sem[c, i, j] = surf_tag[cls]


# -- night: lighting fused into the raster (fog_gym.render.lights builds the inputs) --------------------------
# box face axes: for face f, (normal axis, first in-plane axis, second in-plane axis) in the primitive's frame
FACE_AXES = np.array([[0, 1, 2], [0, 1, 2], [1, 0, 2], [1, 0, 2], [2, 0, 1], [2, 0, 1]], np.int64)


@njit(cache=True, inline="always")
def _enc(x, knee):
    """Exposed linear radiance → uint8 through the tone curve (linear to ``knee``, a smooth shoulder above)."""
    if x > knee:
        x = knee + (1.0 - knee) * (1.0 - np.exp(-(x - knee) / (1.0 - knee)))
    return np.uint8(x * 255.0 + 0.5)


@njit(cache=True, inline="always")
def _light_ground(out_rgb, c, i, j, wx, wy, g, knee, ambient, wmap, w_ox, w_oy, w_inv, smap, s_ox, s_oy, s_inv):
    e0, e1, e2 = _ground_irradiance(wx, wy, ambient, wmap, w_ox, w_oy, w_inv, smap, s_ox, s_oy, s_inv)
    k = g * (1.0 / 255.0)
    out_rgb[c, i, j, 0] = _enc(out_rgb[c, i, j, 0] * k * e0, knee)
    out_rgb[c, i, j, 1] = _enc(out_rgb[c, i, j, 1] * k * e1, knee)
    out_rgb[c, i, j, 2] = _enc(out_rgb[c, i, j, 2] * k * e2, knee)


@njit(cache=True, inline="always")
def _ground_irradiance(wx, wy, ambient, wmap, w_ox, w_oy, w_inv, smap, s_ox, s_oy, s_inv):
    """Irradiance (RGB, ambient included) of the ground at world (wx, wy): bilinear in the window map, nearest
    in the static map beyond it (nearest cell)."""
    e0 = ambient
    e1 = ambient
    e2 = ambient
    fi = (wy - w_oy) * w_inv - 0.5
    fj = (wx - w_ox) * w_inv - 0.5
    if fi >= 0.0 and fj >= 0.0 and fi < wmap.shape[0] - 1 and fj < wmap.shape[1] - 1:
        mi = int(fi)
        mj = int(fj)
        ti = fi - mi
        tj = fj - mj
        b00 = (1.0 - ti) * (1.0 - tj)
        b01 = (1.0 - ti) * tj
        b10 = ti * (1.0 - tj)
        b11 = ti * tj
        e0 += b00 * wmap[mi, mj, 0] + b01 * wmap[mi, mj + 1, 0] + b10 * wmap[mi + 1, mj, 0] + b11 * wmap[mi + 1, mj + 1, 0]
        e1 += b00 * wmap[mi, mj, 1] + b01 * wmap[mi, mj + 1, 1] + b10 * wmap[mi + 1, mj, 1] + b11 * wmap[mi + 1, mj + 1, 1]
        e2 += b00 * wmap[mi, mj, 2] + b01 * wmap[mi, mj + 1, 2] + b10 * wmap[mi + 1, mj, 2] + b11 * wmap[mi + 1, mj + 1, 2]
    else:
        fi = (wy - s_oy) * s_inv
        fj = (wx - s_ox) * s_inv
        if fi >= 0.0 and fj >= 0.0 and fi < smap.shape[0] and fj < smap.shape[1]:
            mi = int(fi)
            mj = int(fj)
            e0 += smap[mi, mj, 0]
            e1 += smap[mi, mj, 1]
            e2 += smap[mi, mj, 2]
    return e0, e1, e2


#: Night encoding: albedo (0–255) × exposed irradiance in units of ``255/TONE_STEPS`` (``E·gain·TONE_STEPS/255``,
#: float32) is the index of the exposed radiance in a tone table of :data:`TONE_STEPS` entries per unit up to
#: :data:`TONE_MAX` (the tone curve is 255 from ≈ 4 on): one product, one conversion and one lookup per channel,
#: at most a quarter of an 8-bit level from the exact ``round(tone(x)·255)``.
TONE_STEPS, TONE_MAX = 1024, 8
#: A ground row samples its irradiance every ``step`` pixels (linear in between), ``step`` pixels spanning at most
#: :data:`LIGHT_SPAN` window-map cells and at most :data:`MAX_LIGHT_STEP`; a face span every :data:`FACE_STEP`
#: pixels where that spans at most one cell of the face's grid (else every pixel).
MAX_LIGHT_STEP = 16
LIGHT_SPAN = 0.5
FACE_STEP = 8
#: Two ground samples further apart than this (in the encoding's units: two 8-bit levels on white) and than an
#: eighth of the smaller are not interpolated (beam edges): the pixels between them are lit one by one.
_JUMP = 8.0 / 255.0


def night_tone_table(knee: float) -> np.ndarray:
    """``table[i] = round(tone((i + ½)/TONE_STEPS)·255)`` (uint8): the night encoding of exposed radiance."""
    x = (np.arange(TONE_STEPS * TONE_MAX + 1) + 0.5) / TONE_STEPS
    y = np.where(x <= knee, x, knee + (1 - knee) * (1 - np.exp(-(np.maximum(x, knee) - knee) / (1 - knee))))
    return np.floor(y * 255.0 + 0.5).astype(np.uint8)


@njit(cache=True, inline="always")
def _fix(e, scale):
    """Irradiance ``e`` in the units of the night encoding (``scale`` = gain · TONE_STEPS/255), float32."""
    return np.float32(min(e * scale, 1e30))


@njit(cache=True, inline="always")
def _tone_at(tone, albedo, efix):
    return tone[np.int32(min(np.float32(albedo) * efix, np.float32(TONE_STEPS * TONE_MAX)))]


@njit(cache=True)
def _night_ground_row(out_rgb, out_sem, out_depth, c, i, width, tf, fxw, fyw, kx, ky, surface, s_rows, s_cols,
                      tiles_x, surf_lut, surf_tag, surf_x0, surf_y0, surf_res, escale, ambient, wmap, w_ox, w_oy,
                      w_inv, smap, s_ox, s_oy, s_inv, tone):  # fmt: skip
    """Draw, light, expose and encode a ground row (every pixel of it ground): pixel ``j`` sees surface-map
    coordinates (fxw + j·kx, fyw + j·ky). The irradiance is sampled every ``step`` pixels (``step`` pixels spanning
    at most :data:`LIGHT_SPAN` cells of the window map) and interpolated linearly in between."""
    dwx = kx * surf_res
    dwy = ky * surf_res
    wx0 = surf_x0 + fxw * surf_res
    wy0 = surf_y0 + fyw * surf_res
    cpp = max(abs(dwx), abs(dwy)) * w_inv  # window cells per pixel
    step = 1
    if cpp * MAX_LIGHT_STEP <= LIGHT_SPAN:
        step = MAX_LIGHT_STEP
    elif cpp * 2.0 <= LIGHT_SPAN:
        step = int(LIGHT_SPAN / cpp)
    e0, e1, e2 = _ground_irradiance(wx0, wy0, ambient, wmap, w_ox, w_oy, w_inv, smap, s_ox, s_oy, s_inv)
    a0 = _fix(e0, escale)
    a1 = _fix(e1, escale)
    a2 = _fix(e2, escale)
    j0 = 0
    while True:
        j1 = min(j0 + step, width - 1)
        b0, b1, b2 = a0, a1, a2
        d0 = d1 = d2 = np.float32(0.0)
        if j1 > j0:
            e0, e1, e2 = _ground_irradiance(wx0 + dwx * j1, wy0 + dwy * j1, ambient, wmap, w_ox, w_oy, w_inv, smap,
                                            s_ox, s_oy, s_inv)  # fmt: skip
            b0 = _fix(e0, escale)
            b1 = _fix(e1, escale)
            b2 = _fix(e2, escale)
            inv = np.float32(1.0 / (j1 - j0))
            d0 = (b0 - a0) * inv
            d1 = (b1 - a1) * inv
            d2 = (b2 - a2) * inv
        last = j1 == width - 1
        # samples more than an eighth and two levels apart (a beam's edge): every pixel between them is lit exactly
        jump = max(abs(b0 - a0) - max(0.125 * min(a0, b0), _JUMP), abs(b1 - a1) - max(0.125 * min(a1, b1), _JUMP),
                   abs(b2 - a2) - max(0.125 * min(a2, b2), _JUMP))  # fmt: skip
        exact = jump > 0
        q0, q1, q2 = a0, a1, a2
        for j in range(j0, j1 + 1 if last else j1):
            cls, k = _surface_cell(fxw + kx * j, fyw + ky * j, surface, s_rows, s_cols, tiles_x)
            if exact and j > j0:
                e0, e1, e2 = _ground_irradiance(wx0 + dwx * j, wy0 + dwy * j, ambient, wmap, w_ox, w_oy, w_inv, smap,
                                                s_ox, s_oy, s_inv)  # fmt: skip
                q0 = _fix(e0, escale)
                q1 = _fix(e1, escale)
                q2 = _fix(e2, escale)
            out_rgb[c, i, j, 0] = _tone_at(tone, surf_lut[k, 0], q0)
            out_rgb[c, i, j, 1] = _tone_at(tone, surf_lut[k, 1], q1)
            out_rgb[c, i, j, 2] = _tone_at(tone, surf_lut[k, 2], q2)
            out_sem[c, i, j] = surf_tag[cls]
            out_depth[c, i, j] = tf
            q0 += d0
            q1 += d1
            q2 += d2
        if last:
            break
        j0 = j1
        a0, a1, a2 = b0, b1, b2


@njit(cache=True, inline="always")
def _grid_bilinear(o, n1, n2, s1, s2, g_data):
    """Bilinear read of an ``n1 × n2`` irradiance grid at ``data[o:]`` at grid coordinates (s1, s2), clamped."""
    s1 = min(max(s1, 0.0), n1 - 1.0)
    s2 = min(max(s2, 0.0), n2 - 1.0)
    u0 = min(int(s1), n1 - 1)
    v0 = min(int(s2), n2 - 1)
    u1 = min(u0 + 1, n1 - 1)
    v1 = min(v0 + 1, n2 - 1)
    fu = s1 - u0
    fv = s2 - v0
    w00 = (1.0 - fu) * (1.0 - fv)
    w01 = (1.0 - fu) * fv
    w10 = fu * (1.0 - fv)
    w11 = fu * fv
    k00 = o + u0 * n2 + v0
    k01 = o + u0 * n2 + v1
    k10 = o + u1 * n2 + v0
    k11 = o + u1 * n2 + v1
    e0 = w00 * g_data[k00, 0] + w01 * g_data[k01, 0] + w10 * g_data[k10, 0] + w11 * g_data[k11, 0]
    e1 = w00 * g_data[k00, 1] + w01 * g_data[k01, 1] + w10 * g_data[k10, 1] + w11 * g_data[k11, 1]
    e2 = w00 * g_data[k00, 2] + w01 * g_data[k01, 2] + w10 * g_data[k10, 2] + w11 * g_data[k11, 2]
    return e0, e1, e2


@njit(cache=True, inline="always")
def _face_sample(j, pa, rowz, cx, fx, g1x, rb1, go1, g2x, rb2, go2, g_o, gn1, gn2, g_data, ambient, escale):
    """Grid coordinates and fixed-point irradiance of a lit face's span at pixel column ``j`` (row terms given)."""
    zz = 1.0 / (pa * (j + 0.5) + rowz)
    xn = (j + 0.5 - cx) / fx
    s1 = zz * (g1x * xn + rb1) + go1
    s2 = zz * (g2x * xn + rb2) + go2
    e0, e1, e2 = _grid_bilinear(g_o, gn1, gn2, s1, s2, g_data)
    return s1, s2, _fix(ambient + e0, escale), _fix(ambient + e1, escale), _fix(ambient + e2, escale)


@njit(cache=True, inline="always")
def _grid_axis(R, ccx, ccy, ccz, p, ax, n, centers, halves, cossin):
    """Coefficients (gx, gy, gz, o) of grid coordinate ``s = g·P + o`` along local axis ``ax`` (``n`` cells) of
    primitive ``p``'s face grid for a camera-frame point ``P`` (camera rotation ``R``, centre ``cc`` in the world)."""
    if ax == 0:
        ux, uy, uz = cossin[p, 0], cossin[p, 1], 0.0
    elif ax == 1:
        ux, uy, uz = -cossin[p, 1], cossin[p, 0], 0.0
    else:
        ux, uy, uz = 0.0, 0.0, 1.0
    sc = 0.5 * n / halves[p, ax]
    gx = (R[0, 0] * ux + R[0, 1] * uy + R[0, 2] * uz) * sc
    gy = (R[1, 0] * ux + R[1, 1] * uy + R[1, 2] * uz) * sc
    gz = (R[2, 0] * ux + R[2, 1] * uy + R[2, 2] * uz) * sc
    o = (ux * (ccx - centers[p, 0]) + uy * (ccy - centers[p, 1]) + uz * (ccz - centers[p, 2])) * sc + 0.5 * n - 0.5
    return gx, gy, gz, o


@njit(cache=True, inline="always")
def face_irradiance(p, fs, wx, wy, wz, centers, halves, cossin, g_off, g_dims, g_data):
    """Bilinear irradiance (RGB) of face ``fs`` of primitive ``p`` at world point w from its grid (0 if unlit)."""
    o = g_off[p, fs]
    if o < 0:
        return 0.0, 0.0, 0.0
    dx = wx - centers[p, 0]
    dy = wy - centers[p, 1]
    lx = dx * cossin[p, 0] + dy * cossin[p, 1]
    ly = -dx * cossin[p, 1] + dy * cossin[p, 0]
    lz = wz - centers[p, 2]
    ax1 = FACE_AXES[fs, 1]
    ax2 = FACE_AXES[fs, 2]
    q1 = lx if ax1 == 0 else ly
    q2 = ly if ax2 == 1 else lz
    n1 = g_dims[p, fs, 0]
    n2 = g_dims[p, fs, 1]
    s1 = (q1 / halves[p, ax1] + 1.0) * 0.5 * n1 - 0.5
    s2 = (q2 / halves[p, ax2] + 1.0) * 0.5 * n2 - 0.5
    return _grid_bilinear(o, n1, n2, s1, s2, g_data)


@njit(cache=True, parallel=True, fastmath=False)
def _raster_bands(
    cam_rot, cam_trans, cam_k, width, height, far,
    surface, s_rows, s_cols, tiles_x, surf_x0, surf_y0, surf_res, surf_lut, surf_tag,
    sky_horizon, sky_zenith,
    verts, nverts, planes, face_rgb, face_tag, face_inst, bounds, counts,
    out_rgb, out_depth, out_sem, out_inst, want_face, out_face,
    night, gains, knee, ambient, emis_gain, sky_gain, wmap, w_ox, w_oy, w_inv, smap, s_ox, s_oy, s_inv,
    face_emis, face_prim, face_side, centers, halves, cossin, g_off, g_dims, g_data, tone,
):  # fmt: skip
    n_cam = cam_rot.shape[0]
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
                s0 = _enc(s0 * ks, knee)
                s1 = _enc(s1 * ks, knee)
                s2 = _enc(s2 * ks, knee)
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
                        _night_ground_row(out_rgb, out_sem, out_depth, c, i, width, tf, fxw, fyw, kx, ky, surface,
                                          s_rows, s_cols, tiles_x, surf_lut, surf_tag, surf_x0, surf_y0, surf_res,
                                          escale, ambient, wmap, w_ox, w_oy, w_inv, smap, s_ox, s_oy, s_inv, tone)
                    else:
                        for j in range(width):
                            _ground_pixel(out_rgb, out_sem, c, i, j, fxw + kx * j, fyw + ky * j, surface,
                                          s_rows, s_cols, tiles_x, surf_lut, surf_tag)
                            out_depth[c, i, j] = tf
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
                    _ground_pixel(out_rgb, out_sem, c, i, j, (ccx + t * (bx + sx * u) - surf_x0) * inv_res,
                                  (ccy + t * (by + sy * u) - surf_y0) * inv_res, surface,
                                  s_rows, s_cols, tiles_x, surf_lut, surf_tag)
                    out_depth[c, i, j] = t
                    if night:
                        _light_ground(out_rgb, c, i, j, ccx + t * (bx + sx * u), ccy + t * (by + sy * u), gains[c],
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
                    fr0 = _enc(face_rgb[c, f, 0] * kf * emis_gain, knee)
                    fr1 = _enc(face_rgb[c, f, 1] * kf * emis_gain, knee)
                    fr2 = _enc(face_rgb[c, f, 2] * kf * emis_gain, knee)
                else:
                    lit = g_off[p_f, s_f] >= 0
                    fr0 = _enc(face_rgb[c, f, 0] * kf * ambient, knee)
                    fr1 = _enc(face_rgb[c, f, 1] * kf * ambient, knee)
                    fr2 = _enc(face_rgb[c, f, 2] * kf * ambient, knee)
                if lit:
                    # grid coordinates (s1, s2) of the face's irradiance grid are affine in the camera-frame point
                    # P = z·(xn, yn, 1): s = g·P + o (see face_irradiance for the same map from world points)
                    g_o = g_off[p_f, s_f]
                    gn1 = g_dims[p_f, s_f, 0]
                    gn2 = g_dims[p_f, s_f, 1]
                    g1x, g1y, g1z, go1 = _grid_axis(R, ccx, ccy, ccz, p_f, FACE_AXES[s_f, 1], gn1, centers, halves, cossin)
                    g2x, g2y, g2z, go2 = _grid_axis(R, ccx, ccy, ccz, p_f, FACE_AXES[s_f, 2], gn2, centers, halves, cossin)
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
                    sa1, sa2, a0, a1, a2 = _face_sample(ja, pa, rowz, cx, fx, g1x, rb1, go1, g2x, rb2, go2, g_o, gn1,
                                                        gn2, g_data, ambient, escale)  # fmt: skip
                    while ja <= j1:
                        jb = min(ja + FACE_STEP, j1)
                        b0, b1, b2 = a0, a1, a2
                        sb1, sb2 = sa1, sa2
                        d0 = d1 = d2 = np.float32(0.0)
                        if jb > ja:
                            sb1, sb2, b0, b1, b2 = _face_sample(jb, pa, rowz, cx, fx, g1x, rb1, go1, g2x, rb2, go2, g_o,
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
                                    e0, e1, e2 = _grid_bilinear(g_o, gn1, gn2, zz * (g1x * xn + rb1) + go1,
                                                                zz * (g2x * xn + rb2) + go2, g_data)  # fmt: skip
                                    q0 = _fix(ambient + e0, escale)
                                    q1 = _fix(ambient + e1, escale)
                                    q2 = _fix(ambient + e2, escale)
                                out_rgb[c, i, j, 0] = _tone_at(tone, fa0, q0)
                                out_rgb[c, i, j, 1] = _tone_at(tone, fa1, q1)
                                out_rgb[c, i, j, 2] = _tone_at(tone, fa2, q2)
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


def _night_prims(night: dict | None) -> tuple:
    if night is None:
        z3 = np.zeros((1, 3))
        return (z3, z3, np.zeros((1, 2)), np.full((1, 6), -1, np.int64), np.ones((1, 6, 2), np.int64),
                np.zeros((1, 3), np.float32))  # fmt: skip
    return night["centers"], night["halves"], night["cossin"], night["g_off"], night["g_dims"], night["g_data"]


class TiledSurface(NamedTuple):
    """A road-surface class map stored in 8×8 tiles (one cache line each), for fast lookups from any view."""

    flat: np.ndarray  # uint8, tiled
    rows: int
    cols: int
    tiles_x: int
    origin: tuple[float, float]  # world (x, y) of cell (0, 0)'s corner
    resolution: float  # metres per cell


def tile_surface(grid: np.ndarray, origin: tuple[float, float], resolution: float) -> TiledSurface:
    """Convert a row-major (rows = world y, cols = world x) class grid into :class:`TiledSurface`."""
    rows, cols = grid.shape
    ty, tx = -(-rows // 8), -(-cols // 8)
    padded = np.zeros((ty * 8, tx * 8), np.uint8)
    padded[:rows, :cols] = grid
    flat = np.ascontiguousarray(padded.reshape(ty, 8, tx, 8).transpose(0, 2, 1, 3)).reshape(-1)
    return TiledSurface(flat, rows, cols, tx, (float(origin[0]), float(origin[1])), float(resolution))


def surface_lut(class_rgb: np.ndarray, texture_amp: float) -> np.ndarray:
    """Per-class shaded colours with 16 texture levels: ``(n_classes * 16, 3)`` uint8."""
    base = np.asarray(class_rgb, np.float64)[:, None, :]
    levels = (np.arange(16) - 7.5)[None, :, None] * texture_amp
    return np.clip(np.rint(base + levels), 0, 255).astype(np.uint8).reshape(-1, 3)


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
) -> dict[str, np.ndarray]:
    """Render ``C`` cameras of one resolution.

    ``cam_rot`` (C, 3, 3) and ``cam_trans`` (C, 3) map world to camera frame (``p_c = R p_w + t``);
    ``cam_k`` (C, 4) holds fx, fy, cx, cy. ``prims`` is a :class:`~fog_gym.primitives.Primitives` (or a mapping
    :meth:`~fog_gym.primitives.Primitives.coerce` accepts): ``centers`` (P, 3), ``halves`` (P, 3), ``yaws`` (P,),
    ``colors`` (P, 3) albedo in [0, 1], ``tags`` (P,) uint8, ``insts`` (P,) uint16, ``emissive`` (P,) bool.
    ``surface_lut_rgb`` comes from :func:`surface_lut`, ``surface_tag`` maps surface class → semantic tag.
    Returns ``rgb`` (C, H, W, 3) uint8, ``depth`` (C, H, W) float32, ``sem`` (C, H, W) uint8,
    ``inst`` (C, H, W) uint16. With ``face_ids`` (for lighting passes) also ``face`` (C, H, W) int32, the index of
    the face seen at each pixel (−1: ground or sky), ``face_normal`` (C, F, 3) float32 world-frame normals and
    ``face_emissive`` (C, F) bool, ``face_prim`` (C, F) int32 (the primitive each face belongs to) and
    ``face_side`` (C, F) int8 (which of its
    six faces: +x, −x, +y, −y, +z, −z in the primitive's frame).

    ``night`` (from :func:`fog_gym.render.lights.night_inputs`) lights, exposes and encodes the RGB in the same
    pass (the surface map and face colours then hold albedo); depth, semantics and instances are unaffected.
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
    faces = _setup_faces(
        cam_rot, cam_trans, cam_k, int(width), int(height), float(far),
        prims.centers, prims.halves, prims.yaws, prims.colors, prims.tags, prims.insts,
        prims.emissive, np.asarray(sun_dir, np.float64), float(ambient), float(sun_intensity),
    )  # fmt: skip
    face = np.empty((n_cam, height, width), np.int32) if face_ids else np.empty((1, 1, 1), np.int32)
    _raster_bands(
        cam_rot, cam_trans, cam_k, int(width), int(height), float(far),
        surface.flat, surface.rows, surface.cols, surface.tiles_x, surface.origin[0], surface.origin[1],
        surface.resolution, surface_lut_rgb, np.asarray(surface_tag, np.uint8),
        np.asarray(sky_horizon, np.float64), np.asarray(sky_zenith, np.float64),
        *faces[:8], out["rgb"], out["depth"], out["sem"], out["inst"], bool(face_ids), face,
        *_night_args(night, n_cam), faces[9], faces[10], faces[11], *_night_prims(night),
        _night_tone(night),
    )  # fmt: skip
    if face_ids:
        out = {**out, "face": face, "face_normal": faces[8], "face_emissive": faces[9], "face_prim": faces[10],
               "face_side": faces[11]}
    return out

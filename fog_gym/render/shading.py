"""Night shading kernels: what a lit pixel costs (numba, inlined into the renderers' loops).

Both renderers use these public functions: the one-pass night raster of :mod:`fog_gym.render.raster` (a ground row
samples its light map every few pixels, a lit face span its irradiance grid every :data:`FACE_STEP` pixels) and the
light-map code of :mod:`fog_gym.render.lights`. Light model, exposure and tone curve are described in
:mod:`fog_gym.render.lights`; here live the per-pixel pieces: the ground's irradiance from the light maps
(:func:`ground_irradiance`), a face's from its grid (:func:`face_irradiance`), the tone curve (:func:`tone`) and the
night encoding through one table (:func:`night_tone_table`, :func:`tone_at`).

Example:
    >>> float(tone(0.3)), float(tone(2.0)) < 1.0
    (0.3, True)
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from fog_gym.render.surface import surface_cell


#: Highlight shoulder of the encoding: linear up to ``KNEE``, then ``KNEE + (1 − KNEE)(1 − e^{−(x − KNEE)/(1 − KNEE)})``.
KNEE = 0.6
# box face axes: for face f, (normal axis, first in-plane axis, second in-plane axis) in the primitive's frame
FACE_AXES = np.array([[0, 1, 2], [0, 1, 2], [1, 0, 2], [1, 0, 2], [2, 0, 1], [2, 0, 1]], np.int64)


@njit(cache=True, inline="always")
def encode_tone(x, knee):
    """Exposed linear radiance → uint8 through the tone curve (linear to ``knee``, a smooth shoulder above)."""
    if x > knee:
        x = knee + (1.0 - knee) * (1.0 - np.exp(-(x - knee) / (1.0 - knee)))
    return np.uint8(x * 255.0 + 0.5)


@njit(cache=True, inline="always")
def light_ground(out_rgb, c, i, j, wx, wy, g, knee, ambient, wmap, w_ox, w_oy, w_inv, smap, s_ox, s_oy, s_inv):
    e0, e1, e2 = ground_irradiance(wx, wy, ambient, wmap, w_ox, w_oy, w_inv, smap, s_ox, s_oy, s_inv)
    k = g * (1.0 / 255.0)
    out_rgb[c, i, j, 0] = encode_tone(out_rgb[c, i, j, 0] * k * e0, knee)
    out_rgb[c, i, j, 1] = encode_tone(out_rgb[c, i, j, 1] * k * e1, knee)
    out_rgb[c, i, j, 2] = encode_tone(out_rgb[c, i, j, 2] * k * e2, knee)


@njit(cache=True, inline="always")
def ground_irradiance(wx, wy, ambient, wmap, w_ox, w_oy, w_inv, smap, s_ox, s_oy, s_inv):
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
def fix_irradiance(e, scale):
    """Irradiance ``e`` in the units of the night encoding (``scale`` = gain · TONE_STEPS/255), float32."""
    return np.float32(min(e * scale, 1e30))


@njit(cache=True, inline="always")
def tone_at(tone, albedo, efix):
    return tone[np.int32(min(np.float32(albedo) * efix, np.float32(TONE_STEPS * TONE_MAX)))]


@njit(cache=True, nogil=True)
def night_ground_row(out_rgb, out_sem, out_depth, c, i, width, tf, fxw, fyw, kx, ky, surface, s_rows, s_cols,
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
    e0, e1, e2 = ground_irradiance(wx0, wy0, ambient, wmap, w_ox, w_oy, w_inv, smap, s_ox, s_oy, s_inv)
    a0 = fix_irradiance(e0, escale)
    a1 = fix_irradiance(e1, escale)
    a2 = fix_irradiance(e2, escale)
    j0 = 0
    while True:
        j1 = min(j0 + step, width - 1)
        b0, b1, b2 = a0, a1, a2
        d0 = d1 = d2 = np.float32(0.0)
        if j1 > j0:
            e0, e1, e2 = ground_irradiance(wx0 + dwx * j1, wy0 + dwy * j1, ambient, wmap, w_ox, w_oy, w_inv, smap,
                                            s_ox, s_oy, s_inv)  # fmt: skip
            b0 = fix_irradiance(e0, escale)
            b1 = fix_irradiance(e1, escale)
            b2 = fix_irradiance(e2, escale)
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
            cls, k = surface_cell(fxw + kx * j, fyw + ky * j, surface, s_rows, s_cols, tiles_x)
            if exact and j > j0:
                e0, e1, e2 = ground_irradiance(wx0 + dwx * j, wy0 + dwy * j, ambient, wmap, w_ox, w_oy, w_inv, smap,
                                                s_ox, s_oy, s_inv)  # fmt: skip
                q0 = fix_irradiance(e0, escale)
                q1 = fix_irradiance(e1, escale)
                q2 = fix_irradiance(e2, escale)
            out_rgb[c, i, j, 0] = tone_at(tone, surf_lut[k, 0], q0)
            out_rgb[c, i, j, 1] = tone_at(tone, surf_lut[k, 1], q1)
            out_rgb[c, i, j, 2] = tone_at(tone, surf_lut[k, 2], q2)
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
def grid_bilinear(o, n1, n2, s1, s2, g_data):
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
def face_sample(j, pa, rowz, cx, fx, g1x, rb1, go1, g2x, rb2, go2, g_o, gn1, gn2, g_data, ambient, escale):
    """Grid coordinates and fixed-point irradiance of a lit face's span at pixel column ``j`` (row terms given)."""
    zz = 1.0 / (pa * (j + 0.5) + rowz)
    xn = (j + 0.5 - cx) / fx
    s1 = zz * (g1x * xn + rb1) + go1
    s2 = zz * (g2x * xn + rb2) + go2
    e0, e1, e2 = grid_bilinear(g_o, gn1, gn2, s1, s2, g_data)
    return s1, s2, fix_irradiance(ambient + e0, escale), fix_irradiance(ambient + e1, escale), fix_irradiance(ambient + e2, escale)


@njit(cache=True, inline="always")
def grid_axis(R, ccx, ccy, ccz, p, ax, n, centers, halves, cossin):
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
    return grid_bilinear(o, n1, n2, s1, s2, g_data)


@njit(cache=True, inline="always")
def tone_curve(x, knee):
    """The tone curve of one exposed radiance (linear up to ``knee``, a smooth shoulder to 1 above)."""
    if x <= knee:
        return x
    return knee + (1.0 - knee) * (1.0 - math.exp(-(x - knee) / (1.0 - knee)))


def tone(x: np.ndarray | float) -> np.ndarray:
    """The encoding's tone curve on exposed radiance (identity below :data:`KNEE`, a smooth shoulder to 1 above).

    >>> tone(np.array([0.3, 0.6, 1.0, 100.0])).round(3).tolist()
    [0.3, 0.6, 0.853, 1.0]
    """
    x = np.asarray(x, np.float64)
    return np.where(x <= KNEE, x, KNEE + (1 - KNEE) * (1 - np.exp(-(np.maximum(x, KNEE) - KNEE) / (1 - KNEE))))


@njit(cache=True, nogil=True)
def draw_heads(cam_rot, cam_trans, cam_k, depth, rgb, heads, head_rad, color):
    """Lamp heads as discs (RGB only) where nothing nearer hides them; ``color`` is the encoded uint8 triple."""
    n_cam, height, width = depth.shape
    for c in range(n_cam):
        R = cam_rot[c]
        T = cam_trans[c]
        fx, fy, cx, cy = cam_k[c, 0], cam_k[c, 1], cam_k[c, 2], cam_k[c, 3]
        for k in range(heads.shape[0]):
            pxc = R[0, 0] * heads[k, 0] + R[0, 1] * heads[k, 1] + R[0, 2] * heads[k, 2] + T[0]
            pyc = R[1, 0] * heads[k, 0] + R[1, 1] * heads[k, 1] + R[1, 2] * heads[k, 2] + T[1]
            pzc = R[2, 0] * heads[k, 0] + R[2, 1] * heads[k, 1] + R[2, 2] * heads[k, 2] + T[2]
            if pzc < 0.5:
                continue
            u = fx * pxc / pzc + cx
            v = fy * pyc / pzc + cy
            rp = max(fx * head_rad / pzc, 0.75)
            for i in range(max(int(v - rp), 0), min(int(v + rp) + 1, height)):
                for j in range(max(int(u - rp), 0), min(int(u + rp) + 1, width)):
                    du = j + 0.5 - u
                    dv = i + 0.5 - v
                    if du * du + dv * dv <= rp * rp and pzc < depth[c, i, j]:
                        rgb[c, i, j, 0] = color[0]
                        rgb[c, i, j, 1] = color[1]
                        rgb[c, i, j, 2] = color[2]

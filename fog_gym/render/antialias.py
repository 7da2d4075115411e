"""Anti-aliasing of the RGB cameras: filtered ground and morphological edge anti-aliasing (numba kernels).

The rasteriser samples each pixel at its centre, so a pixel takes whatever its centre sees: the ground's texels
and shadow borders come out as hard staircases (and far away, where a pixel spans many texels, one texel picked at
random: the shimmer of a moving camera), and every object's outline as a staircase. Two passes fix the RGB of a
camera with ``antialias=True``; depth, semantics and instance ids stay point-sampled (CARLA's are):

1. :func:`filter_ground` (by day): each ground pixel whose footprint covers more than one texel or shadow cell
   takes the mean colour of the surface over its footprint — its corners traced to the ground, an ``n × n`` grid
   of rays with ``n`` the footprint's extent in texels + 1 (at most :data:`MAX_GROUND_SAMPLES`) — the box filter a
   mip-mapped, anisotropic texture lookup approximates, computed exactly from the surface map;
2. :func:`antialias`: morphological anti-aliasing (Reshetov, "Morphological antialiasing", HPG 2009) on the
   geometry's edges — between pixels of different objects (instance ids) or across a depth step of more than
   :data:`DEPTH_STEP` (an occlusion; the sky is far) — found from the buffers the camera renders anyway, not from
   colour: each straight run of edge between two rows (or columns) that ends in one-pixel stair steps is read as a
   slanted edge through the steps' midpoints (L, Z and U shapes; a longer climb is a corner and gets no blend),
   and each pixel of the run is blended with its neighbour across the edge by the area that line leaves to it.

What it does not do: geometry finer than a pixel that no centre sample hit (a far pole, a thin branch) stays
missing, and colour edges inside one object (windows on a wall) keep their stairs.

Example (a 45° edge drawn as a staircase: the pixels along it become blends):
    >>> img = np.zeros((6, 6, 3), np.uint8)
    >>> for i in range(6):
    ...     img[i, : i + 1] = 200  # a bright object below the diagonal
    >>> inst = np.where(img[..., 0] > 0, 5, 0).astype(np.uint16)
    >>> out = antialias(img, np.ones((6, 6), np.float32), np.zeros((6, 6), np.uint8), inst)
    >>> out[2, :5, 0].tolist()
    [200, 200, 150, 50, 0]
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit, prange

import fog_gym._numba  # noqa: F401  (numba's fork-safe threading layer, before any kernel runs)
from fog_gym._numba import pick, serial_twin
from fog_gym.render.surface import surface_cell

#: Neighbours of one object whose depths differ by more than this fraction of the nearer share an edge (an occlusion).
DEPTH_STEP = 0.1


@njit(cache=True, inline="always")
def _luma(rgb, i, j):
    return 0.299 * rgb[i, j, 0] + 0.587 * rgb[i, j, 1] + 0.114 * rgb[i, j, 2]


@njit(cache=True, inline="always")
def _differ(rgb, depth, sem, inst, i0, j0, i1, j1, thr, step):
    if inst[i0, j0] != inst[i1, j1]:
        return True
    d0, d1 = depth[i0, j0], depth[i1, j1]
    if abs(d0 - d1) > step * min(d0, d1):
        return True
    return abs(_luma(rgb, i0, j0) - _luma(rgb, i1, j1)) > thr


@njit(cache=True, inline="always")
def _parts(hp, hq, length):
    """Integrals of max(h, 0) and max(−h, 0) of a linear h from hp to hq over ``length``."""
    if hp >= 0.0 and hq >= 0.0:
        return 0.5 * (hp + hq) * length, 0.0
    if hp <= 0.0 and hq <= 0.0:
        return 0.0, -0.5 * (hp + hq) * length
    r = hp / (hp - hq) * length  # the zero crossing
    if hp > 0.0:
        return 0.5 * hp * r, -0.5 * hq * (length - r)
    return 0.5 * hq * (length - r), -0.5 * hp * r


@njit(cache=True, inline="always")
def _height(s, a, b1, hl, hr):
    """The reconstructed edge's offset from the pixel border at position s of a run [a, b1)."""
    if hl != 0.0 and hr != 0.0 and (hl > 0.0) == (hr > 0.0):  # U: down to the border at the middle and back
        mid = 0.5 * (a + b1)
        if s <= mid:
            return hl * (mid - s) / (mid - a)
        return hr * (s - mid) / (b1 - mid)
    return hl + (hr - hl) * (s - a) / (b1 - a)


@njit(cache=True, nogil=True, parallel=True)
def _mlaa_kernel(rgb, depth, sem, inst, thr, step, out):
    height, width, _ = rgb.shape
    # edges: eh[i, j] between (i, j) and (i + 1, j); ev[i, j] between (i, j) and (i, j + 1)
    eh = np.zeros((max(height - 1, 0), width), np.bool_)
    ev = np.zeros((height, max(width - 1, 0)), np.bool_)
    for i in prange(height):
        for j in range(width):
            if i + 1 < height:
                eh[i, j] = _differ(rgb, depth, sem, inst, i, j, i + 1, j, thr, step)
            if j + 1 < width:
                ev[i, j] = _differ(rgb, depth, sem, inst, i, j, i, j + 1, thr, step)
    # blend weights toward the neighbour across: up (i − 1), down (i + 1), left, right
    w_up = np.zeros((height, width), np.float32)
    w_down = np.zeros((height, width), np.float32)
    w_left = np.zeros((height, width), np.float32)
    w_right = np.zeros((height, width), np.float32)
    for i in prange(height - 1):  # runs of horizontal edges between rows i and i + 1
        j = 0
        while j < width:
            if not eh[i, j]:
                j += 1
                continue
            a = j
            while j < width and eh[i, j]:
                j += 1
            b1 = j  # the run is [a, b1)
            # a stair step at an end: the edge climbs one pixel there and runs on along the next row boundary (a
            # longer climb is a corner of the shape, not a step of a slanted edge: no blend)
            top_l = a > 0 and i > 0 and ev[i, a - 1] and eh[i - 1, a - 1]
            bot_l = a > 0 and i + 1 < height - 1 and ev[i + 1, a - 1] and eh[i + 1, a - 1]
            top_r = b1 < width and i > 0 and ev[i, b1 - 1] and eh[i - 1, b1]
            bot_r = b1 < width and i + 1 < height - 1 and ev[i + 1, b1 - 1] and eh[i + 1, b1]
            hl = 0.5 if top_l and not bot_l else (-0.5 if bot_l and not top_l else 0.0)
            hr = 0.5 if top_r and not bot_r else (-0.5 if bot_r and not top_r else 0.0)
            if hl == 0.0 and hr == 0.0:
                continue
            for x in range(a, b1):
                pos, neg = _segment(x, a, b1, hl, hr)
                w_down[i, x] = pos  # the top pixel takes the bottom's colour over the area above the border
                w_up[i + 1, x] = neg
    for j in prange(width - 1):  # runs of vertical edges between columns j and j + 1
        i = 0
        while i < height:
            if not ev[i, j]:
                i += 1
                continue
            a = i
            while i < height and ev[i, j]:
                i += 1
            b1 = i
            lft_l = a > 0 and j > 0 and eh[a - 1, j] and ev[a - 1, j - 1]
            rgt_l = a > 0 and j + 1 < width - 1 and eh[a - 1, j + 1] and ev[a - 1, j + 1]
            lft_r = b1 < height and j > 0 and eh[b1 - 1, j] and ev[b1, j - 1]
            rgt_r = b1 < height and j + 1 < width - 1 and eh[b1 - 1, j + 1] and ev[b1, j + 1]
            hl = 0.5 if lft_l and not rgt_l else (-0.5 if rgt_l and not lft_l else 0.0)
            hr = 0.5 if lft_r and not rgt_r else (-0.5 if rgt_r and not lft_r else 0.0)
            if hl == 0.0 and hr == 0.0:
                continue
            for y in range(a, b1):
                pos, neg = _segment(y, a, b1, hl, hr)
                w_right[y, j] = pos
                w_left[y, j + 1] = neg
    for i in prange(height):
        for j in range(width):
            wu, wd, wl, wr = w_up[i, j], w_down[i, j], w_left[i, j], w_right[i, j]
            if wu == 0.0 and wd == 0.0 and wl == 0.0 and wr == 0.0:
                for ch in range(3):
                    out[i, j, ch] = rgb[i, j, ch]
                continue
            for ch in range(3):
                c = np.float32(rgb[i, j, ch])
                v = c
                if wu > 0.0:
                    v += wu * (rgb[i - 1, j, ch] - c)
                if wd > 0.0:
                    v += wd * (rgb[i + 1, j, ch] - c)
                if wl > 0.0:
                    v += wl * (rgb[i, j - 1, ch] - c)
                if wr > 0.0:
                    v += wr * (rgb[i, j + 1, ch] - c)
                out[i, j, ch] = np.uint8(min(max(v + 0.5, 0.0), 255.0))
    return out


@njit(cache=True, inline="always")
def _segment(x, a, b1, hl, hr):
    """Areas above (positive) and below (negative) the border that the reconstructed edge leaves in pixel x."""
    h0 = _height(x, a, b1, hl, hr)
    h1 = _height(x + 1.0, a, b1, hl, hr)
    if hl != 0.0 and hr != 0.0 and (hl > 0.0) == (hr > 0.0):
        mid = 0.5 * (a + b1)
        if x < mid < x + 1.0:  # the U's middle inside the pixel: two linear pieces
            hm = 0.0
            p0, n0 = _parts(h0, hm, mid - x)
            p1, n1 = _parts(hm, h1, x + 1.0 - mid)
            return p0 + p1, n0 + n1
    return _parts(h0, h1, 1.0)


_mlaa_kernel_serial = serial_twin(_mlaa_kernel)


def antialias(rgb: np.ndarray, depth: np.ndarray, semantic: np.ndarray, instance: np.ndarray,
              depth_step: float = DEPTH_STEP, luma_threshold: float | None = None) -> np.ndarray:  # fmt: skip
    """``rgb`` (H, W, 3) uint8 anti-aliased along its geometry's edges (module docstring), from the camera's
    point-sampled ``depth`` and ``instance`` ids of the same frame (``semantic``: checked for shape); a new array.
    ``luma_threshold`` (0–255) also takes colour edges (FXAA's and SMAA's habit; off by default: on fog-gym's frames
    it blurs the texture that the ground filter already anti-aliased, see ``docs/sensors.md``)."""
    img = np.ascontiguousarray(rgb)
    if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8:
        raise ValueError(f"rgb must be an (H, W, 3) uint8 image, got {img.dtype} {img.shape}")
    for name, a in (("depth", depth), ("semantic", semantic), ("instance", instance)):
        if np.shape(a) != img.shape[:2]:
            raise ValueError(f"{name} must be (H, W) = {img.shape[:2]}, got {np.shape(a)}")
    out = np.empty_like(img)
    kernel = pick(_mlaa_kernel, _mlaa_kernel_serial, img.shape[0] * img.shape[1])
    return kernel(img, np.ascontiguousarray(depth, np.float32), np.ascontiguousarray(semantic),
                  np.ascontiguousarray(instance), np.inf if luma_threshold is None else float(luma_threshold),
                  float(depth_step), out)  # fmt: skip


# -- filtered ground ------------------------------------------------------------------------------------------------
#: At most this many samples per axis of a ground pixel's footprint.
MAX_GROUND_SAMPLES = 4


@njit(cache=True, inline="always")
def _ground_at(ccx, ccy, ccz, bx, by, bz, sx, sy, sz, u, cx, far, x0, y0, inv_res):
    """Surface-grid coordinates where the ray through column position u (of a row with base direction b) meets the
    ground, and whether it does within ``far``."""
    dx = bx + sx * (u - cx)
    dy = by + sy * (u - cx)
    dz = bz + sz * (u - cx)
    if dz >= -1e-12:
        return 0.0, 0.0, False
    t = -ccz / dz
    if not (0.0 < t < far):
        return 0.0, 0.0, False
    return (ccx + t * dx - x0) * inv_res, (ccy + t * dy - y0) * inv_res, True


@njit(cache=True, inline="always")
def _cell_key(fx, fy, sh_x0, sh_y0, sh_k, shadow):
    """The texel and shadow cell of surface-grid point (fx, fy): the pixel is one colour when its corners share it."""
    shx = sh_x0 + sh_k * fx
    shy = sh_y0 + sh_k * fy
    s = -1
    if shx >= 0.0 and shy >= 0.0 and shy < shadow.shape[0] and shx < shadow.shape[1]:
        s = int(shy) * shadow.shape[1] + int(shx)
    return int(np.floor(fx)), int(np.floor(fy)), s


@njit(cache=True, nogil=True, parallel=True)
def _ground_kernel(cam_rot, cam_trans, cam_k, cams, far, surface, s_rows, s_cols, tiles_x, x0, y0, res, lut,
                   shadow_lut, shadow, sh_ox, sh_oy, sh_inv, sky_horizon, sky_zenith, depth, inst, rgb, max_n):  # fmt: skip
    n_cam, height, width = depth.shape
    inv_res = 1.0 / res
    sh_k = res * sh_inv
    sh_x0 = (x0 - sh_ox) * sh_inv
    sh_y0 = (y0 - sh_oy) * sh_inv
    for task in prange(n_cam * height):
        c = task // height
        i = task % height
        if not cams[c]:
            continue
        R = cam_rot[c]
        T = cam_trans[c]
        fx, fy, cx, cy = cam_k[c, 0], cam_k[c, 1], cam_k[c, 2], cam_k[c, 3]
        sx, sy, sz = R[0, 0] / fx, R[0, 1] / fx, R[0, 2] / fx
        if abs(sz) >= 1e-15:
            continue  # a rolled camera: its ground rows are not level (left point-sampled)
        ccx = -(R[0, 0] * T[0] + R[1, 0] * T[1] + R[2, 0] * T[2])
        ccy = -(R[0, 1] * T[0] + R[1, 1] * T[1] + R[2, 1] * T[2])
        ccz = -(R[0, 2] * T[0] + R[1, 2] * T[1] + R[2, 2] * T[2])
        ry = (i + 0.5 - cy) / fy
        bz = R[2, 2] + R[1, 2] * ry
        if not (bz < -1e-12 and 0.0 < -ccz / bz < far):
            continue  # no ground in this row
        t_row = np.float32(-ccz / bz)
        # the pixel borders above (v = i) and below (v = i + 1)
        rt, rb = (i - cy) / fy, (i + 1.0 - cy) / fy
        btx, bty, btz = R[2, 0] + R[1, 0] * rt, R[2, 1] + R[1, 1] * rt, R[2, 2] + R[1, 2] * rt
        bbx, bby, bbz = R[2, 0] + R[1, 0] * rb, R[2, 1] + R[1, 1] * rb, R[2, 2] + R[1, 2] * rb
        # the pixel corners on the ground (surface-grid coordinates) and their texel and shadow cell, once per row
        cor = np.empty((2, width + 1, 2))
        hit = np.empty((2, width + 1), np.bool_)
        key = np.empty((2, width + 1, 3), np.int64)
        for j in range(width + 1):
            g = _ground_at(ccx, ccy, ccz, btx, bty, btz, sx, sy, sz, j, cx, far, x0, y0, inv_res)
            cor[0, j, 0], cor[0, j, 1], hit[0, j] = g
            kk = _cell_key(g[0], g[1], sh_x0, sh_y0, sh_k, shadow)
            key[0, j, 0], key[0, j, 1], key[0, j, 2] = kk
            g = _ground_at(ccx, ccy, ccz, bbx, bby, bbz, sx, sy, sz, j, cx, far, x0, y0, inv_res)
            cor[1, j, 0], cor[1, j, 1], hit[1, j] = g
            kk = _cell_key(g[0], g[1], sh_x0, sh_y0, sh_k, shadow)
            key[1, j, 0], key[1, j, 1], key[1, j, 2] = kk
        for j in range(width):
            if inst[c, i, j] != 0 or depth[c, i, j] != t_row:
                continue  # not the ground (a face, or the sky)
            n_u, n_v = max_n, max_n
            if hit[0, j] and hit[0, j + 1] and hit[1, j] and hit[1, j + 1]:
                same = True
                for q in range(3):
                    k0 = key[0, j, q]
                    if key[0, j + 1, q] != k0 or key[1, j, q] != k0 or key[1, j + 1, q] != k0:
                        same = False
                if same:
                    continue  # one texel and one shadow cell: the point sample is the footprint's colour
                ext_u = max(abs(cor[0, j + 1, 0] - cor[0, j, 0]), abs(cor[0, j + 1, 1] - cor[0, j, 1]),
                            abs(cor[1, j + 1, 0] - cor[1, j, 0]), abs(cor[1, j + 1, 1] - cor[1, j, 1]))
                ext_v = max(abs(cor[1, j, 0] - cor[0, j, 0]), abs(cor[1, j, 1] - cor[0, j, 1]),
                            abs(cor[1, j + 1, 0] - cor[0, j + 1, 0]), abs(cor[1, j + 1, 1] - cor[0, j + 1, 1]))
                n_u = min(max(int(np.ceil(max(ext_u, sh_k * ext_u))) + 1, 2), max_n)
                n_v = min(max(int(np.ceil(max(ext_v, sh_k * ext_v))) + 1, 2), max_n)
            a0 = 0.0
            a1 = 0.0
            a2 = 0.0
            for b in range(n_v):
                v = i + (b + 0.5) / n_v
                rv = (v - cy) / fy
                bx, by, bz2 = R[2, 0] + R[1, 0] * rv, R[2, 1] + R[1, 1] * rv, R[2, 2] + R[1, 2] * rv
                for a in range(n_u):
                    u = j + (a + 0.5) / n_u
                    g = _ground_at(ccx, ccy, ccz, bx, by, bz2, sx, sy, sz, u, cx, far, x0, y0, inv_res)
                    if g[2]:
                        fxw, fyw = g[0], g[1]
                        tab = lut
                        shx = sh_x0 + sh_k * fxw
                        shy = sh_y0 + sh_k * fyw
                        if shx >= 0.0 and shy >= 0.0 and shy < shadow.shape[0] and shx < shadow.shape[1]:
                            if shadow[int(shy), int(shx)]:
                                tab = shadow_lut
                        cls, k = surface_cell(fxw, fyw, surface, s_rows, s_cols, tiles_x)
                        a0 += tab[k, 0]
                        a1 += tab[k, 1]
                        a2 += tab[k, 2]
                    else:  # above the horizon (or beyond far): the sky's colour of this sub-row
                        mx = bx + sx * (0.5 * width + 0.5 - cx)
                        my = by + sy * (0.5 * width + 0.5 - cx)
                        mz = bz2 + sz * (0.5 * width + 0.5 - cx)
                        e = max(mz / np.sqrt(mx * mx + my * my + mz * mz), 0.0)
                        w = np.sqrt(e)
                        a0 += np.float64(np.uint8(sky_horizon[0] * (1.0 - w) + sky_zenith[0] * w))
                        a1 += np.float64(np.uint8(sky_horizon[1] * (1.0 - w) + sky_zenith[1] * w))
                        a2 += np.float64(np.uint8(sky_horizon[2] * (1.0 - w) + sky_zenith[2] * w))
            n = n_u * n_v
            rgb[c, i, j, 0] = np.uint8(a0 / n + 0.5)
            rgb[c, i, j, 1] = np.uint8(a1 / n + 0.5)
            rgb[c, i, j, 2] = np.uint8(a2 / n + 0.5)


def filter_ground(out: dict[str, np.ndarray], cams: np.ndarray, cam_rot: np.ndarray, cam_trans: np.ndarray,
                  cam_k: np.ndarray, far: float, surface: Any, lut: np.ndarray, shadow_lut: np.ndarray | None,
                  shadows: Any, sky_horizon: np.ndarray, sky_zenith: np.ndarray,
                  max_samples: int = MAX_GROUND_SAMPLES) -> None:  # fmt: skip
    """Re-colour, in place, each day ground pixel of the cameras ``cams`` (bool per camera) of a
    :func:`fog_gym.render.raster.render` output ``out`` with the mean of the surface over the pixel's footprint:
    the footprint's corners are traced to the ground; a pixel whose corners share one texel and one shadow cell keeps
    its colour, the others average an ``n_u × n_v`` grid of rays (``n`` = the footprint's extent in texels + 1,
    at most ``max_samples`` per axis; rays above the horizon take the sky's colour) — the box filter that a
    mip-mapped, anisotropic texture lookup approximates. Rolled cameras are left point-sampled."""
    from fog_gym.render.shadows import ShadowMap

    sm = ShadowMap.empty() if shadows is None else shadows
    launch = pick(_ground_kernel, _ground_kernel_serial, out["depth"].size)
    launch(np.ascontiguousarray(cam_rot, np.float64), np.ascontiguousarray(cam_trans, np.float64),
           np.ascontiguousarray(cam_k, np.float64), np.asarray(cams, np.bool_), float(far), surface.flat, surface.rows,
           surface.cols, surface.tiles_x, surface.origin[0], surface.origin[1], surface.resolution, lut,
           lut if shadow_lut is None else shadow_lut, sm.grid, sm.origin[0], sm.origin[1], 1.0 / sm.resolution,
           np.asarray(sky_horizon, np.float64), np.asarray(sky_zenith, np.float64), out["depth"], out["inst"],
           out["rgb"], int(max_samples))  # fmt: skip


_ground_kernel_serial = serial_twin(_ground_kernel)

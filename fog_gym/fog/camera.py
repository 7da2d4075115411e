"""Koschmieder fog for camera images, implemented from the equations (research note ``fog_physics.md`` §1).

``I = J·t + A·(1 − t)``, ``t = exp(−α·ℓ)`` with ℓ the Euclidean distance of each pixel (from planar depth and the
intrinsics) and ``A`` the atmospheric light (dark channel 15×15, top 0.1 %, median grey); at night ``A`` comes
from the lit surroundings (:func:`night_airlight`) and lit fog glows around bright sources
(:func:`fog_gym.fog.glow.add_glow`).

Example:
    >>> from fog_gym.fog.physics import parse_fog
    >>> img = fog_image(np.zeros((2, 2, 3), np.uint8), np.full((2, 2), 1000.0, np.float32), np.eye(3),
    ...                 parse_fog("dense").alpha, np.full(3, 200.0))
    >>> int(img.max())  # the sky takes the airlight
    200
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence

import cv2
import numpy as np
from numba import njit, prange

import fog_gym._numba  # noqa: F401  (numba's fork-safe threading layer, before any kernel runs)
from fog_gym._numba import FASTMATH, pick, serial_twin
from fog_gym.fog.depth import optical_depths
from fog_gym.fog.glow import _NO_GLOW, _blend_glow, _glow_rows_of

def ray_length_factor(width: int, height: int, K: np.ndarray) -> np.ndarray:
    """Per-pixel ``ℓ / z`` = ``sqrt(1 + ((u − cx)/fx)² + ((v − cy)/fy)²)`` at pixel centres, float32 ``(H, W)``."""
    u = (np.arange(width) + 0.5 - K[0, 2]) / K[0, 0]
    v = (np.arange(height) + 0.5 - K[1, 2]) / K[1, 1]
    return np.sqrt(1.0 + u[None, :] ** 2 + v[:, None] ** 2).astype(np.float32)


def atmospheric_light(rgb: np.ndarray, window: int = 15, top_fraction: float = 0.001) -> np.ndarray:
    """Atmospheric light ``A`` (RGB, 0–255 floats) of a clear image: dark channel (``window``² erosion, channel
    minimum), the top ``top_fraction`` of its pixels (count forced odd), and the RGB of the one with median grey.
    """
    img = np.ascontiguousarray(rgb)
    if img.ndim != 3 or img.shape[2] != 3:
        raise ValueError(f"expected an (H, W, 3) RGB image, got shape {img.shape}")
    channels = cv2.split(img)
    dark = cv2.erode(cv2.min(cv2.min(channels[0], channels[1]), channels[2]), np.ones((window, window), np.uint8))
    k = max(1, int(math.floor(top_fraction * dark.size)))
    k += 1 - k % 2
    flat = dark.reshape(-1)
    # the k brightest dark-channel pixels: all above a threshold value, then ties in raster order
    counts = np.bincount(flat, minlength=256)
    above = np.cumsum(counts[::-1])[::-1]  # pixels >= value
    threshold = int(np.nonzero(above >= k)[0].max())
    strictly = np.flatnonzero(flat > threshold)
    ties = np.flatnonzero(flat == threshold)[: k - len(strictly)]
    top = np.concatenate([strictly, ties])
    pixels = img.reshape(-1, 3)[top].astype(np.float64)
    grey = pixels @ np.array([0.2989, 0.5870, 0.1140])
    return pixels[np.argsort(grey, kind="stable")[k // 2]]


#: Night airlight: pixels nearer than this [m] light the fog; their ``NIGHT_AIRLIGHT_PERCENTILE`` colour is ``A``.
NIGHT_AIRLIGHT_RANGE, NIGHT_AIRLIGHT_PERCENTILE = 30.0, 75.0


def night_airlight(rgb: np.ndarray, depth: np.ndarray, max_range: float = NIGHT_AIRLIGHT_RANGE) -> np.ndarray:
    """Atmospheric light of a night frame: the fog is lit like the surfaces around the camera.

    At night there is no bright sky to take ``A`` from (the dark-channel estimate would pick a lamp head); the
    droplets near the camera are lit by the same lamps and beams as the surfaces there, so ``A`` is the
    ``NIGHT_AIRLIGHT_PERCENTILE`` colour of the pixels nearer than ``max_range`` (all pixels if none are).

    >>> rgb = np.zeros((2, 2, 3), np.uint8); rgb[0] = 80
    >>> night_airlight(rgb, np.array([[10.0, 10.0], [500.0, 500.0]], np.float32)).tolist()
    [80.0, 80.0, 80.0]
    """
    img = np.asarray(rgb)
    if img.ndim != 3 or img.shape[2] != 3 or np.shape(depth) != img.shape[:2]:
        raise ValueError(f"rgb must be (H, W, 3) and depth (H, W), got {img.shape} and {np.shape(depth)}")
    near = np.asarray(depth) < max_range
    pixels = img[near] if near.any() else img.reshape(-1, 3)
    if pixels.dtype != np.uint8:
        return np.percentile(pixels.astype(np.float64), NIGHT_AIRLIGHT_PERCENTILE, axis=0)
    # np.percentile's linear rule from the channels' 256-bin counts (no sort): the order statistics at
    # floor(q·(n − 1)) and the next one, interpolated by the fraction
    pos = NIGHT_AIRLIGHT_PERCENTILE / 100.0 * (len(pixels) - 1)
    lo, frac = int(math.floor(pos)), pos - math.floor(pos)
    out = np.empty(3)
    for ch in range(3):
        cum = np.cumsum(np.bincount(pixels[:, ch], minlength=256))
        a, b = np.searchsorted(cum, [lo + 1, min(lo + 2, len(pixels))]).astype(np.float64)
        out[ch] = b - (b - a) * (1.0 - frac) if frac >= 0.5 else a + (b - a) * frac
    return out


_F32 = np.float32


@njit(cache=True, inline="always", fastmath=FASTMATH)
def _exp_neg(x):
    """exp(x) for float32 x ≤ 0 without a libm call, so pixel loops vectorise: exp(x) = (exp(x/64))^64 with a
    degree-5 Taylor polynomial on [−0.25, 0] (relative error < 2e-5); x is clamped at −16 (exp(−16) = 1.1e-7)."""
    y = max(x, _F32(-16.0)) * _F32(0.015625)
    p = _F32(1.0) + y * (_F32(1.0) + y * (_F32(0.5) + y * (_F32(1.0 / 6) + y * (_F32(1.0 / 24) + y * _F32(1.0 / 120)))))
    p = p * p
    p = p * p
    p = p * p
    p = p * p
    p = p * p
    return p * p


@njit(cache=True, inline="always", fastmath=FASTMATH)
def _fog_row(o, t, t3, diff, airlight_row):
    # One fogged row: each pixel's transmittance t repeated for its three channels (t3, scratch), then
    # o = A + (J − A)·t rounded (diff = J − A).
    for j in range(t.shape[0]):
        t3[3 * j] = t[j]
        t3[3 * j + 1] = t[j]
        t3[3 * j + 2] = t[j]
    for k in range(o.shape[0]):
        o[k] = np.uint8(airlight_row[k] + diff[k] * t3[k] + np.float32(0.5))


@njit(cache=True, nogil=True, parallel=True, fastmath=FASTMATH)
def _koschmieder(rgb, depth, col_sq, row_sq, alphas, airlight_row, out, y0s, wys, firsts, fofs, wide, rofs, span_lo,
                 span_hi):  # fmt: skip
    # rgb (H, 3W) and out (L, H, 3W) are viewed flat per row so every inner loop is contiguous (SIMD);
    # rows go in 16 chunks so each task allocates its scratch rows once. At night each fogged row gets its glow while
    # it is in cache (_blend_glow; the arguments after out, _NO_GLOW when y0s has no levels).
    glow = y0s.shape[0] > 0
    h, w = depth.shape
    n_levels = alphas.shape[0]
    n_chunks = 16
    for chunk in prange(n_chunks):
        ell = np.empty(w, np.float32)
        t = np.empty(w, np.float32)
        diff = np.empty(3 * w, np.float32)
        t3 = np.empty(3 * w, np.float32)
        for i in range(chunk * h // n_chunks, (chunk + 1) * h // n_chunks):
            b2 = np.float32(1.0) + row_sq[i]
            for j in range(w):
                ell[j] = depth[i, j] * np.sqrt(b2 + col_sq[j])
            for k in range(3 * w):
                diff[k] = np.float32(rgb[i, k]) - airlight_row[k]
            for lv in range(n_levels):
                a = -alphas[lv]
                for j in range(w):
                    t[j] = _exp_neg(a * ell[j])
                _fog_row(out[lv, i], t, t3, diff, airlight_row)
                if glow:
                    _blend_glow(out[lv, i], i, lv, y0s, wys, firsts, fofs, wide, rofs, span_lo, span_hi)


_koschmieder_serial = serial_twin(_koschmieder)


def check_fog_inputs(rgb: np.ndarray, depth: np.ndarray, K: np.ndarray, alphas: Sequence[float], airlight: np.ndarray) -> None:
    """``ValueError`` naming the problem unless the inputs of :func:`fog_images` are usable.

    rgb uint8 (H, W, 3); depth (H, W) finite and ≥ 0 (sky is a large finite depth, 1000 m in fog-gym);
    K a 3×3 intrinsic matrix with finite positive focal lengths; every α finite and > 0; airlight three finite
    values in [0, 255].
    """
    depth = np.asarray(depth)
    if depth.ndim != 2:
        raise ValueError(f"depth must be an (H, W) array of metres, got shape {depth.shape}")
    h, w = depth.shape
    if not isinstance(rgb, np.ndarray) or rgb.shape != (h, w, 3) or rgb.dtype != np.uint8:
        raise ValueError(f"expected a uint8 (H, W, 3) image matching depth {depth.shape}, got "
                         f"{getattr(rgb, 'dtype', type(rgb).__name__)} {getattr(rgb, 'shape', '')}")  # fmt: skip
    low = float(np.min(depth)) if depth.size else 0.0
    if not math.isfinite(low) or low < 0 or (depth.size and not math.isfinite(float(np.max(depth)))):
        raise ValueError("depth must be finite and >= 0 metres everywhere (sky: a large finite depth such as 1000)")
    K = np.asarray(K, np.float64)
    if K.shape != (3, 3) or not np.isfinite(K).all() or K[0, 0] <= 0 or K[1, 1] <= 0:
        raise ValueError(f"K must be a finite 3×3 intrinsic matrix with positive focal lengths, got {K.tolist()}")
    a = np.asarray(alphas, np.float64)
    if a.ndim != 1 or not len(a) or not np.isfinite(a).all() or (a <= 0).any():
        raise ValueError(f"alphas must be finite extinctions > 0 [1/m], got {list(np.atleast_1d(a))}")
    A = np.asarray(airlight, np.float64)
    if A.shape != (3,) or not np.isfinite(A).all() or (A < 0).any() or (A > 255).any():
        raise ValueError(f"airlight must be three values in [0, 255], got {A.tolist()}")


@functools.lru_cache(maxsize=64)
def _ray_slopes(fx: float, fy: float, cx: float, cy: float, w: int, h: int) -> tuple[np.ndarray, np.ndarray]:
    """Squared ray slopes of the pixel centres of a camera, per column and per row (float32; a camera's own, kept
    across its frames: the kernels only read them)."""
    col = (((np.arange(w) + 0.5 - cx) / fx) ** 2).astype(np.float32)
    row = (((np.arange(h) + 0.5 - cy) / fy) ** 2).astype(np.float32)
    return col, row


def fog_images(rgb: np.ndarray, depth: np.ndarray, K: np.ndarray, alphas: Sequence[float], airlight: np.ndarray,
               validate: bool = True, glow: bool = False) -> np.ndarray:  # fmt: skip
    """Koschmieder fog at several extinctions in one pass: ``(L, H, W, 3)`` uint8 for ``alphas`` (all > 0).

    ``ℓ = z · sqrt(1 + ((u − cx)/fx)² + ((v − cy)/fy)²)`` at pixel centres; ``t = exp(−α·ℓ)``;
    ``I = A + (J − A)·t`` rounded. One read of image and depth serves every level. Inputs are checked
    (:func:`check_fog_inputs`) unless ``validate=False`` (the env's own frames, on the hot path). With ``glow=True``
    (night) each level also gets the glow of the frame's bright sources (:func:`fog_gym.fog.glow.add_glows`, the same
    bits) while its rows are in cache.
    """
    if validate:
        check_fog_inputs(rgb, depth, K, alphas, airlight)
    rows = _glow_rows_of(rgb, depth, K, alphas) if glow else None
    h, w = depth.shape
    col, row = _ray_slopes(float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2]), w, h)
    out = np.empty((len(alphas), h, w, 3), np.uint8)
    airlight_row = np.tile(np.asarray(airlight, np.float32), w)
    pick(_koschmieder, _koschmieder_serial, len(alphas) * h * w)(
        np.ascontiguousarray(rgb).reshape(h, 3 * w), np.ascontiguousarray(depth, np.float32), col, row,
        np.asarray(alphas, np.float32), airlight_row, out.reshape(len(alphas), h, 3 * w), *(rows or _NO_GLOW),
    )  # fmt: skip
    return out


def fog_image(rgb: np.ndarray, depth: np.ndarray, K: np.ndarray, alpha: float, airlight: np.ndarray) -> np.ndarray:
    """Koschmieder fog on a uint8 RGB image with planar depth (metres) and intrinsic ``K``; ``alpha = 0`` copies.

    >>> from fog_gym.fog.physics import alpha_from_visibility
    >>> img = np.zeros((2, 2, 3), np.uint8); depth = np.full((2, 2), 50.0, np.float32)
    >>> K = np.array([[1e6, 0, 1], [0, 1e6, 1], [0, 0, 1]])
    >>> fog_image(img, depth, K, alpha_from_visibility(50), np.array([200.0, 200, 200]))[0, 0].tolist()
    [190, 190, 190]
    """
    if alpha == 0.0:
        check_fog_inputs(rgb, depth, K, [1.0], airlight)
        return rgb.copy()
    return fog_images(rgb, depth, K, [alpha], airlight)[0]


# -- fog fields (fog_gym.fog.fields): per-pixel optical depth instead of α·ℓ ------------------------------------------


@njit(cache=True, nogil=True, parallel=True, fastmath=FASTMATH)
def _koschmieder_field(rgb, depth, xs, ys, pose, terms, starts, airlight_row, out, y0s, wys, firsts, fofs, wide, rofs,
                       span_lo, span_hi):  # fmt: skip
    # rgb (H, 3W), out (L, H, 3W) flat per row; xs (W) / ys (H) the pixel centres' ray slopes; pose (field_pose);
    # level lv's field is terms[starts[lv]:starts[lv + 1]] (fog_gym.fog.fields packed rows). τ per pixel along its ray
    # from the camera centre (u_c, z_c) to the surface, term by term in contiguous loops (SIMD):
    #   homogeneous  β·ℓ
    #   height       β0·ℓ·[f_below + (1 − f_below)·e^{−z_lo/H}·g((z_hi − z_lo)/H)], g(x) = (1 − e^{−x})/x, heights
    #                clamped at the road (β(z < 0) = β(0)); f_below the part of the ray below it
    #   bank         ℓ·[β_bg + Δβ·(W(u1) − W(u0))/(u1 − u0)], W the integral of the bank's trapezoid (its mean over a
    #                sideways ray: the trapezoid at the ray's middle)
    # and t = e^{−τ}, I = A + (J − A)·t rounded, then the glow, as _koschmieder.
    glow = y0s.shape[0] > 0
    h, w = depth.shape
    n_levels = starts.shape[0] - 1
    u_c, z_c = pose[0], pose[1]
    n_chunks = 16
    for chunk in prange(n_chunks):
        ell = np.empty(w, np.float64)
        run_u = np.empty(w, np.float64)
        run_z = np.empty(w, np.float64)
        tau = np.empty(w, np.float64)
        t = np.empty(w, np.float32)
        diff = np.empty(3 * w, np.float32)
        t3 = np.empty(3 * w, np.float32)
        for i in range(chunk * h // n_chunks, (chunk + 1) * h // n_chunks):
            y = ys[i]
            cu, cz = pose[3] * y + pose[4], pose[6] * y + pose[7]
            b2 = 1.0 + y * y
            for j in range(w):
                d = np.float64(depth[i, j])
                x = xs[j]
                ell[j] = d * np.sqrt(b2 + x * x)
                run_u[j] = d * (pose[2] * x + cu)
                run_z[j] = d * (pose[5] * x + cz)
            for k in range(3 * w):
                diff[k] = np.float32(rgb[i, k]) - airlight_row[k]
            for lv in range(n_levels):
                for j in range(w):
                    tau[j] = 0.0
                for r in range(starts[lv], starts[lv + 1]):
                    kind = terms[r, 0]
                    if kind == 0.0:
                        beta = terms[r, 1]
                        for j in range(w):
                            tau[j] += beta * ell[j]
                    elif kind == 1.0:
                        b0, inv_h = terms[r, 1], 1.0 / terms[r, 2]
                        for j in range(w):
                            z1 = z_c + run_z[j]
                            lo, hi = min(z_c, z1), max(z_c, z1)
                            below = min(max(-lo / max(hi - lo, 1e-9), 0.0), 1.0)
                            lo_c = max(lo, 0.0)
                            x = (max(hi, 0.0) - lo_c) * inv_h
                            g = 1.0 - x * (0.5 - x * (1.0 / 6.0 - x * (1.0 / 24.0))) if x < 0.25 else \
                                (1.0 - _exp_neg(-x)) / max(x, 0.25)  # fmt: skip
                            tau[j] += b0 * ell[j] * (below + (1.0 - below) * _exp_neg(-lo_c * inv_h) * g)
                    else:
                        db, a, b, c, d, p, bg = (terms[r, 1], terms[r, 2], terms[r, 3], terms[r, 4], terms[r, 5],
                                                 terms[r, 6], terms[r, 7])  # fmt: skip
                        half_rise = 0.5 / (b - a) if b > a else 0.0
                        half_fall = 0.5 / (d - c) if d > c else 0.0
                        rise = 1.0 / (b - a) if b > a else 1e30
                        fall = 1.0 / (d - c) if d > c else 1e30
                        x = min(max(u_c, a), b) - a
                        y0 = min(max(u_c, c), d) - c
                        w0 = p * (x * x * half_rise + min(max(u_c, b), c) - b + y0 - y0 * y0 * half_fall)
                        for j in range(w):
                            span = run_u[j]
                            u1 = u_c + span
                            x = min(max(u1, a), b) - a
                            y1 = min(max(u1, c), d) - c
                            w1 = p * (x * x * half_rise + min(max(u1, b), c) - b + y1 - y1 * y1 * half_fall)
                            mid = u_c + 0.5 * span
                            at_mid = p * min(max(min((mid - a) * rise, (d - mid) * fall), 0.0), 1.0)
                            long = abs(span) > 1e-3
                            mean = (w1 - w0) / (span if long else 1.0) if long else at_mid
                            tau[j] += (bg + db * mean) * ell[j]
                for j in range(w):
                    t[j] = _exp_neg(np.float32(-tau[j]))
                _fog_row(out[lv, i], t, t3, diff, airlight_row)
                if glow:
                    _blend_glow(out[lv, i], i, lv, y0s, wys, firsts, fofs, wide, rofs, span_lo, span_hi)


_koschmieder_field_serial = serial_twin(_koschmieder_field)


def fog_field_images(rgb: np.ndarray, depth: np.ndarray, K: np.ndarray, fields: Sequence, airlight: np.ndarray,
                     pose: np.ndarray, time: float = 0.0, validate: bool = True, glow: bool = False) -> np.ndarray:  # fmt: skip
    """Koschmieder fog with fog fields (:mod:`fog_gym.fog.fields`): ``(L, H, W, 3)`` uint8, one image per field.

    Each pixel's transmittance is ``t = exp(−τ)``, τ the field's optical depth along the pixel's ray from the camera
    centre to the surface (planar depth → ray length; sky pixels to the far plane), in closed form; ``I = A + (J − A)·t``
    with the airlight of a clear frame as for homogeneous fog. ``pose`` places the camera in the field frame
    (:func:`fog_gym.fog.depth.field_pose`), ``time`` [s] moves drifting banks. A homogeneous field gives
    :func:`fog_images`'s result within 1/255 (use that for them: it is the reference). With ``glow=True`` (night) the sources lose ``1 − e^{−τ}``
    of their light along their own rays to the glow, whose width follows each field's peak extinction.
    """
    if validate:
        check_fog_inputs(rgb, depth, K, [1.0], airlight)
        pose = np.asarray(pose, np.float64)
        if pose.shape != (8,) or not np.isfinite(pose).all():
            raise ValueError(f"pose must be field_pose(camera_to_world, frame) (fog_gym.fog.depth): 8 finite numbers, got {pose!r}")
    packed = [f.pack(time) for f in fields]
    if not packed:
        raise ValueError("fields must hold at least one fog field")
    starts = np.concatenate([[0], np.cumsum([len(p) for p in packed])]).astype(np.int64)
    h, w = depth.shape
    xs = (np.arange(w) + 0.5 - K[0, 2]) / K[0, 0]
    ys = (np.arange(h) + 0.5 - K[1, 2]) / K[1, 1]
    pose = np.asarray(pose, np.float64)
    rows = None
    if glow:
        def depths(si: np.ndarray, sj: np.ndarray) -> np.ndarray:  # each field's τ along the sources' rays
            d, x, y = depth[si, sj].astype(np.float64), xs[sj], ys[si]
            ell = d * np.sqrt(1.0 + x * x + y * y)
            du, dz = d * (pose[2] * x + pose[3] * y + pose[4]) / ell, d * (pose[5] * x + pose[6] * y + pose[7]) / ell
            return np.stack([optical_depths(p, pose[0], pose[1], du, dz, ell) for p in packed], axis=1)

        rows = _glow_rows_of(rgb, depth, K, [f.alpha for f in fields], depths)
    out = np.empty((len(packed), h, w, 3), np.uint8)
    pick(_koschmieder_field, _koschmieder_field_serial, len(packed) * h * w)(
        np.ascontiguousarray(rgb).reshape(h, 3 * w), np.ascontiguousarray(depth, np.float32), xs, ys, pose,
        np.concatenate(packed), starts, np.tile(np.asarray(airlight, np.float32), w), out.reshape(len(packed), h, 3 * w),
        *(rows or _NO_GLOW))
    return out

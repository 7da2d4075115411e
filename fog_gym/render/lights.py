"""Night lighting for the RGB cameras: street lamps, headlight beams and histogram auto-exposure (numba kernels).

Pure functions over numpy arrays; nothing here imports the environment. Used after the rasteriser ran in
*albedo mode* (``ambient = 1``, no sun, an unshaded surface map) with ``face_ids=True``: the depth buffer gives
each pixel's world point, the face index its normal, and the RGB buffer its albedo. Depth, semantics and
instance ids are never touched; only the RGB buffer is rewritten.

Light model (all in linear "albedo × irradiance" units, in which the day renderer's sun gives ≈ 0.45–1.05):

* irradiance of a point ``p`` with normal ``n`` from a light at ``q``:
  ``E = I · P(ω) · max(n·ω, 0) / max(d², 1 m²) · W(d)``, ``ω = (q − p)/d``, with Unreal's windowed inverse
  square ``W(d) = clamp(1 − (d/R)⁴, 0, 1)²`` that brings each light to exactly zero at its radius ``R``;
* street lamp (full cut-off luminaire): ``P = clamp(ω_z / 0.15, 0, 1)`` (light only below the lamp head);
* low beam, along the vehicle's heading: horizontally 1 within ±12° fading to 0 at ±22°; vertically a sharp
  cut-off above the horizon (``exp(−(φ/1.5°)²)`` for rays rising by φ) and ``min(1, (φ_h/φ)²)`` below it, with
  ``φ_h = atan(h/45 m)``: the hot spot just under the cut-off reaches the road at 45 m and the pool fades out
  by ≈ 60 m (the road's irradiance ∝ I·h/d³ stays nearly flat from 10 to 45 m, as real beam patterns do);
* radiance ``L = albedo · (A + Σ E_l · colour_l)`` with the night ambient ``A``; emissive faces (lamps) emit
  ``albedo · EMISSIVE_GAIN``, the sky its colour × ``SKY_GAIN``; street-lamp heads are drawn as emissive discs
  (RGB only: they are not geometry, so depth and semantics stay unchanged).

No shadows: a light reaches every point within its radius that faces it (documented limitation).

Auto-exposure (in the spirit of CARLA's default ``exposure_mode = "histogram"``): per camera and frame, a
histogram of ``log2`` luminance over ``[LOG_MIN, LOG_MAX]``; the mean log luminance of the pixels between the
``LOW_PERCENT`` and ``HIGH_PERCENT`` of that histogram (the darkest half and the brightest 2 % — black sky,
lamp heads — do not steer it) is mapped to ``KEY``: ``gain = KEY / 2^mean``, clamped to ``[GAIN_MIN,
GAIN_MAX]`` (0 to +6 EV). Encoding: ``round(tone(L · gain) · 255)`` with a filmic-like shoulder (:func:`tone`)
that keeps headlit cars from clipping flat.

Example (one lamp 7 m above a grey floor point, straight down):
    >>> import numpy as np
    >>> e = irradiance(np.array([0.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]), street_lamp_lights(np.array([[0.0, 0.0, 7.0]])))
    >>> bool(round(float(e[0]), 4) == round(LAMP_INTENSITY / 49 * (1 - (7 / LAMP_RADIUS) ** 4) ** 2 * LAMP_COLOR[0], 4))
    True
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from fog_gym.render import raster  # noqa: F401  (fork-safe threading layer before any kernel runs)

LAMP, HEADLIGHT = 0, 1
#: Street lamp: luminous intensity in albedo·m² units, radius of influence [m], colour (warm white LED).
LAMP_INTENSITY, LAMP_RADIUS = 40.0, 40.0
LAMP_COLOR = np.array([1.0, 0.88, 0.70])
LAMP_HEAD_RADIUS = 0.3  # drawn disc [m]
LAMP_HEAD_RADIANCE = 6.0
#: Low beam: peak intensity (both lamps together), radius of influence [m], colour, hot-spot distance [m].
BEAM_INTENSITY, BEAM_RADIUS, BEAM_HOTSPOT = 1200.0, 60.0, 45.0
BEAM_COLOR = np.array([1.0, 0.97, 0.90])
BEAM_HALF_ANGLE, BEAM_FADE_ANGLE, BEAM_CUTOFF = math.radians(12.0), math.radians(22.0), math.radians(1.5)
#: Night ambient (sky glow) irradiance, emissive and sky radiance scales.
NIGHT_AMBIENT = 0.02
EMISSIVE_GAIN = 4.0
SKY_GAIN = 0.1
#: Auto-exposure.
LOG_MIN, LOG_MAX, N_BINS = -12.0, 4.0, 128
LOW_PERCENT, HIGH_PERCENT = 0.5, 0.98
KEY = 0.18
GAIN_MIN, GAIN_MAX = 1.0, 64.0
#: Highlight shoulder of the encoding: linear up to ``KNEE``, then ``KNEE + (1 − KNEE)(1 − e^{−(x − KNEE)/(1 − KNEE)})``.
KNEE = 0.6
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
            v = math.exp(-(phi / 0.02617993877991494) ** 2)  # BEAM_CUTOFF
        else:
            ph = math.atan2(max(lheight[k], 0.1), 45.0)  # BEAM_HOTSPOT
            v = min(1.0, (ph / phi) ** 2)
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


@njit(cache=True, parallel=True, fastmath=False)
def _shade(
    cam_rot, cam_trans, cam_k, far, rgb, depth, face, face_nrm, face_emis,
    lpos, laxis, lcol, lint, lrad, lkind, lheight, heads, head_rad, head_col,
    ambient, emissive_gain, sky_gain, out_lin,
):  # fmt: skip
    n_cam, height, width = depth.shape
    ty = (height + TILE - 1) // TILE
    tx = (width + TILE - 1) // TILE
    n_l = lpos.shape[0]
    n_h = heads.shape[0]
    for task in prange(n_cam * ty * tx):
        c = task // (ty * tx)
        r0 = ((task // tx) % ty) * TILE
        c0 = (task % tx) * TILE
        r1 = min(r0 + TILE, height)
        c1 = min(c0 + TILE, width)
        R = cam_rot[c]
        T = cam_trans[c]
        fx, fy, cx, cy = cam_k[c, 0], cam_k[c, 1], cam_k[c, 2], cam_k[c, 3]
        # world bounding box of this tile's surface points
        lo0, lo1, lo2 = 1e30, 1e30, 1e30
        hi0, hi1, hi2 = -1e30, -1e30, -1e30
        for i in range(r0, r1):
            yn = (i + 0.5 - cy) / fy
            for j in range(c0, c1):
                z = depth[c, i, j]
                if z >= far:
                    continue
                xc = (j + 0.5 - cx) / fx * z - T[0]
                yc = yn * z - T[1]
                zc = z - T[2]
                wx = R[0, 0] * xc + R[1, 0] * yc + R[2, 0] * zc
                wy = R[0, 1] * xc + R[1, 1] * yc + R[2, 1] * zc
                wz = R[0, 2] * xc + R[1, 2] * yc + R[2, 2] * zc
                lo0, lo1, lo2 = min(lo0, wx), min(lo1, wy), min(lo2, wz)
                hi0, hi1, hi2 = max(hi0, wx), max(hi1, wy), max(hi2, wz)
        sel = np.empty(n_l, np.int64)
        n_sel = 0
        if hi0 >= lo0:
            for k in range(n_l):
                ex = max(lo0 - lpos[k, 0], 0.0, lpos[k, 0] - hi0)
                ey = max(lo1 - lpos[k, 1], 0.0, lpos[k, 1] - hi1)
                ez = max(lo2 - lpos[k, 2], 0.0, lpos[k, 2] - hi2)
                if ex * ex + ey * ey + ez * ez < lrad[k] * lrad[k]:
                    sel[n_sel] = k
                    n_sel += 1
        # lamp heads whose disc may touch the tile
        hsel = np.empty(n_h, np.int64)
        hu = np.empty(n_h)
        hv = np.empty(n_h)
        hz = np.empty(n_h)
        hr = np.empty(n_h)
        n_hs = 0
        for k in range(n_h):
            pxc = R[0, 0] * heads[k, 0] + R[0, 1] * heads[k, 1] + R[0, 2] * heads[k, 2] + T[0]
            pyc = R[1, 0] * heads[k, 0] + R[1, 1] * heads[k, 1] + R[1, 2] * heads[k, 2] + T[1]
            pzc = R[2, 0] * heads[k, 0] + R[2, 1] * heads[k, 1] + R[2, 2] * heads[k, 2] + T[2]
            if pzc < 0.5:
                continue
            u = fx * pxc / pzc + cx
            v = fy * pyc / pzc + cy
            rp = max(fx * head_rad / pzc, 0.75)
            if u + rp < c0 or u - rp > c1 or v + rp < r0 or v - rp > r1:
                continue
            hsel[n_hs] = k
            hu[n_hs], hv[n_hs], hz[n_hs], hr[n_hs] = u, v, pzc, rp
            n_hs += 1
        for i in range(r0, r1):
            yn = (i + 0.5 - cy) / fy
            for j in range(c0, c1):
                z = depth[c, i, j]
                a0 = rgb[c, i, j, 0] * (1.0 / 255.0)
                a1 = rgb[c, i, j, 1] * (1.0 / 255.0)
                a2 = rgb[c, i, j, 2] * (1.0 / 255.0)
                if z >= far:
                    l0, l1, l2 = a0 * sky_gain, a1 * sky_gain, a2 * sky_gain
                else:
                    f = face[c, i, j]
                    if f >= 0 and face_emis[c, f]:
                        l0, l1, l2 = a0 * emissive_gain, a1 * emissive_gain, a2 * emissive_gain
                    else:
                        if f >= 0:
                            nx, ny, nz = face_nrm[c, f, 0], face_nrm[c, f, 1], face_nrm[c, f, 2]
                        else:
                            nx, ny, nz = 0.0, 0.0, 1.0
                        xc = (j + 0.5 - cx) / fx * z - T[0]
                        yc = yn * z - T[1]
                        zc = z - T[2]
                        wx = R[0, 0] * xc + R[1, 0] * yc + R[2, 0] * zc
                        wy = R[0, 1] * xc + R[1, 1] * yc + R[2, 1] * zc
                        wz = R[0, 2] * xc + R[1, 2] * yc + R[2, 2] * zc
                        # lift the point 1 cm off its surface so lights at grazing angles stay stable
                        wx += 0.01 * nx
                        wy += 0.01 * ny
                        wz += 0.01 * nz
                        e0, e1, e2 = ambient, ambient, ambient
                        for s in range(n_sel):
                            k = sel[s]
                            w = _light_at(wx, wy, wz, nx, ny, nz, k, lpos, laxis, lint, lrad, lkind, lheight)
                            if w > 0.0:
                                e0 += w * lcol[k, 0]
                                e1 += w * lcol[k, 1]
                                e2 += w * lcol[k, 2]
                        l0, l1, l2 = a0 * e0, a1 * e1, a2 * e2
                for s in range(n_hs):
                    du = j + 0.5 - hu[s]
                    dv = i + 0.5 - hv[s]
                    if du * du + dv * dv <= hr[s] * hr[s] and hz[s] < z:
                        l0, l1, l2 = head_col[0], head_col[1], head_col[2]
                out_lin[c, i, j, 0] = l0
                out_lin[c, i, j, 1] = l1
                out_lin[c, i, j, 2] = l2


@njit(cache=True, parallel=True)
def _log_histograms(lin, log_min, log_max, n_bins):
    n_cam, height, width, _ = lin.shape
    hist = np.zeros((n_cam, height, n_bins), np.int64)
    scale = n_bins / (log_max - log_min)
    for task in prange(n_cam * height):
        c = task // height
        i = task % height
        for j in range(width):
            y = 0.2126 * lin[c, i, j, 0] + 0.7152 * lin[c, i, j, 1] + 0.0722 * lin[c, i, j, 2]
            b = 0
            if y > 0.0:
                b = int((math.log2(y) - log_min) * scale)
                b = min(max(b, 0), n_bins - 1)
            hist[c, i, b] += 1
    return hist.sum(axis=1)


def exposure_gains(lin: np.ndarray) -> np.ndarray:
    """Auto-exposure gain per camera from linear radiance ``lin`` (C, H, W, 3); see the module docstring.

    >>> lin = np.full((1, 4, 4, 3), 0.05, np.float32)
    >>> g = exposure_gains(lin)[0]
    >>> bool(abs(g * 0.05 - KEY) / KEY < 0.1)
    True
    """
    hist = _log_histograms(np.ascontiguousarray(lin, np.float32), LOG_MIN, LOG_MAX, N_BINS)
    centres = LOG_MIN + (np.arange(N_BINS) + 0.5) * (LOG_MAX - LOG_MIN) / N_BINS
    gains = np.empty(len(hist))
    for c, h in enumerate(hist):
        cum = np.cumsum(h) / max(h.sum(), 1)
        lo = np.r_[0.0, cum[:-1]]
        # the fraction of each bin that lies inside [LOW_PERCENT, HIGH_PERCENT]
        w = np.clip(np.minimum(cum, HIGH_PERCENT) - np.maximum(lo, LOW_PERCENT), 0.0, None)
        mean_log = float((w * centres).sum() / max(w.sum(), 1e-12))
        gains[c] = float(np.clip(KEY / 2.0**mean_log, GAIN_MIN, GAIN_MAX))
    return gains


@njit(cache=True, inline="always")
def _tone(x, knee):
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


@njit(cache=True, parallel=True)
def _encode(lin, gains, knee, out):
    n_cam, height, width, _ = lin.shape
    for task in prange(n_cam * height):
        c = task // height
        i = task % height
        g = gains[c]
        for j in range(width):
            for ch in range(3):
                out[c, i, j, ch] = np.uint8(_tone(lin[c, i, j, ch] * g, knee) * 255.0 + 0.5)


def shade_night(
    cam_rot: np.ndarray, cam_trans: np.ndarray, cam_k: np.ndarray, far: float, buffers: dict[str, np.ndarray],
    lights: Lights, heads: np.ndarray, ambient: float = NIGHT_AMBIENT,
) -> np.ndarray:
    """Light, expose and encode in place the RGB of an albedo-mode render; returns the exposure gain per camera.

    ``buffers`` is :func:`fog_gym.render.raster.render`'s output with ``face_ids=True`` (its ``rgb`` holding
    albedo); ``heads`` (N, 3) are lamp heads to draw. Only ``buffers["rgb"]`` changes.
    """
    missing = [k for k in ("rgb", "depth", "face", "face_normal", "face_emissive") if k not in buffers]
    if missing:
        raise ValueError(f"buffers lack {missing}: pass the output of render(..., face_ids=True)")
    rgb = buffers["rgb"]
    lin = np.empty(rgb.shape, np.float32)
    heads = np.ascontiguousarray(np.reshape(heads, (-1, 3)), np.float64)
    _shade(
        np.ascontiguousarray(cam_rot, np.float64), np.ascontiguousarray(cam_trans, np.float64),
        np.ascontiguousarray(cam_k, np.float64), float(far), rgb, buffers["depth"], buffers["face"],
        buffers["face_normal"], buffers["face_emissive"], lights.pos, lights.axis, lights.color, lights.intensity,
        lights.radius, lights.kind, lights.height, heads, float(LAMP_HEAD_RADIUS), LAMP_COLOR * LAMP_HEAD_RADIANCE,
        float(ambient), float(EMISSIVE_GAIN), float(SKY_GAIN), lin,
    )  # fmt: skip
    gains = exposure_gains(lin)
    _encode(lin, gains, float(KNEE), rgb)
    return gains

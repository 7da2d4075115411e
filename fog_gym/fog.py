"""Calibrated fog physics: Koschmieder for cameras, Hahner et al. (ICCV 2021) for LiDAR. Pure numpy/numba.

Implemented from the equations (research note ``fog_physics.md`` §0–2), not from any reference code.

* Visibility ``V`` (meteorological optical range, 5 % contrast) ↔ extinction ``α = ln 20 / V``; presets
  light 160 m, moderate 100 m, dense 50 m; "clear" is ``V = ∞``, ``α = 0``. The same α drives camera and LiDAR.
* Camera: ``I = J·t + A·(1 − t)``, ``t = exp(−α·ℓ)`` with ℓ the Euclidean distance of each pixel (from planar
  depth and the intrinsics) and ``A`` the atmospheric light (dark channel 15×15, top 0.1 %, median grey).
* LiDAR: intensities on 0–255; hard target ``i_hard = round(i·exp(−2αR))``; soft fog response
  ``i_soft = min(255, I(R, α)·i·R²·β/β0)`` with β = 0.046/V, β0 = Γ/π, Γ = 1e-6 and ``I`` the backscatter
  integral of a 20 ns sin² pulse (a small table for the exact α, built on demand); a point is replaced by a
  fog return on its own ray when ``i_soft > i_hard``, with range noise variant v2 (noise 10 m). N out = N in.

Example:
    >>> level = parse_fog("dense")
    >>> level.visibility_m, round(level.alpha, 6)
    (50.0, 0.059915)
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from numba import njit, prange

import fog_gym._numba  # noqa: F401  (numba's fork-safe threading layer, before any kernel runs)

LN20 = math.log(20.0)
#: FogDrive's fog levels: visibility in metres.
FOG_PRESETS: dict[str, float] = {"light": 160.0, "moderate": 100.0, "dense": 50.0}

# LiDAR pulse and receiver (Hahner et al.; research note §1.1)
SPEED_OF_LIGHT = 299_792_458.0
TAU_H = 2e-8  # half-power pulse width [s]
XI_R1, XI_R2 = 0.9, 1.0  # linear beam/receiver overlap between R1 and R2 [m]
GAMMA = 1e-6  # target reflectivity Γ; β0 = Γ / π
BETA_PER_MOR = 0.046  # fog backscatter β = 0.046 / MOR
TABLE_STEP = 0.1  # R0 step of the soft-response table [m]
TABLE_MAX = 10.0  # beyond this the response is constant (it is from ≈ 4.7 m on)
_MEASURED_RANGES = np.linspace(0.0, 200.0, 2000)


@dataclass(frozen=True)
class FogLevel:
    """One fog condition: a name ("clear", "light", …, or e.g. "75m"), visibility [m] and extinction α [1/m].

    >>> FogLevel.from_visibility(100.0).name, FogLevel.from_visibility(75.0).channel_suffix
    ('moderate', 'FOG_75M')
    """

    name: str
    visibility_m: float
    alpha: float

    @classmethod
    def from_visibility(cls, visibility_m: float) -> FogLevel:
        v = float(visibility_m)
        if math.isinf(v):
            return cls("clear", math.inf, 0.0)
        name = next((k for k, pv in FOG_PRESETS.items() if pv == v), f"{v:g}m")
        return cls(name, v, LN20 / v)

    @property
    def is_clear(self) -> bool:
        return self.alpha == 0.0

    @property
    def channel_suffix(self) -> str:
        """``FOG_LIGHT`` etc. as in FogDrive's channel names; ``FOG_<V>M`` for other visibilities."""
        return "FOG_" + self.name.upper().replace(".", "P")

    def info(self) -> dict[str, float]:
        return {"visibility_m": self.visibility_m, "alpha": self.alpha}


def alpha_from_visibility(visibility_m: float) -> float:
    """α = ln 20 / V (5 % contrast threshold); 0 for V = ∞.

    >>> [round(alpha_from_visibility(v), 6) for v in (50, 100, 160)]
    [0.059915, 0.029957, 0.018723]
    """
    return parse_fog(visibility_m).alpha


def parse_fog(fog: str | float | int | FogLevel) -> FogLevel:
    """A level name ("clear", "light", "moderate", "dense") or a visibility in metres (> 0, may be inf)."""
    if isinstance(fog, FogLevel):
        return fog
    if isinstance(fog, str):
        key = fog.strip().lower()
        if key == "clear":
            return FogLevel("clear", math.inf, 0.0)
        if key in FOG_PRESETS:
            return FogLevel(key, FOG_PRESETS[key], LN20 / FOG_PRESETS[key])
        raise ValueError(
            f"fog must be one of ('clear', 'light', 'moderate', 'dense') or a visibility in metres > 0, got {fog!r}"
        )
    if isinstance(fog, bool) or not isinstance(fog, (int, float, np.integer, np.floating)):
        raise ValueError(f"fog must be a level name or a visibility in metres > 0, got {fog!r}")
    v = float(fog)
    if math.isnan(v) or v <= 0.0:
        raise ValueError(f"fog visibility must be a number of metres > 0 (or inf for clear), got {fog!r}")
    return FogLevel.from_visibility(v)


# ---------------------------------------------------------------------------------------------------------------
# Camera: Koschmieder


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


# Camera fog at night: airlight from the scene's lights, glow of bright sources

#: Night airlight: pixels nearer than this [m] light the fog; their ``NIGHT_AIRLIGHT_PERCENTILE`` colour is ``A``.
NIGHT_AIRLIGHT_RANGE, NIGHT_AIRLIGHT_PERCENTILE = 30.0, 75.0
#: Glow: sources are pixels at or above ``GLOW_THRESHOLD`` (any channel, 0–255), taken at ``GLOW_SOURCE_GAIN`` ×
#: their 8-bit value (a clipped lamp is far brighter than white); ``GLOW_FORWARD`` of the light they lose to fog
#: is scattered forwards into a Gaussian of angular width ``GLOW_WIDTH_RAD · (1 + α · GLOW_DISTANCE)``.
GLOW_THRESHOLD, GLOW_SOURCE_GAIN, GLOW_FORWARD = 240, 12.0, 0.5
GLOW_WIDTH_RAD, GLOW_DISTANCE = math.radians(0.6), 50.0


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


def glow_sigma_px(K: np.ndarray, alpha: float) -> float:
    """Width (pixels) of the glow around a bright source: ``fx · tan(GLOW_WIDTH_RAD · (1 + α · GLOW_DISTANCE))``."""
    return float(K[0, 0] * math.tan(GLOW_WIDTH_RAD * (1.0 + alpha * GLOW_DISTANCE)))


def add_glow(fogged: np.ndarray, clean: np.ndarray, depth: np.ndarray, K: np.ndarray, alpha: float) -> np.ndarray:
    """Forward-scattered light of bright sources (lamps, headlights) added to a fogged night image.

    A source pixel of radiance ``S`` (clean image, ≥ ``GLOW_THRESHOLD``, taken at ``GLOW_SOURCE_GAIN · S``) at
    ray distance ℓ loses ``1 − e^{−αℓ}`` of its light to the fog; ``GLOW_FORWARD`` of that is scattered forwards
    into a Gaussian of width :func:`glow_sigma_px`: ``G = N_σ * [η · g · S · (1 − e^{−αℓ})]`` and the result is
    ``min(255, fogged + G)``. Both the strength (through ``1 − e^{−αℓ}``) and the width grow with α; with
    ``α = 0`` nothing is added.

    >>> clean = np.zeros((41, 41, 3), np.uint8); clean[20, 20] = 255
    >>> K = np.array([[100.0, 0, 20.5], [0, 100.0, 20.5], [0, 0, 1]])
    >>> d = np.full((41, 41), 40.0, np.float32)
    >>> g = add_glow(np.zeros_like(clean), clean, d, K, 0.06)
    >>> bool(g[20, 24, 0] > g[20, 28, 0] > 0), int(add_glow(clean, clean, d, K, 0.0)[20, 19, 0])
    (True, 0)
    """
    if alpha <= 0.0:
        return fogged
    src = clean.max(axis=2) >= GLOW_THRESHOLD
    if not src.any():
        return fogged
    h, w = depth.shape
    sigma = max(glow_sigma_px(K, alpha), 0.5)
    # only the sources' bounding box grown by the kernel's reach can receive glow (OpenCV's float kernel spans
    # ±4σ): blur that window alone, with the same zero border
    reach = int(round(4.0 * sigma)) + 2
    rows, cols = np.flatnonzero(src.any(axis=1)), np.flatnonzero(src.any(axis=0))
    r0, r1 = max(rows[0] - reach, 0), min(rows[-1] + reach + 1, h)
    c0, c1 = max(cols[0] - reach, 0), min(cols[-1] + reach + 1, w)
    win = (slice(r0, r1), slice(c0, c1))
    ell = depth[win] * ray_length_factor(w, h, K)[win]
    weight = np.where(src[win], GLOW_FORWARD * GLOW_SOURCE_GAIN * (1.0 - np.exp(-alpha * ell)), 0.0).astype(np.float32)
    energy = clean[win].astype(np.float32) * weight[..., None]
    glow = cv2.GaussianBlur(energy, (0, 0), sigmaX=sigma, sigmaY=sigma, borderType=cv2.BORDER_CONSTANT)
    out = np.array(fogged, np.uint8, copy=True)
    out[win] = np.clip(fogged[win].astype(np.float32) + glow + 0.5, 0, 255).astype(np.uint8)
    return out


_F32 = np.float32


@njit(cache=True, inline="always", fastmath=True)
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


@njit(cache=True, parallel=True, fastmath=True)
def _koschmieder(rgb, depth, col_sq, row_sq, alphas, airlight_row, out):
    # rgb (H, 3W) and out (L, H, 3W) are viewed flat per row so every inner loop is contiguous (SIMD);
    # rows go in 16 chunks so each task allocates its scratch rows once
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
                for j in range(w):  # repeat each pixel's transmittance for its three channels
                    t3[3 * j] = t[j]
                    t3[3 * j + 1] = t[j]
                    t3[3 * j + 2] = t[j]
                for k in range(3 * w):
                    out[lv, i, k] = np.uint8(airlight_row[k] + diff[k] * t3[k] + np.float32(0.5))


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


def fog_images(rgb: np.ndarray, depth: np.ndarray, K: np.ndarray, alphas: Sequence[float], airlight: np.ndarray,
               validate: bool = True) -> np.ndarray:  # fmt: skip
    """Koschmieder fog at several extinctions in one pass: ``(L, H, W, 3)`` uint8 for ``alphas`` (all > 0).

    ``ℓ = z · sqrt(1 + ((u − cx)/fx)² + ((v − cy)/fy)²)`` at pixel centres; ``t = exp(−α·ℓ)``;
    ``I = A + (J − A)·t`` rounded. One read of image and depth serves every level. Inputs are checked
    (:func:`check_fog_inputs`) unless ``validate=False`` (the env's own frames, on the hot path).
    """
    if validate:
        check_fog_inputs(rgb, depth, K, alphas, airlight)
    h, w = depth.shape
    col = (((np.arange(w) + 0.5 - K[0, 2]) / K[0, 0]) ** 2).astype(np.float32)
    row = (((np.arange(h) + 0.5 - K[1, 2]) / K[1, 1]) ** 2).astype(np.float32)
    out = np.empty((len(alphas), h, w, 3), np.uint8)
    airlight_row = np.tile(np.asarray(airlight, np.float32), w)
    _koschmieder(np.ascontiguousarray(rgb).reshape(h, 3 * w), np.ascontiguousarray(depth, np.float32), col, row,
                 np.asarray(alphas, np.float32), airlight_row, out.reshape(len(alphas), h, 3 * w))  # fmt: skip
    return out


def fog_image(rgb: np.ndarray, depth: np.ndarray, K: np.ndarray, alpha: float, airlight: np.ndarray) -> np.ndarray:
    """Koschmieder fog on a uint8 RGB image with planar depth (metres) and intrinsic ``K``; ``alpha = 0`` copies.

    >>> img = np.zeros((2, 2, 3), np.uint8); depth = np.full((2, 2), 50.0, np.float32)
    >>> K = np.array([[1e6, 0, 1], [0, 1e6, 1], [0, 0, 1]])
    >>> fog_image(img, depth, K, alpha_from_visibility(50), np.array([200.0, 200, 200]))[0, 0].tolist()
    [190, 190, 190]
    """
    if alpha == 0.0:
        check_fog_inputs(rgb, depth, K, [1.0], airlight)
        return rgb.copy()
    return fog_images(rgb, depth, K, [alpha], airlight)[0]


# ---------------------------------------------------------------------------------------------------------------
# LiDAR: Hahner et al.


@functools.lru_cache(maxsize=32)
def soft_response_table(alpha: float, step: float = TABLE_STEP, max_range: float = TABLE_MAX,
                        samples: int = 4001) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """The fog backscatter integral for extinction ``alpha``: ``(I, R_tmp)`` on R0 = 0, step, …, max_range.

    ``F(R) = ∫₀^{2τ_H} sin²(πt / 2τ_H) · exp(−2αR′) · ξ(R′) / R′² dt`` with ``R′ = R − ct/2`` (s/m²; 1/R′² is
    0 for R′ ≤ R1). For a hard target at R0 the receiver sees ``F`` only up to R0, so ``I(R0) = max_{R ≤ R0} F(R)``
    and ``R_tmp(R0)`` is where that maximum lies. Composite Simpson over t; measured ranges R on the reference
    tables' grid (2000 points over 0–200 m), so ``I`` and ``R_tmp`` match the published tables.

    >>> I, R = soft_response_table(0.06)
    >>> f"{I[-1]:.4g}", round(float(R[-1]), 1)
    ('3.816e-09', 4.6)
    """
    n = samples + (1 - samples % 2)  # Simpson needs an odd count
    t = np.linspace(0.0, 2 * TAU_H, n)
    pulse = np.sin(np.pi * t / (2 * TAU_H)) ** 2
    weights = np.ones(n)
    weights[1:-1:2], weights[2:-1:2] = 4.0, 2.0
    weights *= (t[1] - t[0]) / 3.0
    r_grid = _MEASURED_RANGES[_MEASURED_RANGES <= max_range + 0.2]
    rp = r_grid[:, None] - SPEED_OF_LIGHT * t[None, :] / 2.0
    xi = np.clip((rp - XI_R1) / (XI_R2 - XI_R1), 0.0, 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_sq = np.where(rp > XI_R1, 1.0 / np.maximum(rp, 1e-12) ** 2, 0.0)
    # where rp <= r1 the overlap xi is 0; clamping there keeps exp finite for any alpha without changing F
    F = (pulse[None, :] * np.exp(-2.0 * alpha * np.maximum(rp, XI_R1)) * xi * inv_sq) @ weights
    running = np.maximum.accumulate(F)
    arg = np.zeros(len(F), np.int64)
    best = 0
    for k in range(len(F)):  # index of the running maximum
        if F[k] > F[best]:
            best = k
        arg[k] = best
    r0 = np.arange(0.0, max_range + 1e-9, step)
    idx = np.searchsorted(r_grid, r0 + 1e-9, side="right") - 1  # last measured range ≤ R0
    return running[idx], np.where(running[idx] > 0, r_grid[arg[idx]], 0.0)


def lidar_crossover_range(level: FogLevel) -> float:
    """Range beyond which every return becomes a fog return (``R²·I·β/β0 > exp(−2αR)``), in metres."""
    I, _ = soft_response_table(level.alpha)
    beta, beta0 = BETA_PER_MOR / level.visibility_m, GAMMA / math.pi
    r = np.arange(5.0, 1000.0, 0.01)
    return float(r[np.argmax(r**2 * I[-1] * beta / beta0 > np.exp(-2 * level.alpha * r))])


@njit(cache=True, parallel=True)
def _hahner(pts, table_i, table_r, alpha, beta_ratio, log_noise, u, out):
    last = table_i.shape[0] - 1
    for n in prange(pts.shape[0]):
        x, y, z = np.float64(pts[n, 0]), np.float64(pts[n, 1]), np.float64(pts[n, 2])
        r0 = np.sqrt(x * x + y * y + z * z)
        i_orig = np.round(np.float64(pts[n, 3]) * 255.0)
        i_hard = np.round(i_orig * np.exp(-2.0 * alpha * r0))
        key = min(int(np.round(min(r0, 200.0) / TABLE_STEP)), last)
        i_soft = min(255.0, table_i[key] * i_orig * r0 * r0 * beta_ratio)
        if i_soft > i_hard:  # the fog's own return is stronger: a fog point on the same ray
            scale = table_r[key] / max(r0, 1e-12) * np.exp(log_noise * u[n])
            out[n, 0] = np.float32(x * scale)
            out[n, 1] = np.float32(y * scale)
            out[n, 2] = np.float32(z * scale)
            out[n, 3] = np.float32(i_soft / 255.0)
        else:
            out[n, 0] = pts[n, 0]
            out[n, 1] = pts[n, 1]
            out[n, 2] = pts[n, 2]
            out[n, 3] = np.float32(i_hard / 255.0)
        for c in range(4, pts.shape[1]):
            out[n, c] = pts[n, c]


def fog_lidar(points: np.ndarray, level: FogLevel, rng: np.random.Generator, noise: float = 10.0) -> np.ndarray:
    """Hahner et al. fog on CARLA LiDAR points ``(N, 4)`` x, y, z, intensity ∈ [0, 1] → ``(N, 4)`` float32.

    Intensities are scaled to 0–255 and rounded; each point either stays with ``round(i·exp(−2αR))`` or, when the
    soft fog response is stronger, moves to ``R_tmp·f`` on its own ray (noise v2: ``f = max(1, noise/5)^u``,
    ``u ~ U(−1, 1)``) with the soft intensity; intensities return to [0, 1] (/255). Clear fog returns a copy.

    >>> pts = np.array([[100.0, 0, 0, 0.67], [10.0, 0, 0, 0.96]], np.float32)
    >>> out = fog_lidar(pts, parse_fog("dense"), np.random.default_rng(0))
    >>> bool(np.linalg.norm(out[0, :3]) < 10), out[1, :3].tolist()  # far point → fog return, near point kept
    (True, [10.0, 0.0, 0.0])
    """
    pts = np.asarray(points, np.float32)
    if pts.ndim != 2 or pts.shape[1] < 4:
        raise ValueError(f"expected LiDAR points of shape (N, 4), got {pts.shape}")
    if not np.isfinite(pts).all():
        raise ValueError("LiDAR points must be finite (no NaN or inf)")
    if not math.isfinite(noise) or noise < 0:
        raise ValueError(f"noise must be a finite number of metres >= 0, got {noise!r}")
    if level.is_clear:
        return pts.copy()
    table_i, table_r = soft_response_table(level.alpha)
    u = rng.uniform(-1.0, 1.0, len(pts))
    out = np.empty_like(pts)
    _hahner(pts, table_i, table_r, level.alpha, BETA_PER_MOR / level.visibility_m / (GAMMA / math.pi),
            math.log(max(1.0, noise / 5.0)) if noise > 0 else 0.0, u, out)  # fmt: skip
    return out

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
from dataclasses import dataclass

import cv2
import numpy as np
from numba import njit, prange

import fog_gym.render.raster  # noqa: F401  (sets numba's fork-safe threading layer before any kernel runs)

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
    dark = cv2.erode(img.min(axis=2), np.ones((window, window), np.uint8))
    k = max(1, int(math.floor(top_fraction * dark.size)))
    k += 1 - k % 2
    flat = dark.reshape(-1)
    top = np.argpartition(flat, flat.size - k)[flat.size - k :]
    pixels = img.reshape(-1, 3)[top].astype(np.float64)
    grey = pixels @ np.array([0.2989, 0.5870, 0.1140])
    return pixels[np.argsort(grey, kind="stable")[k // 2]]


@functools.lru_cache(maxsize=32)
def _transmittance_lut(alpha: float, step: float = 0.01, max_length: float = 2000.0) -> np.ndarray:
    return np.exp(-alpha * np.arange(0.0, max_length + step, step)).astype(np.float32)


@njit(cache=True, parallel=True)
def _koschmieder(rgb, depth, factor, lut, inv_step, airlight, out):
    h, w = depth.shape
    last = lut.shape[0] - 1
    for i in prange(h):
        for j in range(w):
            k = int(depth[i, j] * factor[i, j] * inv_step + 0.5)
            t = lut[min(k, last)]
            for c in range(3):
                out[i, j, c] = np.uint8(rgb[i, j, c] * t + airlight[c] * (1.0 - t) + 0.5)


def fog_image(rgb: np.ndarray, depth: np.ndarray, K: np.ndarray, alpha: float, airlight: np.ndarray,
              factor: np.ndarray | None = None) -> np.ndarray:  # fmt: skip
    """Koschmieder fog on a uint8 RGB image with planar depth (metres) and intrinsic ``K``.

    ``t = exp(−α·ℓ)`` is read from a table at 1 cm steps of ℓ (|error| < α·5 mm, far below 1/255).
    ``alpha = 0`` returns a copy of the input. ``factor`` (from :func:`ray_length_factor`) may be passed to
    save its computation.

    >>> img = np.full((2, 2, 3), 10, np.uint8); depth = np.full((2, 2), 50.0, np.float32)
    >>> K = np.array([[1e6, 0, 1], [0, 1e6, 1], [0, 0, 1]])
    >>> fog_image(img, depth, K, alpha_from_visibility(50), np.array([200.0, 200, 200]))[0, 0].tolist()
    [190, 190, 190]
    """
    if alpha == 0.0:
        return rgb.copy()
    h, w = depth.shape
    if factor is None:
        factor = ray_length_factor(w, h, K)
    out = np.empty_like(rgb)
    _koschmieder(rgb, np.ascontiguousarray(depth, np.float32), factor, _transmittance_lut(float(alpha)), 100.0,
                 np.asarray(airlight, np.float64), out)  # fmt: skip
    return out


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
    F = (pulse[None, :] * np.exp(-2.0 * alpha * rp) * xi * inv_sq) @ weights
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
    if level.is_clear:
        return pts.copy()
    table_i, table_r = soft_response_table(level.alpha)
    xyz = pts[:, :3].astype(np.float64)
    r0 = np.sqrt((xyz * xyz).sum(axis=1))
    i_orig = np.round(pts[:, 3].astype(np.float64) * 255.0)
    i_hard = np.round(i_orig * np.exp(-2.0 * level.alpha * r0))
    key = np.minimum(np.round(np.minimum(r0, 200.0) / TABLE_STEP).astype(np.int64), len(table_i) - 1)
    beta = BETA_PER_MOR / level.visibility_m
    i_soft = np.minimum(255.0, table_i[key] * i_orig * r0 * r0 * beta / (GAMMA / math.pi))
    replace = i_soft > i_hard
    factor = max(1.0, noise / 5.0) ** rng.uniform(-1.0, 1.0, len(pts)) if noise > 0 else np.ones(len(pts))
    out = pts.copy()
    with np.errstate(divide="ignore", invalid="ignore"):
        scale = np.where(replace, table_r[key] / np.maximum(r0, 1e-12) * factor, 1.0)
    out[:, :3] = (xyz * scale[:, None]).astype(np.float32)
    out[:, 3] = (np.where(replace, i_soft, i_hard) / 255.0).astype(np.float32)
    return out

"""Hahner et al. (ICCV 2021) fog for LiDAR point clouds, implemented from the equations (``fog_physics.md`` §2).

Intensities on 0–255; hard target ``i_hard = round(i·exp(−2αR))``; soft fog response
``i_soft = min(255, I(R, α)·i·R²·β/β0)`` with β = 0.046/V, β0 = Γ/π, Γ = 1e-6 and ``I`` the backscatter integral of a
20 ns sin² pulse (a small table for the exact α, built on demand); a point is replaced by a fog return on its own
ray when ``i_soft > i_hard``, with range noise variant v2 (noise 10 m). N out = N in.

Example:
    >>> from fog_gym.fog.physics import parse_fog
    >>> round(lidar_crossover_range(parse_fog("dense")), 1)
    35.6
"""

from __future__ import annotations

import functools
import math

import numpy as np
from numba import njit, prange

import fog_gym._numba  # noqa: F401  (numba's fork-safe threading layer, before any kernel runs)
from fog_gym._numba import pick, serial_twin
from fog_gym.fog.physics import FogLevel

# LiDAR pulse and receiver (Hahner et al.; research note §1.1)
SPEED_OF_LIGHT = 299_792_458.0
TAU_H = 2e-8  # half-power pulse width [s]
XI_R1, XI_R2 = 0.9, 1.0  # linear beam/receiver overlap between R1 and R2 [m]
GAMMA = 1e-6  # target reflectivity Γ; β0 = Γ / π
BETA_PER_MOR = 0.046  # fog backscatter β = 0.046 / MOR
TABLE_STEP = 0.1  # R0 step of the soft-response table [m]
TABLE_MAX = 10.0  # beyond this the response is constant (it is from ≈ 4.7 m on)
_MEASURED_RANGES = np.linspace(0.0, 200.0, 2000)


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


@njit(cache=True, inline="always")
def hahner_intensities(r0, intensity, table_i, alpha, beta_ratio):
    """The rule's two intensities (0–255) of a return at range ``r0`` with CARLA intensity ``intensity`` ∈ [0, 1]:
    ``(i_hard, i_soft, table key)``; a fog return replaces the point when ``i_soft > i_hard``."""
    last = table_i.shape[0] - 1
    i_orig = np.round(intensity * 255.0)
    i_hard = np.round(i_orig * np.exp(-2.0 * alpha * r0))
    key = min(int(np.round(min(r0, 200.0) / TABLE_STEP)), last)
    i_soft = min(255.0, table_i[key] * i_orig * r0 * r0 * beta_ratio)
    return i_hard, i_soft, key


@njit(cache=True, nogil=True, inline="always")
def hahner_keeps(r0, intensity, table_i, table_r, alpha, beta_ratio):
    """Whether a return at range ``r0`` with intensity ``intensity`` survives the fog (``i_soft <= i_hard``); the
    same decision :func:`fog_lidar` makes per point, for the perception kernels."""
    i_hard, i_soft, _ = hahner_intensities(r0, intensity, table_i, alpha, beta_ratio)
    return not i_soft > i_hard


@njit(cache=True, nogil=True, parallel=True)
def _hahner(pts, c_in, table_i, table_r, alpha, beta_ratio, log_noise, u, out, attenuation, mode, floor, flags, behind):
    """Each beam's decision into row ``n`` of ``out`` from the first ``c_in`` columns of ``pts`` (its first ``c_in``
    columns; further columns, a packed channel's ``return``, get 0). ``mode`` 0 strongest; 1 last (a hard target at or above ``floor`` behind a fog
    return takes the row back); 2 dual (such a beam gets ``flags[n]`` 1 and its target's intensity in
    ``behind[n]``, for :func:`_append_last` to add as an extra row)."""
    for n in prange(pts.shape[0]):
        x, y, z = np.float64(pts[n, 0]), np.float64(pts[n, 1]), np.float64(pts[n, 2])
        r0 = np.sqrt(x * x + y * y + z * z)
        ratio = beta_ratio
        if attenuation >= 0.0:  # reflectance intensities: the point's own reflectivity stands in for Γ
            rho = min(max(np.float64(pts[n, 3]) / np.exp(-attenuation * r0), 1e-3), 1.0)
            ratio = beta_ratio * REFERENCE_REFLECTIVITY / rho
        i_hard, i_soft, key = hahner_intensities(r0, np.float64(pts[n, 3]), table_i, alpha, ratio)
        fx, fy, fz = np.float32(0.0), np.float32(0.0), np.float32(0.0)
        seen = False  # dual: the hard target detected behind the fog's stronger echo (the beam's last return)
        fog = i_soft > i_hard  # the fog's echo is the stronger: a point on the same ray
        if fog:
            scale = table_r[key] / max(r0, 1e-12) * np.exp(log_noise * u[n])
            fx, fy, fz = np.float32(x * scale), np.float32(y * scale), np.float32(z * scale)
            # the last echo differs where the target reaches the floor (a fog echo on the target itself is its echo)
            later = mode > 0 and i_hard >= floor and not (fx == pts[n, 0] and fy == pts[n, 1] and fz == pts[n, 2])
            fog = not (later and mode == 1)  # "last": the target takes the row back
            seen = later and mode == 2
        if fog:
            out[n, 0] = fx
            out[n, 1] = fy
            out[n, 2] = fz
            out[n, 3] = np.float32(i_soft / 255.0)
        else:
            out[n, 0] = pts[n, 0]
            out[n, 1] = pts[n, 1]
            out[n, 2] = pts[n, 2]
            out[n, 3] = np.float32(i_hard / 255.0)
        for c in range(4, c_in):
            out[n, c] = pts[n, c]
        for c in range(c_in, out.shape[1]):
            out[n, c] = 0.0
        if flags.shape[0] > 0:
            flags[n] = seen
            if seen:
                behind[n] = i_hard


@njit(cache=True, nogil=True)
def _append_last(pts, c, flags, behind, out):
    """The dual mode's extra rows after the first N: each flagged beam's hard target (the first ``c`` columns of
    ``pts``) with its intensity and ``return`` 1. Returns the number of rows written in all."""
    n = pts.shape[0]
    r = n
    words = flags[: n - n % 8].view(np.uint64)  # eight beams at a time: most words of a sweep hold no flag
    for w in range(words.shape[0] + 1):
        if w < words.shape[0] and words[w] == 0:
            continue
        for k in range(8 * w, min(8 * w + 8, n)):
            if flags[k]:
                for j in range(c):
                    out[r, j] = pts[k, j]
                out[r, 3] = np.float32(behind[k] / 255.0)
                out[r, c] = 1.0
                r += 1
    return r


_hahner_serial = serial_twin(_hahner)


_NO_HARD = np.zeros(0)
_NO_FLAGS = np.zeros(0, np.uint8)

#: With reflectance intensities (:func:`fog_lidar`'s ``reflectance``), the reflectivity decided about as CARLA's
#: intensities are under Hahner et al.'s constant Γ.
REFERENCE_REFLECTIVITY = 0.3


def _checked_points(points: np.ndarray, noise: float) -> np.ndarray:
    """The points as float32 ``(N, 4+)``, or a ``ValueError`` naming what is wrong with them or with ``noise``."""
    pts = np.asarray(points, np.float32)
    if pts.ndim != 2 or pts.shape[1] < 4:
        raise ValueError(f"expected LiDAR points of shape (N, 4), got {pts.shape}")
    if not np.isfinite(pts).all():
        raise ValueError("LiDAR points must be finite (no NaN or inf)")
    if not math.isfinite(noise) or noise < 0:
        raise ValueError(f"noise must be a finite number of metres >= 0, got {noise!r}")
    return pts


def fog_lidar(points: np.ndarray, level: FogLevel, rng: np.random.Generator, noise: float = 10.0,
              reflectance: float | None = None, out: np.ndarray | None = None) -> np.ndarray:  # fmt: skip
    """Hahner et al. fog on CARLA LiDAR points ``(N, 4)`` x, y, z, intensity ∈ [0, 1] → ``(N, 4)`` float32.

    Intensities are scaled to 0–255 and rounded; each point either stays with ``round(i·exp(−2αR))`` or, when the
    soft fog response is stronger, moves to ``R_tmp·f`` on its own ray (noise v2: ``f = max(1, noise/5)^u``,
    ``u ~ U(−1, 1)``) with the soft intensity; intensities return to [0, 1] (/255). Clear fog returns a copy.

    >>> from fog_gym.fog.physics import parse_fog
    >>> pts = np.array([[100.0, 0, 0, 0.67], [10.0, 0, 0, 0.96]], np.float32)
    >>> out = fog_lidar(pts, parse_fog("dense"), np.random.default_rng(0))
    >>> bool(np.linalg.norm(out[0, :3]) < 10), out[1, :3].tolist()  # far point → fog return, near point kept
    (True, [10.0, 0.0, 0.0])

    ``reflectance`` (the LiDAR's atmosphere attenuation rate, for intensities ``ρ·|cos θ|·exp(−a·d)`` of the
    ``"reflectance"`` intensity model) makes the fog see each target's own reflectivity: Hahner et al. derive the
    sensor's constant from a point's intensity under one assumed target reflectivity Γ, so with CARLA's intensities
    the fog's decision does not depend on the target; with reflectance intensities the sensor constant stays fixed
    (a target of :data:`REFERENCE_REFLECTIVITY` is decided about as CARLA's intensities are, within the rounding of
    0–255 intensities) and the hard return scales with ``ρ|cos θ|`` while the fog's own backscatter does not — bright
    surfaces (licence plates, lane markings) outlast dark paint.

    ``out`` (an ``(N, C)`` float32 array, optional; a view will do, such as the first rows of a packed channel)
    receives the result, which is then returned (:func:`fog_lidar_into` writes a packed channel with the return
    modes).
    """
    pts = _checked_points(points, noise)
    if out is not None and (not isinstance(out, np.ndarray) or out.shape != pts.shape or out.dtype != np.float32):
        raise ValueError(f"out must be a float32 array of the points' shape {pts.shape}, got "
                         f"{getattr(out, 'dtype', type(out).__name__)} {getattr(out, 'shape', '')}")  # fmt: skip
    if level.is_clear:
        if out is not None:
            out[...] = pts
            return out
        return pts.copy()
    out = np.empty_like(pts) if out is None else out
    _run_hahner(pts, pts.shape[1], level, rng, noise, reflectance, out, 0, 0.0, _NO_FLAGS, _NO_HARD)
    return out


def _run_hahner(pts, c, level, rng, noise, reflectance, out, mode, floor, flags, behind) -> None:
    """One draw of the range noise per point and :func:`_hahner` over the points (both fog entry points)."""
    table_i, table_r = soft_response_table(level.alpha)
    u = rng.uniform(-1.0, 1.0, len(pts))
    pick(_hahner, _hahner_serial, len(pts))(
        pts, c, table_i, table_r, level.alpha, BETA_PER_MOR / level.visibility_m / (GAMMA / math.pi),
        math.log(max(1.0, noise / 5.0)) if noise > 0 else 0.0, u, out, -1.0 if reflectance is None else float(reflectance),
        mode, floor, flags, behind,
    )  # fmt: skip


@njit(cache=True, nogil=True, parallel=True)
def _zero_rows(channel, start):
    """``channel[start:] = 0`` for a C-contiguous 2-D channel, in eight parallel chunks: a dual channel's empty
    tail is about 1.9 MB (95 000 rows of 5), which one thread clears in 54 µs and two in 34 µs (this project's
    two-core machine)."""
    flat = channel.reshape(-1)
    first = start * channel.shape[1]
    n = flat.shape[0] - first
    for c in prange(8):
        flat[first + c * n // 8:first + (c + 1) * n // 8] = 0.0


_zero_rows_serial = serial_twin(_zero_rows)
#: Values of a channel's empty tail from which :func:`fog_lidar_into` clears it in parallel (a quarter of a MB).
ZERO_SERIAL_BELOW = 1 << 16


def _clear_tail(channel: np.ndarray, rows: int) -> None:
    """Zero the rows of a packed channel after its first ``rows`` (in parallel from :data:`ZERO_SERIAL_BELOW`)."""
    pick(_zero_rows, _zero_rows_serial, (len(channel) - rows) * channel.shape[1], ZERO_SERIAL_BELOW)(channel, rows)


def fog_lidar_into(points: np.ndarray, level: FogLevel, rng: np.random.Generator, channel: np.ndarray,
                   mode: str = "strongest", noise: float = 10.0, reflectance: float | None = None,
                   columns: int | None = None) -> int:  # fmt: skip
    """:func:`fog_lidar` and the return rule (:mod:`fog_gym.fog.returns`) in one pass over the beams, written into a
    packed point channel: ``channel`` a float32 ``(capacity, C)`` array (``"strongest"``, ``"last"``) or ``(capacity,
    C + 1)`` (``"dual"``, its last column ``return``) for the ``(N, C)`` points, ``capacity`` ≥ N (2 N for dual).
    Every row is written (the rows after the sweep become 0), so the channel may be uninitialised. Returns the
    number of points written: the same rows as :func:`fog_lidar` then
    :func:`~fog_gym.fog.returns.apply_returns` with the channel's capacity, from the same draws of ``rng``.
    ``columns``: the points are the first ``columns`` columns of ``points`` (the rest ignored: a dual sweep's own
    ``return`` column, read in place); C is then ``columns``.

    >>> from fog_gym.fog.physics import parse_fog
    >>> pts = np.array([[40.0, 0, 0, 0.9], [10.0, 0, 0, 0.96]], np.float32)
    >>> channel = np.full((4, 5), np.nan, np.float32)
    >>> fog_lidar_into(pts, parse_fog("dense"), np.random.default_rng(0), channel, "dual")  # the far car twice
    3
    >>> bool(channel[0, 0] < 10), channel[2].tolist(), channel[3].tolist()  # fog echo; last echo (return 1); empty
    (True, [40.0, 0.0, 0.0, 0.007843137718737125, 1.0], [0.0, 0.0, 0.0, 0.0, 0.0])
    """
    from fog_gym.fog.returns import DETECTION_FLOOR, check_mode

    check_mode(mode)
    pts = _checked_points(points, noise)
    n, c = pts.shape
    if columns is not None:
        if isinstance(columns, bool) or not isinstance(columns, (int, np.integer)) or not 4 <= columns <= c:
            raise ValueError(f"columns must be a number of leading columns from 4 to {c} or None, got {columns!r}")
        c = int(columns)
    dual = mode == "dual"
    if not (isinstance(channel, np.ndarray) and channel.dtype == np.float32 and channel.ndim == 2
            and channel.flags.c_contiguous and channel.shape[1] == c + dual and len(channel) >= (2 * n if dual else n)):  # fmt: skip
        raise ValueError(f"channel must be a C-contiguous float32 ({'2 × ' if dual else ''}{n} or more, {c + dual}) "
                         f"point channel for the {mode} returns of {n} points, got "
                         f"{getattr(channel, 'dtype', type(channel).__name__)} {getattr(channel, 'shape', '')}")  # fmt: skip
    if level.is_clear:  # every mode is the clean sweep
        channel[:n, :c] = pts[:, :c]
        channel[:n, c:] = 0.0
        _clear_tail(channel, n)
        return n
    flags, behind = (np.empty(n, np.uint8), np.empty(n)) if dual else (_NO_FLAGS, _NO_HARD)
    _run_hahner(pts, c, level, rng, noise, reflectance, channel, RETURN_CODES[mode], DETECTION_FLOOR, flags, behind)
    rows = _append_last(pts, c, flags, behind, channel) if dual else n
    _clear_tail(channel, rows)
    return rows


#: :func:`_hahner`'s ``mode`` per return mode.
RETURN_CODES = {"strongest": 0, "last": 1, "dual": 2}

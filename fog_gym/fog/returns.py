"""LiDAR return modes in fog: strongest, last and dual, from Hahner et al.'s received-power model. Pure numpy.

Hahner et al.'s model gives each beam two candidate echoes: the fog's own backscatter (the "soft" return, at the
range where it peaks) and the hard target attenuated by the fog, ``i_hard = round(i · e^{−2τ})`` on the model's
0–255 scale (``τ`` the optical depth to the target: ``α·R`` in homogeneous fog). A spinning LiDAR reports
(Velodyne HDL-64E S3 and VLP-16 manuals: strongest, last or both):

* ``"strongest"`` — the stronger echo: the fog return replaces the point when ``i_soft > i_hard`` (the model's own
  rule; fog-gym's output since the first release, bit for bit);
* ``"last"`` — the farthest echo the receiver detects: the hard target whenever ``i_hard`` reaches the detection
  floor, else the strongest;
* ``"dual"`` — both: the strongest, and the last where it differs (an extra point), each row with a ``return``
  column — 0 for a beam's strongest echo (also its only one when the two coincide), 1 for a last echo that is not
  the strongest. A beam's last return is its row with 1, or else its row with 0.

**The detection floor** (:data:`DETECTION_FLOOR`) is one level of the model's 8-bit intensity scale: an echo
whose attenuated intensity rounds to 0 of 255 carries no signal the 0–255 scale can report (Hahner et al. work on
intensities quantised to 0–255, §3 of their paper), so the receiver cannot have detected it.

In clear air every mode gives the clean sweep (dual: with ``return`` = 0 everywhere).

Example:
    >>> clean = np.array([[30.0, 0, 0, 0.8], [40.0, 0, 0, 0.02]], np.float32)
    >>> fog = clean.copy(); fog[:, :3] *= 0.1; fog[:, 3] = 0.2  # both became fog returns (the strongest echoes)
    >>> tau = np.array([0.9, 1.2])  # optical depth to each target
    >>> apply_returns(clean, fog, tau, "last")[:, 0].tolist()  # the bright target survives as the last echo
    [30.0, 4.0]
    >>> apply_returns(clean, fog, tau, "dual").tolist()
    [[3.0, 0.0, 0.0, 0.20000000298023224, 0.0], [4.0, 0.0, 0.0, 0.20000000298023224, 0.0], [30.0, 0.0, 0.0, 0.13333334028720856, 1.0]]
"""

from __future__ import annotations

import numpy as np
from numba import njit

from fog_gym.fog.depth import segment_depth

RETURN_MODES = ("strongest", "last", "dual")
#: The smallest intensity a receiver detects, on the model's 0–255 scale (module docstring).
DETECTION_FLOOR = 1.0


def check_mode(mode: str) -> str:
    if mode not in RETURN_MODES:
        raise ValueError(f"returns must be one of {RETURN_MODES}, got {mode!r}")
    return mode


def hard_intensity(points: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """The hard target's attenuated intensity on 0–255, ``round(round(i · 255) · e^{−2τ})`` (Hahner et al.'s
    rounding, as :func:`fog_gym.fog.lidar.fog_lidar` computes it)."""
    i_orig = np.round(np.asarray(points, np.float64)[:, 3] * 255.0)
    return np.round(i_orig * np.exp(-2.0 * np.asarray(tau, np.float64)))


def apply_returns(clean: np.ndarray, strongest: np.ndarray, tau: np.ndarray | None, mode: str,
                  alpha: float | None = None, capacity: int | None = None) -> np.ndarray:  # fmt: skip
    """The sweep a LiDAR in ``mode`` reports, from the clean sweep, the model's strongest-echo output (same rows) and
    the optical depth ``tau`` (N,) from the sensor to each clean point (or, for homogeneous fog, ``tau`` None and the
    extinction ``alpha``: ``τ = α·R``): ``(N, C)`` for ``strongest`` and ``last``, ``(N + M, C + 1)`` for ``dual``
    (the strongest rows first, in order, then the M extra last echoes, in order). ``capacity``: the result packed into a
    ``(capacity, …)`` point channel (:func:`fog_gym.channels.pack_points`), written there directly."""
    check_mode(mode)
    clean = np.asarray(clean, np.float32)
    strongest = np.asarray(strongest, np.float32)
    if clean.shape != strongest.shape:
        raise ValueError(f"clean and strongest must be the same sweep, got shapes {clean.shape} and {strongest.shape}")
    if mode == "strongest":
        return strongest
    if tau is None and alpha is None:
        raise ValueError("apply_returns needs the optical depths tau or, for homogeneous fog, alpha")
    tau_arr = np.zeros(0) if tau is None else np.ascontiguousarray(np.broadcast_to(np.asarray(tau, np.float64), (len(clean),)))
    a = 0.0 if tau is not None else float(alpha)
    dual = mode == "dual"
    n = len(clean)
    if capacity is not None and (int(capacity) < n or (dual and int(capacity) < 2 * n)):
        raise ValueError(f"capacity {capacity} cannot hold the {mode} returns of {n} beams")
    rows = (2 * n if dual else n) if capacity is None else int(capacity)
    out = np.zeros((rows, clean.shape[1] + dual), np.float32)
    r = _returns_kernel(np.ascontiguousarray(clean), np.ascontiguousarray(strongest), out, tau_arr, a, dual,
                        DETECTION_FLOOR)  # fmt: skip
    return out if capacity is not None or r == rows else out[:r].copy()


@njit(cache=True, nogil=True)
def _returns_kernel(clean, strongest, out, tau, alpha, dual, floor):
    """The return rule in one pass over the beams, into ``out`` (zeros after its first rows): its first N rows the
    strongest echoes (copied from ``strongest``); "last" (``dual`` False) rewrites a row whose hard target reaches
    the floor behind the fog, "dual" appends it after the N rows with ``return`` 1. The hard intensities (0–255) from
    ``tau``, or with ``tau`` empty from ``α·R`` (homogeneous fog, as :func:`homogeneous_tau`). Returns the number of
    rows written."""
    n, c = clean.shape
    r = n  # the next extra row (dual)
    for k in range(n):
        for j in range(c):
            out[k, j] = strongest[k, j]
        if out[k, 0] == clean[k, 0] and out[k, 1] == clean[k, 1] and out[k, 2] == clean[k, 2]:
            continue  # the strongest echo is the target itself
        if tau.shape[0] > 0:
            t = tau[k]
        else:
            x, y, z = np.float64(clean[k, 0]), np.float64(clean[k, 1]), np.float64(clean[k, 2])
            t = alpha * np.sqrt(x * x + y * y + z * z)
        h = np.round(np.round(np.float64(clean[k, 3]) * 255.0) * np.exp(-2.0 * t))
        if h < floor:  # nothing the receiver detects behind the fog
            continue
        row = r if dual else k  # "last": the hard target replaces the fog's echo; "dual": an extra row
        for j in range(c):
            out[row, j] = clean[k, j]
        out[row, 3] = np.float32(h / 255.0)
        if dual:
            out[row, c] = 1.0
            r += 1
    return r


def homogeneous_tau(points: np.ndarray, alpha: float) -> np.ndarray:
    """``α · R`` to each point (its range from the sensor)."""
    return alpha * np.linalg.norm(np.asarray(points, np.float64)[:, :3], axis=1)


def field_tau(points: np.ndarray, field, pose: np.ndarray, time: float = 0.0) -> np.ndarray:
    """The optical depth of a fog field from the sensor to each point (``pose``: the sensor in the field frame,
    :func:`fog_gym.fog.depth.field_pose`), in closed form."""
    p = np.asarray(points, np.float64)[:, :3]
    r = np.linalg.norm(p, axis=1)
    d = p / np.maximum(r, 1e-12)[:, None]
    pose = np.asarray(pose, np.float64)
    du = d @ pose[2:5]
    dz = d @ pose[5:8]
    return field.optical_depth(np.full(len(r), pose[0]), np.full(len(r), pose[1]), du, dz, r, time)


@njit(cache=True, nogil=True)
def last_detected(r0, intensity, alpha):
    """Whether the hard target at range ``r0`` (CARLA intensity ∈ [0, 1]) reaches the detection floor through
    homogeneous fog of extinction ``alpha``: a last-return LiDAR reports it (for the perception kernels)."""
    return np.round(np.round(intensity * 255.0) * np.exp(-2.0 * alpha * r0)) >= DETECTION_FLOOR


@njit(cache=True, nogil=True)
def field_last_detected(r0, intensity, terms, u0, z0, du, dz):
    """:func:`last_detected` in a fog field (``terms``, the beam ``(u0, z0, du, dz)`` in the field frame)."""
    tau = segment_depth(terms, u0, z0, du, dz, r0)
    return np.round(np.round(intensity * 255.0) * np.exp(-2.0 * tau)) >= DETECTION_FLOOR

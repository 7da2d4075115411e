"""Hahner et al.'s LiDAR fog with a fog field (:mod:`fog_gym.fog.fields`): the local extinction β(r) along each beam
(``docs/fog.md``, "Fog with a shape"). :func:`fog_lidar_field` is the entry; a homogeneous field goes through
:func:`fog_gym.fog.lidar.fog_lidar`.

Three paths give the same decisions (tested against each other and against a direct integration of the LiDAR
equation): fields whose β depends on height only read one soft-return curve per beam elevation; a single fog bank
reads curves per beam run along the bank's axis, aligned on the bank's face (:mod:`fog_gym.fog.lidar_bank`); any
other field integrates each beam on its own (:func:`_hahner_field`). The shared parts (the pulse's kernel, the curves,
the rule) are in :mod:`fog_gym.fog.lidar_pulse`; the height path in :mod:`fog_gym.fog.lidar_height`.

Example:
    >>> from fog_gym.fog.fields import FogBank
    >>> from fog_gym.fog.depth import field_pose
    >>> pts = np.array([[30.0, 0, 0, 0.5], [120.0, 0, 0, 0.5]], np.float32)
    >>> pose = field_pose(np.eye(4), (0, 0, 0))
    >>> out = fog_lidar_field(pts, FogBank(20.0, 60.0, 30.0), np.random.default_rng(0), pose, noise=0.0)
    >>> out[0].tolist() == pts[0].tolist(), bool(50.0 < out[1, 0] < 70.0)  # kept before the bank; behind: its face
    (True, True)
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

import fog_gym._numba  # noqa: F401  (numba's fork-safe threading layer, before any kernel runs)
from fog_gym._numba import launch
from fog_gym.fog.depth import BANK, point_extinction, segment_depth
from fog_gym.fog.lidar import GAMMA, XI_R1, XI_R2, _checked_points, fog_lidar
from fog_gym.fog.lidar_bank import fog_lidar_bank
from fog_gym.fog.lidar_grid import fog_lidar_grid
from fog_gym.fog.lidar_height import fog_lidar_height
from fog_gym.fog.lidar_pulse import (  # noqa: F401  (FIELD_STEP … KAPPA: the field path's constants, re-exported)
    FIELD_COARSE, FIELD_STEP, KAPPA, NEAR_FIELD_NODES, _clear_node, _field_rule, _soft_bound, beam_soft_maximum,
    field_pulse_weights, peak_extinction,
)  # fmt: skip
from fog_gym.fog.physics import FogLevel


@njit(cache=True, inline="always")
def _beam(pts, n, pose, terms, out):
    # Point n's beam in the field frame: its range, unit direction's run along u and up, τ to the point in closed form,
    # its 0–255 intensity and hard return; a beam without fog keeps the point as in clear air (written to out).
    x, y, z = np.float64(pts[n, 0]), np.float64(pts[n, 1]), np.float64(pts[n, 2])
    r0 = np.sqrt(x * x + y * y + z * z)
    inv = 1.0 / max(r0, 1e-12)
    du = (pose[2] * x + pose[3] * y + pose[4] * z) * inv
    dz = (pose[5] * x + pose[6] * y + pose[7] * z) * inv
    tau0 = segment_depth(terms, pose[0], pose[1], du, dz, r0)
    i_orig = np.round(np.float64(pts[n, 3]) * 255.0)
    if tau0 == 0.0:
        for c in range(pts.shape[1]):
            out[n, c] = pts[n, c]
    return r0, du, dz, tau0, i_orig, np.round(i_orig * np.exp(-2.0 * tau0))


@njit(cache=True, nogil=True)
def field_keeps(r0, intensity, terms, u0, z0, du, dz, weights, ramp, weights5, ramp5, beta_max):
    """Whether a return at range ``r0`` with CARLA intensity ``intensity`` ∈ [0, 1] on the beam ``(u0, z0, du, dz)``
    survives the fog field ``terms`` (``i_soft <= i_hard``): the decision :func:`fog_lidar_field` makes per point (CARLA
    intensities), for the perception kernels; the field's counterpart of ``fog_gym.fog.lidar.hahner_keeps``."""
    tau0 = segment_depth(terms, u0, z0, du, dz, r0)
    if tau0 == 0.0:
        return True
    i_orig = np.round(intensity * 255.0)
    i_hard = np.round(i_orig * np.exp(-2.0 * tau0))
    best, _ = beam_soft_maximum(terms, u0, z0, du, dz, r0, weights, ramp, weights5, ramp5, FIELD_COARSE, FIELD_STEP,
                                beta_max)  # fmt: skip
    return not min(255.0, best * i_orig * r0 * r0 * math.pi / GAMMA) > i_hard


@njit(cache=True, nogil=True, parallel=True)
def _hahner_field(pts, pose, terms, weights, ramp, weights5, ramp5, coarse, step, log_noise, u, out, attenuation,
                  beta_max):
    # pts (N, C) in the sensor frame; pose (8,): the sensor origin (u0, z0) in the field frame and the rows a_u, a_z
    # that turn a unit direction of the sensor frame into its run along u and up; terms a packed field
    # (fog_gym.fog.fields). Per point: τ(R0) in closed form, the soft return's maximum on its beam
    # (beam_soft_maximum); then Hahner et al.'s rule as _hahner.
    u0, z0 = pose[0], pose[1]
    for n in prange(pts.shape[0]):
        r0, du, dz, tau0, i_orig, i_hard = _beam(pts, n, pose, terms, out)
        if tau0 == 0.0:  # no fog on the ray: no backscatter either, the point is kept as in clear air
            continue
        best, best_k = beam_soft_maximum(terms, u0, z0, du, dz, r0, weights, ramp, weights5, ramp5, coarse, step,
                                         beta_max)  # fmt: skip
        scale, value = _field_rule(np.float64(pts[n, 3]), r0, i_orig, i_hard, best, best_k * step, log_noise, u[n],
                                   attenuation)  # fmt: skip
        for c in range(pts.shape[1]):  # (written here: numba counted references to arrays a helper writes to)
            out[n, c] = np.float32(np.float64(pts[n, c]) * scale) if c < 3 else (value if c == 3 else pts[n, c])


def fog_lidar_field(points: np.ndarray, field, rng: np.random.Generator, pose: np.ndarray, time: float = 0.0,
                    noise: float = 10.0, reflectance: float | None = None) -> np.ndarray:  # fmt: skip
    """Hahner et al. fog with a fog field (:mod:`fog_gym.fog.fields`) on LiDAR points ``(N, 4+)`` → the same shape.

    The generalisation of :func:`fog_lidar` to a local extinction β(r) along each beam (``docs/fog.md``): the hard
    target keeps ``round(i·e^{−2τ(R0)})``, τ the optical depth to the point in closed form; the fog's soft return is
    ``i_soft = min(255, max_{R ≤ R0} F(R)·i·R0²·π/Γ)`` with ``F(R) = ∫ P(t)·κβ(R′)·e^{−2τ(R′)}·ξ(R′)/R′² dt``
    (:func:`field_pulse_weights`; with constant β this is Hahner et al.'s ``I(R0, α)·β``), on a range grid of
    :data:`FIELD_STEP`. The same replace rule and noise. ``pose`` places the LiDAR in the field frame
    (:func:`fog_gym.fog.depth.field_pose`); ``time`` [s] moves drifting banks. A homogeneous field goes through
    :func:`fog_lidar`.
    """
    if field.is_homogeneous:
        from fog_gym.fog.physics import parse_fog

        return fog_lidar(points, parse_fog(field.visibility_m) if not isinstance(field, FogLevel) else field, rng,
                         noise, reflectance)  # fmt: skip
    pts = _checked_points(points, noise)
    pose = np.asarray(pose, np.float64)
    if pose.shape != (8,) or not np.isfinite(pose).all():
        raise ValueError(f"pose must be field_pose(sensor_to_world, frame): 8 finite numbers, got {pose!r}")
    u = rng.uniform(-1.0, 1.0, len(pts))
    out = np.empty_like(pts)
    terms = field.pack(time)
    log_noise, attenuation = math.log(max(1.0, noise / 5.0)) if noise > 0 else 0.0, -1.0 if reflectance is None else float(reflectance)
    if not len(pts):
        return out
    if BANK not in terms[:, 0]:  # β depends on height only: one soft-return curve per beam elevation
        fog_lidar_height(pts, terms, pose, log_noise, u, out, attenuation)
        return out
    if fog_lidar_bank(pts, terms, pose, log_noise, u, out, attenuation):  # one bank: curves per run, face-aligned
        return out
    fog_lidar_grid(pts, terms, pose, log_noise, u, out, attenuation)  # sums: curves on a grid of directions
    return out

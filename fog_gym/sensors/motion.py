"""A LiDAR sweep that takes time, and undoing the ego's part of it (``deskew``). Pure numpy.

A spinning LiDAR fires its azimuth columns one after another over the sweep (50 ms at FogDrive's 20 Hz; 49 µs
between columns of a 1 016-column sweep): at speed, the cloud is smeared — a wall passed at 30 m/s bends by 1.5 m
over one sweep. fog-gym's default sweep is instantaneous (FogDrive's synchronous CARLA); ``motion="continuous"``
on the LiDAR's config (``lidar_motion=`` on the env) makes it take time:

* the tick's columns are split into :data:`MOTION_SLICES` consecutive slices (:func:`sweep_slices`; 22.5° and
  3.1 ms each at FogDrive's rate); slice ``k`` fires at ``t_k = −T + (k + ½)·T/S`` seconds from the keyframe,
  ``T = 1/simulation_frequency`` the tick (the sweep ends at the keyframe, as nuScenes stamps its sweeps);
* each slice is cast from the ego's pose at ``t_k`` against every vehicle at its pose at ``t_k``
  (:class:`fog_gym.world.motion.SceneMotion`: interpolated between the keyframes that bracket the sweep);
* each point is in the sensor's frame at its firing time, with a ``time`` column ``t_k`` (seconds, ≤ 0);
* the boxes stay at the keyframe's time (as nuScenes' annotations do).

Within a slice the rays share one instant: against a truly continuous sweep a point is off by at most half a
slice of relative motion (±1.6 ms: ±4.7 cm at 30 m/s; 32 slices would halve it; 16 cost 1.2–1.5× an
instantaneous sweep, ``fog-gym bench``). :func:`deskew` moves each point into the sensor frame at
a reference time (the keyframe) from the ego's poses, which undoes the ego's part of the smear exactly; what other
vehicles did meanwhile stays (as in real data).

Example:
    >>> slices, times = sweep_slices(np.arange(8), 8, 20.0, n_slices=4)
    >>> [s.tolist() for s in slices], times.round(6).tolist()
    ([[0, 1], [2, 3], [4, 5], [6, 7]], [-0.04375, -0.03125, -0.01875, -0.00625])
    >>> pts = np.array([[10.0, 0.0, 0.0, 0.5, -0.05]], np.float32)  # fired 50 ms before the keyframe
    >>> poses = np.array([[-0.05, 0.0, 0.0, 0.0], [0.0, 1.5, 0.0, 0.0]])  # the ego drove 1.5 m along x meanwhile
    >>> deskew(pts, poses)[0, :3].tolist()  # the point as the sensor sees it at the keyframe: 1.5 m nearer
    [8.5, 0.0, 0.0]
"""

from __future__ import annotations

import numpy as np

#: Slices a sweep is cast in (module docstring).
MOTION_SLICES = 16


def slice_count(n_columns: int, n_slices: int = MOTION_SLICES) -> int:
    """The slices a sweep of ``n_columns`` azimuth columns is cast in: ``n_slices``, but at least 1 and at most one a
    column."""
    return max(1, min(int(n_slices), int(n_columns)))


def column_slices(columns: np.ndarray, n_columns: int, n_slices: int) -> np.ndarray:
    """Each azimuth column's slice (of ``n_slices``, already :func:`slice_count`'s): ``column·S // n_columns``."""
    return np.asarray(columns, np.int64) * int(n_slices) // int(n_columns)


def slice_times(simulation_frequency: float, n_slices: int = MOTION_SLICES) -> np.ndarray:
    """Each slice's firing time [s] from the tick's end: ``−T + (k + ½)·T/S``."""
    tick = 1.0 / float(simulation_frequency)
    return -tick + (np.arange(n_slices) + 0.5) * tick / n_slices


def sweep_order(columns: np.ndarray, n_columns: int, n_slices: int = MOTION_SLICES) -> tuple[np.ndarray, np.ndarray]:
    """The rays sorted by slice (stably: laser order within a slice) and each slice's bounds in that order: slice
    ``k`` is ``order[bounds[k]:bounds[k + 1]]``. One radix pass (the slice numbers fit a byte or two)."""
    n_slices = slice_count(n_columns, n_slices)
    k = column_slices(columns, n_columns, n_slices)
    order = np.argsort(k.astype(np.uint8 if n_slices <= 256 else np.uint16), kind="stable")
    bounds = np.zeros(n_slices + 1, np.int64)
    np.cumsum(np.bincount(k, minlength=n_slices)[:n_slices], out=bounds[1:])
    return order, bounds


def sweep_slices(columns: np.ndarray, n_columns: int, simulation_frequency: float,
                 n_slices: int = MOTION_SLICES) -> tuple[list[np.ndarray], np.ndarray]:  # fmt: skip
    """The rays of each slice (indices into ``columns``, each ray's azimuth column of ``n_columns``) and each slice's
    time [s] from the tick's end."""
    n_slices = slice_count(n_columns, n_slices)
    order, bounds = sweep_order(columns, n_columns, n_slices)
    return [order[bounds[i]: bounds[i + 1]] for i in range(n_slices)], slice_times(simulation_frequency, n_slices)


def pose_matrices(xy_yaw: np.ndarray) -> np.ndarray:
    """``(N, 4, 4)`` frames at ``(x, y, 0)`` turned by ``yaw`` about +z, from ``(N, 3)`` rows of ``(x, y, yaw)``
    (:func:`fog_gym.geometry.yaw_transform` of each row).

    >>> pose_matrices(np.array([[2.0, 1.0, np.pi / 2]]))[0] @ [1.0, 0.0, 0.0, 1.0]
    array([2., 2., 0., 1.])
    """
    c, s = np.cos(xy_yaw[:, 2]), np.sin(xy_yaw[:, 2])
    m = np.zeros((len(xy_yaw), 4, 4))
    m[:, 0, 0], m[:, 0, 1], m[:, 1, 0], m[:, 1, 1] = c, -s, s, c
    m[:, 2, 2] = m[:, 3, 3] = 1.0
    m[:, 0, 3], m[:, 1, 3] = xy_yaw[:, 0], xy_yaw[:, 1]
    return m


def ego_poses_at(ego_poses: np.ndarray, times: np.ndarray) -> np.ndarray:
    """``(N, 3)`` ego ``(x, y, yaw)`` at ``times``, interpolated linearly in ``ego_poses`` ``(K, 4)`` rows of
    ``(t, x, y, yaw)`` sorted by time (heading along the shorter arc; held constant outside the span)."""
    p = np.asarray(ego_poses, np.float64)
    if p.ndim != 2 or p.shape[1] != 4 or len(p) == 0 or not np.all(np.isfinite(p)) or np.any(np.diff(p[:, 0]) < 0):
        raise ValueError(f"ego_poses must be finite (K >= 1, 4) rows of (t, x, y, yaw) sorted by time, got shape {p.shape}")
    t = np.asarray(times, np.float64)
    yaw = np.concatenate([[p[0, 3]], p[0, 3] + np.cumsum((np.diff(p[:, 3]) + np.pi) % (2 * np.pi) - np.pi)])
    return np.stack([np.interp(t, p[:, 0], p[:, 1]), np.interp(t, p[:, 0], p[:, 2]), np.interp(t, p[:, 0], yaw)], axis=1)


def deskew(points: np.ndarray, ego_poses: np.ndarray, lidar_to_ego: np.ndarray | None = None, time_column: int = 4,
           reference_time: float = 0.0) -> np.ndarray:  # fmt: skip
    """Points of a sweep that took time (``points[:, time_column]`` each point's time, the LiDAR's frame at that
    time) in the LiDAR's frame at ``reference_time`` (the keyframe, 0): ``p_ref = T_ref⁻¹ · T(t) · p``, ``T(t)`` the
    LiDAR → world transform at ``t`` from the ego's poses ``ego_poses`` ``(K, 4)`` rows of ``(t, x, y, yaw)`` (world
    frame, interpolated; the env gives them in ``info["lidar_ego_poses"]``) and the mount ``lidar_to_ego`` (4×4;
    default the identity: points in the ego frame). Other columns are kept; a new array."""
    pts = np.asarray(points, np.float32)
    if pts.ndim != 2 or pts.shape[1] <= max(3, int(time_column)):
        raise ValueError(f"points must be (N, C) with xyz and a time column {time_column}, got shape {pts.shape}")
    mount = np.eye(4) if lidar_to_ego is None else np.asarray(lidar_to_ego, np.float64)
    if mount.shape != (4, 4) or not np.all(np.isfinite(mount)):
        raise ValueError(f"lidar_to_ego must be a finite 4x4 matrix, got shape {mount.shape}")
    t = pts[:, time_column].astype(np.float64)
    at = pose_matrices(ego_poses_at(ego_poses, t)) @ mount  # LiDAR → world at each point's time
    ref = pose_matrices(ego_poses_at(ego_poses, np.array([float(reference_time)])))[0] @ mount
    m = np.linalg.inv(ref) @ at  # (N, 4, 4): LiDAR at t → LiDAR at the reference time
    xyz = pts[:, :3].astype(np.float64)
    moved = np.einsum("nij,nj->ni", m[:, :3, :3], xyz) + m[:, :3, 3]
    out = pts.copy()
    out[:, :3] = moved.astype(np.float32)
    return out

"""The world between keyframes: every vehicle's pose at a time near the scene's instant (numpy and two small
numba kernels).

A sensor that takes time to measure (a spinning LiDAR's sweep, :mod:`fog_gym.sensors.motion`) sees each vehicle
where it is when the beam fires. :class:`SceneMotion` gives the poses at ``t`` seconds from the scene's instant
(``t <= 0`` within the last keyframe interval): interpolated linearly (position, and heading along the shorter
arc) between the previous keyframe's state (:attr:`fog_gym.world.scene.Scene.previous`) and the scene's, for
vehicles in both; extrapolated at constant velocity and heading from the scene's state otherwise (a vehicle that
appeared, the episode's first frame). Over FogDrive's keyframe interval (0.1 s, two simulation steps) a
highway-env vehicle's path is a straight line to within millimetres, so this is the simulation's own motion.

Example:
    >>> from fog_gym.world.fleet import VehicleState
    >>> def state(x, yaw):
    ...     return VehicleState(np.array([1]), np.zeros(1, np.int8), np.array([[x, 0.0, 0.75]]), np.array([[4.5, 1.8, 1.5]]),
    ...                         np.array([yaw]), np.array([[30.0, 0, 0]]), np.full((1, 3), 0.5))
    >>> m = SceneMotion(state(13.0, 0.1), previous=(-0.1, state(10.0, 0.0)))
    >>> tuple(round(v, 6) for v in m.ego_pose_at(-0.05, ego_id=1))
    (11.5, 0.0, 0.05)
    >>> tuple(round(v, 6) for v in SceneMotion(state(13.0, 0.0)).ego_pose_at(-0.05, ego_id=1))  # constant velocity
    (11.5, 0.0, 0.0)
"""

from __future__ import annotations

from dataclasses import replace
from typing import NamedTuple

import numpy as np
from numba import njit

import fog_gym._numba  # noqa: F401  (numba's fork-safe threading layer, before any kernel runs)
from fog_gym.world.fleet import VehicleState
from fog_gym.world.primitives import Primitives


class SceneMotion:
    """Poses of the vehicles of ``current`` (the scene's state, time 0) at times near it; ``previous`` is the
    ``(time, state)`` of the keyframe before (time < 0), or None."""

    def __init__(self, current: VehicleState, previous: tuple[float, VehicleState] | None = None) -> None:
        self.current = current
        self._ids = np.ascontiguousarray(current.ids, np.int64)
        self._dxy = np.asarray(current.velocities, np.float64)[:, :2].copy()  # metres per second from time 0
        self._dyaw = np.zeros(len(current))  # radians per second
        if previous is not None:
            t_prev, prev = previous
            if not t_prev < 0:
                raise ValueError(f"the previous keyframe must lie before the scene (time < 0), got {t_prev!r}")
            _rates(self._ids, _f64(current.centers), _f64(current.yaws), np.ascontiguousarray(prev.ids, np.int64),
                   _f64(prev.centers), _f64(prev.yaws), float(t_prev), self._dxy, self._dyaw)  # fmt: skip

    def offsets(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Each vehicle's displacement (N, 2) and heading change (N,) from the scene's instant to time ``t``."""
        return self._dxy * t, self._dyaw * t

    def ego_pose_at(self, t: float, ego_id: int) -> tuple[float, float, float]:
        """``(x, y, yaw)`` of vehicle ``ego_id`` (the ground point under its centre) at time ``t``."""
        return tuple(float(v) for v in self.ego_poses_during([t], ego_id)[0])

    def ego_poses_during(self, times, ego_id: int) -> np.ndarray:
        """:meth:`ego_pose_at` at each of ``times``: ``(S, 3)`` rows of ``(x, y, yaw)``."""
        rows = np.flatnonzero(self._ids == int(ego_id))
        if len(rows) == 0:
            raise KeyError(f"no vehicle {ego_id!r} in the scene")
        k = rows[0]
        t = np.asarray(times, np.float64).reshape(-1)
        out = np.empty((len(t), 3))
        out[:, 0] = self.current.centers[k, 0] + self._dxy[k, 0] * t
        out[:, 1] = self.current.centers[k, 1] + self._dxy[k, 1] * t
        out[:, 2] = self.current.yaws[k] + self._dyaw[k] * t
        return out

    def primitives_at(self, prims: Primitives, t: float) -> Primitives:
        """``prims`` with every vehicle's boxes (``insts`` > 0, its id) moved rigidly to time ``t``: rotated about the
        vehicle's centre by its heading change and shifted by its displacement; the static world stays."""
        return prims if t == 0.0 else self.primitives_during(prims, [t])[0]

    def primitives_during(self, prims: Primitives, times) -> list[Primitives]:
        """:meth:`primitives_at` at each of ``times``, in one pass over the moving boxes."""
        worlds = self.slice_worlds(prims, times)
        return [prims if t == 0.0 else replace(prims, centers=worlds.centers[k], yaws=worlds.yaws[k])
                for k, t in enumerate(np.asarray(times, np.float64).reshape(-1))]  # fmt: skip

    def slice_worlds(self, prims: Primitives, times) -> SliceWorlds:
        """:meth:`primitives_at` at each of ``times`` as arrays: every box's centre and heading at each time."""
        t = np.ascontiguousarray(times, np.float64).reshape(-1)
        centers, yaws = np.empty((len(t), len(prims), 3)), np.empty((len(t), len(prims)))
        _move(prims.centers, prims.yaws, prims.insts, self._ids, _f64(self.current.centers), self._dxy, self._dyaw, t,
              centers, yaws)  # fmt: skip
        return SliceWorlds(prims, centers, yaws)


class SliceWorlds(NamedTuple):
    """The world at several times (a sweep's slices), as arrays: ``prims`` (the boxes, meshes, tags …, at the scene's
    instant) and each box's ``centers`` ``(S, P, 3)`` and ``yaws`` ``(S, P)`` at each time; only vehicles move."""

    prims: Primitives
    centers: np.ndarray
    yaws: np.ndarray


def _f64(a) -> np.ndarray:
    return np.ascontiguousarray(a, np.float64)


@njit(cache=True, nogil=True)
def _rates(ids, centers, yaws, prev_ids, prev_centers, prev_yaws, t_prev, dxy, dyaw):
    """Each vehicle in both keyframes (``ids`` now, ``prev_ids`` at ``t_prev`` < 0): its displacement and heading
    change (along the shorter arc) per second into ``dxy`` and ``dyaw``; the others keep theirs."""
    for k in range(ids.shape[0]):
        for j in range(prev_ids.shape[0]):
            if prev_ids[j] == ids[k]:
                dxy[k, 0] = (centers[k, 0] - prev_centers[j, 0]) / -t_prev
                dxy[k, 1] = (centers[k, 1] - prev_centers[j, 1]) / -t_prev
                dyaw[k] = ((yaws[k] - prev_yaws[j] + np.pi) % (2 * np.pi) - np.pi) / -t_prev
                break


@njit(cache=True, nogil=True)
def _move(centers, yaws, insts, ids, vehicle_centers, dxy, dyaw, times, out_centers, out_yaws):
    """Every box at each of ``times``: a vehicle's (``insts`` its id, one of ``ids``) turned by its heading change
    about its centre and shifted by its displacement, every other box (and every box at time 0) as it is."""
    n_ids = 0
    for k in range(ids.shape[0]):
        n_ids = max(n_ids, ids[k] + 1)
    row = np.full(n_ids, -1, np.int64)
    for k in range(ids.shape[0]):
        if ids[k] >= 0 and (dxy[k, 0] != 0.0 or dxy[k, 1] != 0.0 or dyaw[k] != 0.0):
            row[ids[k]] = k  # the moving vehicles
    for s in range(times.shape[0]):
        t = times[s]
        for p in range(centers.shape[0]):
            out_centers[s, p, 0] = centers[p, 0]
            out_centers[s, p, 1] = centers[p, 1]
            out_centers[s, p, 2] = centers[p, 2]
            out_yaws[s, p] = yaws[p]
            i = np.int64(insts[p])
            if t == 0.0 or i <= 0 or i >= n_ids or row[i] < 0:
                continue
            r = row[i]
            a = dyaw[r] * t
            c, sn = np.cos(a), np.sin(a)
            px, py = vehicle_centers[r, 0], vehicle_centers[r, 1]
            rx, ry = centers[p, 0] - px, centers[p, 1] - py
            out_centers[s, p, 0] = px + c * rx - sn * ry + dxy[r, 0] * t
            out_centers[s, p, 1] = py + sn * rx + c * ry + dxy[r, 1] * t
            out_yaws[s, p] = yaws[p] + a

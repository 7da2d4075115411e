"""The world between keyframes: every vehicle's pose at a time near the scene's instant (pure numpy).

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

from fog_gym.world.fleet import VehicleState
from fog_gym.world.primitives import Primitives


class SceneMotion:
    """Poses of the vehicles of ``current`` (the scene's state, time 0) at times near it; ``previous`` is the
    ``(time, state)`` of the keyframe before (time < 0), or None."""

    def __init__(self, current: VehicleState, previous: tuple[float, VehicleState] | None = None) -> None:
        self.current = current
        ids = np.asarray(current.ids, np.int64)
        self._row = {int(i): k for k, i in enumerate(ids)}
        self._dxy = np.asarray(current.velocities, np.float64)[:, :2].copy()  # metres per second from time 0
        self._dyaw = np.zeros(len(current))  # radians per second
        self._prims: tuple | None = None  # (primitives, moving boxes, their vehicles' rows, pivots, offsets)
        if previous is not None:
            t_prev, prev = previous
            if not t_prev < 0:
                raise ValueError(f"the previous keyframe must lie before the scene (time < 0), got {t_prev!r}")
            before = np.asarray(prev.ids, np.int64)
            k, j = _matching_rows(ids, before)  # the vehicles in both keyframes: rows k now, j then
            self._dxy[k] = (current.centers[k, :2] - prev.centers[j, :2]) / -t_prev
            dyaw = (current.yaws[k] - prev.yaws[j] + np.pi) % (2 * np.pi) - np.pi
            self._dyaw[k] = dyaw / -t_prev

    def offsets(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Each vehicle's displacement (N, 2) and heading change (N,) from the scene's instant to time ``t``."""
        return self._dxy * t, self._dyaw * t

    def ego_pose_at(self, t: float, ego_id: int) -> tuple[float, float, float]:
        """``(x, y, yaw)`` of vehicle ``ego_id`` (the ground point under its centre) at time ``t``."""
        return tuple(float(v) for v in self.ego_poses_during([t], ego_id)[0])

    def ego_poses_during(self, times, ego_id: int) -> np.ndarray:
        """:meth:`ego_pose_at` at each of ``times``: ``(S, 3)`` rows of ``(x, y, yaw)``."""
        k = self._row[int(ego_id)]
        t = np.asarray(times, np.float64).reshape(-1)
        out = np.empty((len(t), 3))
        out[:, 0] = self.current.centers[k, 0] + self._dxy[k, 0] * t
        out[:, 1] = self.current.centers[k, 1] + self._dxy[k, 1] * t
        out[:, 2] = self.current.yaws[k] + self._dyaw[k] * t
        return out

    def _moving(self, prims: Primitives) -> tuple:
        """Which boxes of ``prims`` move, with whom: (moving boxes, their vehicles' rows, pivots, offsets), once per
        set of primitives."""
        cached = self._prims
        if cached is None or cached[0] is not prims:
            moving = np.flatnonzero(prims.insts > 0)
            k, rows = _matching_rows(prims.insts[moving].astype(np.int64), np.asarray(self.current.ids, np.int64))
            moving = moving[k]
            still = (self._dxy[rows] == 0).all(axis=1) & (self._dyaw[rows] == 0)
            moving, rows = moving[~still], rows[~still]
            pivot = self.current.centers[rows, :2]
            cached = self._prims = (prims, moving, rows, pivot, prims.centers[moving, :2] - pivot)
        return cached[1:]

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
        t = np.asarray(times, np.float64).reshape(-1)
        moving, rows, pivot, rel = self._moving(prims)
        centers = np.repeat(prims.centers[None], len(t), axis=0)
        yaws = np.repeat(prims.yaws[None], len(t), axis=0)
        if moving.size:
            d, dyaw = self._dxy[rows][None] * t[:, None, None], self._dyaw[rows][None] * t[:, None]
            c, s = np.cos(dyaw), np.sin(dyaw)
            centers[:, moving, 0] = pivot[:, 0] + c * rel[:, 0] - s * rel[:, 1] + d[..., 0]  # (S, M)
            centers[:, moving, 1] = pivot[:, 1] + s * rel[:, 0] + c * rel[:, 1] + d[..., 1]
            yaws[:, moving] = prims.yaws[moving] + dyaw
            still = t == 0.0  # the scene's instant: its own boxes, bit for bit
            centers[still], yaws[still] = prims.centers, prims.yaws
        return SliceWorlds(prims, centers, yaws)


class SliceWorlds(NamedTuple):
    """The world at several times (a sweep's slices), as arrays: ``prims`` (the boxes, meshes, tags …, at the scene's
    instant) and each box's ``centers`` ``(S, P, 3)`` and ``yaws`` ``(S, P)`` at each time; only vehicles move."""

    prims: Primitives
    centers: np.ndarray
    yaws: np.ndarray


def _matching_rows(ids: np.ndarray, other: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows ``k`` of ``ids`` and ``j`` of ``other`` with ``ids[k] == other[j]`` (``other``'s unique), ``k`` ascending.

    >>> [a.tolist() for a in _matching_rows(np.array([4, 9, 2]), np.array([2, 5, 4]))]
    [[0, 2], [2, 0]]
    """
    if len(other) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    by_id = np.argsort(other, kind="stable")
    pos = np.minimum(np.searchsorted(other[by_id], ids), len(other) - 1)
    found = other[by_id[pos]] == ids
    return np.flatnonzero(found), by_id[pos[found]]

"""The ego pose of each sample: an extra file beside the FogDrive channels (``ego_pose/000000.json``).

FogDrive's layout has no ego poses: its boxes and point clouds live in the LiDAR frame of each sample. Exports to
formats with a global frame (nuScenes) need the true pose, so ``RecordFogDrive`` and ``fog-gym generate`` write one
small JSON file per sample, written before the sample's ``BBOX_3D`` file (a complete sample has its pose). It is
not a channel: the index does not list it, so a reader that only knows FogDrive never sees it.

The record, in CARLA's world frame (left-handed: +x forward, +y right, +z up, yaw positive to the right)::

    {"translation": [x, y, z],          # the ego origin: the ground point under its centre [m]
     "yaw": yaw,                        # the ego's heading [rad]
     "velocity": [vx, vy, vz],          # the ego's velocity [m/s]
     "lidar_to_ego": [[...], ...]}      # 4×4: LiDAR-frame points → ego-frame points (the LiDAR's mount)

Example:
    >>> pose = decode_ego_pose(encode_ego_pose((10.0, 2.0, 0.0), 0.1, (20.0, 0.0, 0.0), np.eye(4)))
    >>> pose.translation.tolist(), pose.yaw, ego_pose_problem(b'{"yaw": 1}')
    ([10.0, 2.0, 0.0], 0.1, "missing keys ['translation', 'velocity', 'lidar_to_ego']")
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np

from fog_gym.checks import json_numbers, json_record

KEYS = ("translation", "yaw", "velocity", "lidar_to_ego")


class EgoPose(NamedTuple):
    """One sample's ego pose (module docstring): world frame, CARLA's axes."""

    translation: np.ndarray  # (3,)
    yaw: float
    velocity: np.ndarray  # (3,)
    lidar_to_ego: np.ndarray  # (4, 4)

    def ego_to_world(self) -> np.ndarray:
        """4×4: ego-frame points → world points."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        m = np.eye(4)
        m[:2, :2] = [[c, -s], [s, c]]
        m[:3, 3] = self.translation
        return m

    def lidar_to_world(self) -> np.ndarray:
        """4×4: LiDAR-frame points (boxes, point clouds) → world points."""
        return self.ego_to_world() @ self.lidar_to_ego


def encode_ego_pose(translation: Sequence[float], yaw: float, velocity: Sequence[float],
                    lidar_to_ego: np.ndarray) -> bytes:  # fmt: skip
    """The file's bytes; ``ValueError`` naming the argument for a non-finite or wrongly shaped value."""
    record = {
        "translation": _finite(translation, (3,), "translation"),
        "yaw": _finite(yaw, (), "yaw"),
        "velocity": _finite(velocity, (3,), "velocity"),
        "lidar_to_ego": _finite(lidar_to_ego, (4, 4), "lidar_to_ego"),
    }
    return json.dumps(record).encode()


def _finite(value: Any, shape: tuple[int, ...], name: str) -> Any:
    a = np.asarray(value, np.float64)
    if a.shape != shape or not np.isfinite(a).all():
        raise ValueError(f"{name} must be finite with shape {shape}, got {value!r}")
    return a.tolist()


def ego_pose_problem(data: bytes) -> str | None:
    """The problem with an ego-pose file's bytes (one phrase), or None. Never raises."""
    record, problem = json_record(data, KEYS)
    if record is None:
        return problem
    for key, shape in (("translation", (3,)), ("yaw", ()), ("velocity", (3,)), ("lidar_to_ego", (4, 4))):
        try:
            a = json_numbers(key, record[key])
        except ValueError:
            return f"{key} must be numbers with shape {shape}"
        if a.shape != shape or not np.isfinite(a).all():
            return f"{key} must be finite numbers with shape {shape}"
    if not np.allclose(np.asarray(record["lidar_to_ego"], np.float64)[3], [0, 0, 0, 1]):
        return "lidar_to_ego must be a rigid transform (last row 0, 0, 0, 1)"
    return None


def decode_ego_pose(data: bytes) -> EgoPose:
    """An ego-pose file's bytes → :class:`EgoPose`; ``ValueError`` with the problem if they are not one."""
    problem = ego_pose_problem(data)
    if problem is not None:
        raise ValueError(problem)
    r = json.loads(data)
    return EgoPose(np.asarray(r["translation"], np.float64), float(r["yaw"]), np.asarray(r["velocity"], np.float64),
                   np.asarray(r["lidar_to_ego"], np.float64))  # fmt: skip

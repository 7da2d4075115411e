"""``RADAR_FRONT``: a CARLA ``sensor.other.radar`` (velocity, azimuth, altitude, depth) — config, physics, sensor.

Random rays into an elliptic cone, detections on actors only, radial velocity (negative = approaching); research
note fog_physics.md §4.3. Radar is never fogged.

Example:
    >>> s = RadarSensor(RadarConfig.fogdrive())
    >>> s.channels, s.layout()["RADAR_FRONT"].folder, s.space().shape[1]
    (('RADAR_FRONT',), 'radar', 4)
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from fog_gym.checks import finite, positive
from fog_gym.geometry import Pose, sensor_to_world
from fog_gym.sensors.base import PointSensor, point_space, register
from fog_gym.sensors.lidar import simulation_frequency_hz, split_transform
from fog_gym.channels.packing import RADAR
from fog_gym.sensors.raycast import cast_rays
from fog_gym.world.primitives import Primitives


@dataclass(frozen=True)
class RadarConfig:
    """A CARLA ``sensor.other.radar`` (defaults are CARLA's). Angles in degrees, range in metres.

    >>> RadarConfig.fogdrive().rays_per_tick(20)
    900
    >>> RadarConfig(vertical_fov=180)
    Traceback (most recent call last):
    ...
    ValueError: vertical_fov must lie in (0, 180) degrees, got 180
    """

    pose: Pose = field(default_factory=Pose)
    range: float = 100.0
    points_per_second: float = 1500.0
    horizontal_fov: float = 30.0
    vertical_fov: float = 30.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "pose", Pose.coerce(self.pose))
        for name in ("range", "points_per_second"):
            object.__setattr__(self, name, positive(name, getattr(self, name)))
        for name in ("horizontal_fov", "vertical_fov"):
            v = finite(name, getattr(self, name))
            if not 0.0 < v < 180.0:
                raise ValueError(f"{name} must lie in (0, 180) degrees, got {getattr(self, name)!r}")
            object.__setattr__(self, name, v)

    @classmethod
    def fogdrive(cls, **overrides: Any) -> RadarConfig:
        """FogDrive's radar: front bumper (2, 0, 1.2), 150 m, 18 k points/s, FOV 120° × 30°.

        >>> RadarConfig.fogdrive().pose.location
        (2.0, 0.0, 1.2)
        """
        values = dict(pose=Pose(2.0, 0.0, 1.2), range=150.0, points_per_second=18000.0, horizontal_fov=120.0,
                      vertical_fov=30.0)  # fmt: skip
        values.update(overrides)
        return cls(**values)

    def rays_per_tick(self, simulation_frequency: float = 20.0) -> int:
        """``int(points_per_second / simulation_frequency)`` rays per tick, as CARLA (truncated)."""
        return int(math.floor(self.points_per_second / simulation_frequency_hz(simulation_frequency) + 1e-9))


def _velocity_table(velocities: Any, max_id: int) -> np.ndarray:
    """(max_id + 1, 3) world velocity per instance id from a mapping, an (ids, velocities) pair or a VehicleState."""
    table = np.zeros((max_id + 1, 3))
    if velocities is None:
        return table
    if isinstance(velocities, Mapping):
        ids = np.array(list(velocities.keys()), np.int64)
        vels = np.array([np.asarray(v, np.float64).reshape(3) for v in velocities.values()]).reshape(-1, 3)
    elif hasattr(velocities, "ids") and hasattr(velocities, "velocities"):
        ids, vels = np.asarray(velocities.ids, np.int64), np.asarray(velocities.velocities, np.float64)
    else:
        try:
            ids, vels = velocities
        except (TypeError, ValueError):
            raise ValueError(
                "velocities_by_id must be a mapping id -> (3,), an (ids, velocities) pair or a VehicleState"
            ) from None
        ids, vels = np.asarray(ids, np.int64).reshape(-1), np.asarray(vels, np.float64).reshape(-1, 3)
    if ids.shape[0] != vels.shape[0]:
        raise ValueError(f"velocities_by_id: {ids.shape[0]} ids but {vels.shape[0]} velocity rows")
    inside = (ids >= 0) & (ids <= max_id)
    table[ids[inside]] = vels[inside]
    return table


def simulate_radar(
    cfg: RadarConfig,
    sensor_to_world: np.ndarray,
    prims: Primitives | Mapping[str, Any],
    rng: np.random.Generator,
    velocities_by_id: Any = None,
    sensor_velocity: np.ndarray | tuple[float, float, float] = (0.0, 0.0, 0.0),
    simulation_frequency: float = 20.0,
) -> np.ndarray:
    """One tick of a CARLA radar: ``(N, 4)`` float32 velocity [m/s], azimuth [rad], altitude [rad], depth [m].

    ``rays_per_tick`` rays go from the sensor to ``(range, tan(hfov/2)·range·r·cos θ, tan(vfov/2)·range·r·sin θ)``
    (sensor frame) with ``r, θ/2π ~ U(0, 1)`` as in CARLA, so the far end of the cone is the plane ``x = range``.
    Every box and the ground occlude, but only hits on actors (``insts > 0``) become detections, in ray order.
    ``velocity = (v_target − sensor_velocity) · unit(hit − sensor)``: negative when the target approaches.
    ``velocities_by_id`` gives each actor's world velocity: a mapping id → (3,), an ``(ids, velocities)`` pair or a
    :class:`~fog_gym.world.fleet.VehicleState`; ids it lacks count as standing still. Azimuth (positive to the right)
    and altitude come from the ray direction in the sensor frame; depth is the hit distance.

    >>> box = {"centers": np.array([[22.0, 0, 1]]), "halves": np.array([[2.0, 1, 1]]), "yaws": np.zeros(1),
    ...        "tags": np.array([14], np.uint8), "insts": np.array([5], np.uint16)}
    >>> cfg = RadarConfig.fogdrive()
    >>> det = simulate_radar(cfg, sensor_to_world(cfg.pose), box, np.random.default_rng(0), {5: (-3.0, 0, 0)})
    >>> bool(len(det) > 0 and np.all(det[:, 0] < 0) and np.all(det[:, 3] >= 18.0))
    True
    """
    rot, origin = split_transform(sensor_to_world)
    n = cfg.rays_per_tick(simulation_frequency)
    u = rng.random((n, 2))
    radius, angle = u[:, 0], 2.0 * np.pi * u[:, 1]
    max_rx = math.tan(math.radians(cfg.horizontal_fov / 2.0)) * cfg.range
    max_ry = math.tan(math.radians(cfg.vertical_fov / 2.0)) * cfg.range
    ends = np.c_[np.full(n, cfg.range), max_rx * radius * np.cos(angle), max_ry * radius * np.sin(angle)]
    length = np.linalg.norm(ends, axis=1)
    dirs = ends / length[:, None]
    world_dirs = dirs @ rot.T
    prims = Primitives.coerce(prims)
    hits = cast_rays(origin, world_dirs, float(length.max()) if n else cfg.range, prims)
    insts = prims.insts.astype(np.int64)
    idx = hits.index
    actor = np.zeros(n, bool)
    on_box = idx >= 0
    actor[on_box] = insts[idx[on_box]] > 0
    det = np.flatnonzero(actor & (hits.distance < length))
    ids = insts[idx[det]]
    table = _velocity_table(velocities_by_id, int(insts.max()) if insts.size else 0)
    v_rel = table[ids] - np.asarray(sensor_velocity, np.float64).reshape(3)
    out = np.empty((det.size, 4), np.float32)
    out[:, 0] = np.einsum("ij,ij->i", v_rel, world_dirs[det])
    d = dirs[det]
    out[:, 1] = np.arctan2(d[:, 1], d[:, 0])
    out[:, 2] = np.arctan2(d[:, 2], np.hypot(d[:, 0], d[:, 1]))
    out[:, 3] = hits.distance[det]
    return out


def radar_space(cfg, simulation_frequency: float) -> Any:
    """Box of the radar channel: velocity, azimuth, altitude, depth; one row per ray of a tick."""
    h, v = math.radians(cfg.horizontal_fov) / 2, math.radians(cfg.vertical_fov) / 2
    reach = cfg.range * math.sqrt(1 + math.tan(h) ** 2 + math.tan(v) ** 2) + 1.0
    return point_space(cfg.rays_per_tick(simulation_frequency), [-500.0, -math.pi, -math.pi / 2, 0.0],
                 [500.0, math.pi, math.pi / 2, reach])  # fmt: skip


@register(RadarConfig)
class RadarSensor(PointSensor):
    kind = "radar"
    default_channel, columns, default_folder = RADAR, 4, "radar"

    def space(self):
        return radar_space(self.config, self.simulation_frequency)

    def measure(self, scene, prims, rng: np.random.Generator, tick: int) -> dict[str, np.ndarray]:
        cfg = self.config
        ego_velocity = scene.vehicles.velocities[scene.vehicles.ids == scene.ego_id][0]
        pts = simulate_radar(cfg, sensor_to_world(cfg.pose, scene.ego_pose), prims, rng, scene.vehicles, ego_velocity,
                             self.simulation_frequency)  # fmt: skip
        return {self.channel: pts}

"""CARLA-style ray-cast LiDAR, semantic LiDAR and radar over the scene's boxes and ground plane.

Pure functions of the render primitives (upright boxes, see :mod:`fog_gym.scene`), the road-surface map, a
sensor→world transform and a seeded ``numpy.random.Generator``; nothing here imports the environment.
The models follow CARLA's ``sensor.lidar.ray_cast``, ``sensor.lidar.ray_cast_semantic`` and
``sensor.other.radar`` (RayCastLidar.cpp, Radar.cpp; research note fog_physics.md §4.2–4.3):

* ray pattern: ``channels`` lasers evenly spaced from ``upper_fov`` down to ``lower_fov``; each shoots
  ``round(points_per_second / (simulation_frequency · channels))`` rays per tick, evenly spaced over the
  ``rotation_frequency · horizontal_fov / simulation_frequency`` degrees the head turns in one tick
  (one full sweep when the rotation frequency equals the simulation frequency);
* LiDAR intensity ``exp(−a · d)``, general and intensity drop-off, Gaussian range noise;
* semantic LiDAR: cos(incidence), object id (vehicle id, 0 for the static world and the ground) and tag;
* radar: random rays into an elliptic cone, detections on actors only, radial velocity (negative = approaching).

All points are in the sensor frame: left-handed, +x forward, +y right, +z up (as CARLA's ``raw_data``).
Pass primitives without the ego's own boxes (``Scene.primitives`` leaves them out); a sensor inside a box sees
through it in any case, as a line trace that starts inside a mesh.

Example:
    >>> from fog_gym.scenery import SurfaceMap
    >>> surface = SurfaceMap(np.ones((300, 300), np.uint8), (-150.0, -150.0), 1.0)
    >>> cfg = LidarConfig.fogdrive()
    >>> pts = simulate_semantic_lidar(cfg, sensor_to_world(cfg.pose), Primitives.empty(), surface)
    >>> pts.shape[1], set(pts[:, 5].tolist())  # every return is road (tag 1) here
    (6, {1.0})
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numba import njit

from fog_gym.pose import Pose
from fog_gym.pose import finite as _number  # one finite-number check for every config
from fog_gym.geometry import transform_matrix, yaw_transform
from fog_gym.primitives import Primitives
from fog_gym.render.raycast import MISS, cast_rays
from fog_gym.scenery import SURFACE_TAGS, SurfaceMap

_EPS = float(np.finfo(np.float32).eps)  # CARLA switches drop-off / noise on above float epsilon


def _positive(name: str, value: Any) -> float:
    v = _number(name, value)
    if v <= 0.0:
        raise ValueError(f"{name} must be > 0, got {value!r}")
    return v


def _interval(name: str, value: Any, lo: float, hi: float, open_lo: bool = False) -> float:
    v = _number(name, value)
    if v > hi or v < lo or (open_lo and v == lo):
        bounds = f"({lo:g}, {hi:g}]" if open_lo else f"[{lo:g}, {hi:g}]"
        raise ValueError(f"{name} must lie in {bounds}, got {value!r}")
    return v


def _simulation_frequency(value: Any) -> float:
    return _positive("simulation_frequency", value)


@dataclass(frozen=True)
class LidarConfig:
    """A rotating ray-cast LiDAR (CARLA ``sensor.lidar.ray_cast`` attributes and defaults).

    Angles in degrees, range in metres, frequencies in Hz. :meth:`fogdrive` and :meth:`fogdrive_semantic` are
    the FogDrive sensors (Table 2); what FogDrive leaves at default keeps CARLA's default.
    The semantic LiDAR ignores the attenuation, drop-off and noise fields.

    >>> cfg = LidarConfig.fogdrive()
    >>> cfg.channels, cfg.range, cfg.points_per_channel(20)
    (64, 120.0, 1016)
    >>> LidarConfig(upper_fov=-40.0)
    Traceback (most recent call last):
    ...
    ValueError: upper_fov must be greater than lower_fov, got upper_fov=-40.0 and lower_fov=-30.0
    """

    pose: Pose = field(default_factory=Pose)
    channels: int = 32
    range: float = 10.0
    points_per_second: float = 56000.0
    rotation_frequency: float = 10.0
    upper_fov: float = 10.0
    lower_fov: float = -30.0
    horizontal_fov: float = 360.0
    atmosphere_attenuation_rate: float = 0.004
    dropoff_general_rate: float = 0.45
    dropoff_intensity_limit: float = 0.8
    dropoff_zero_intensity: float = 0.4
    noise_stddev: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "pose", Pose.coerce(self.pose))
        ch = self.channels
        if isinstance(ch, bool) or not isinstance(ch, (int, np.integer, float)) or (
            isinstance(ch, float) and not ch.is_integer()
        ) or ch < 1:
            raise ValueError(f"channels must be an integer >= 1, got {ch!r}")
        object.__setattr__(self, "channels", int(ch))
        for name in ("range", "points_per_second", "rotation_frequency"):
            object.__setattr__(self, name, _positive(name, getattr(self, name)))
        upper = _interval("upper_fov", self.upper_fov, -90.0, 90.0)
        lower = _interval("lower_fov", self.lower_fov, -90.0, 90.0)
        if upper <= lower:
            raise ValueError(
                f"upper_fov must be greater than lower_fov, got upper_fov={upper!r} and lower_fov={lower!r}"
            )
        object.__setattr__(self, "upper_fov", upper)
        object.__setattr__(self, "lower_fov", lower)
        object.__setattr__(self, "horizontal_fov", _interval("horizontal_fov", self.horizontal_fov, 0.0, 360.0, True))
        for name in ("dropoff_general_rate", "dropoff_intensity_limit", "dropoff_zero_intensity"):
            object.__setattr__(self, name, _interval(name, getattr(self, name), 0.0, 1.0))
        for name in ("atmosphere_attenuation_rate", "noise_stddev"):
            v = _number(name, getattr(self, name))
            if v < 0.0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)!r}")
            object.__setattr__(self, name, v)

    @classmethod
    def fogdrive(cls, **overrides: Any) -> LidarConfig:
        """FogDrive's LiDAR: roof at (0, 0, 2), 64 channels, 120 m, 1.3 M points/s, 20 Hz, FOV [−20°, +5°] × 360°.

        >>> LidarConfig.fogdrive(noise_stddev=0.02).noise_stddev
        0.02
        """
        values = dict(pose=Pose(0.0, 0.0, 2.0), channels=64, range=120.0, points_per_second=1_300_000.0,
                      rotation_frequency=20.0, upper_fov=5.0, lower_fov=-20.0, horizontal_fov=360.0)  # fmt: skip
        values.update(overrides)
        return cls(**values)

    @classmethod
    def fogdrive_semantic(cls, **overrides: Any) -> SemanticLidarConfig:
        """FogDrive's semantic LiDAR: as :meth:`fogdrive` with 750 k points/s (a :class:`SemanticLidarConfig`).

        >>> LidarConfig.fogdrive_semantic().points_per_channel(20)
        586
        """
        return SemanticLidarConfig.fogdrive(**{"points_per_second": 750_000.0, **overrides})

    def points_per_channel(self, simulation_frequency: float = 20.0) -> int:
        """Rays per laser per tick, ``points_per_second / (simulation_frequency · channels)`` rounded half up.

        >>> LidarConfig(channels=32, points_per_second=56000).points_per_channel(10)
        175
        """
        f = _simulation_frequency(simulation_frequency)
        return int(math.floor(self.points_per_second / (f * self.channels) + 0.5))

    def tick_angle(self, simulation_frequency: float = 20.0) -> float:
        """Degrees the head turns in one tick: ``rotation_frequency · horizontal_fov / simulation_frequency``.

        >>> LidarConfig.fogdrive().tick_angle(20)
        360.0
        """
        return self.rotation_frequency * self.horizontal_fov / _simulation_frequency(simulation_frequency)

    def ray_angles(self, simulation_frequency: float = 20.0, start_angle: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """Laser elevations ``(C,)`` (upper first) and the tick's azimuths ``(M,)``, degrees, as CARLA.

        Azimuth ``i`` is ``fmod(start_angle + i · tick_angle / M, horizontal_fov) − horizontal_fov / 2``; pass
        ``(start_angle + tick_angle) % horizontal_fov`` to the next tick when one tick is not a full sweep.

        >>> el, az = LidarConfig(channels=3, upper_fov=0, lower_fov=-10, points_per_second=240,
        ...                      rotation_frequency=20).ray_angles(20)
        >>> el.tolist(), az.tolist()
        ([0.0, -5.0, -10.0], [-180.0, -90.0, 0.0, 90.0])
        """
        m = self.points_per_channel(simulation_frequency)
        c = self.channels
        step_el = 0.0 if c == 1 else (self.upper_fov - self.lower_fov) / (c - 1)
        elevations = self.upper_fov - step_el * np.arange(c)
        step_az = self.tick_angle(simulation_frequency) / m
        azimuths = np.fmod(float(start_angle) + step_az * np.arange(m), self.horizontal_fov) - self.horizontal_fov / 2
        return elevations, azimuths


@dataclass(frozen=True)
class SemanticLidarConfig(LidarConfig):
    """A semantic LiDAR (CARLA ``sensor.lidar.ray_cast_semantic``): the LiDAR's attributes, its own type so that a
    rig's sensor registry builds a semantic LiDAR for it (:mod:`fog_gym.sensors`).

    >>> isinstance(LidarConfig.fogdrive_semantic(), SemanticLidarConfig)
    True
    """


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
            object.__setattr__(self, name, _positive(name, getattr(self, name)))
        for name in ("horizontal_fov", "vertical_fov"):
            v = _number(name, getattr(self, name))
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
        return int(math.floor(self.points_per_second / _simulation_frequency(simulation_frequency) + 1e-9))


def sensor_to_world(pose: Pose, ego_pose: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> np.ndarray:
    """4×4 sensor→world transform of a sensor mounted at ``pose`` on an ego at ``(x, y, yaw_rad)`` (ground origin).

    >>> sensor_to_world(Pose(0, 0, 2), (10.0, 5.0, 0.0))[:3, 3].tolist()
    [10.0, 5.0, 2.0]
    """
    pose = Pose.coerce(pose)
    return yaw_transform(*ego_pose) @ transform_matrix(pose.location, pose.rotation)


@functools.lru_cache(maxsize=16)
def _lidar_directions(cfg: LidarConfig, simulation_frequency: float, start_angle: float) -> np.ndarray:
    el, az = cfg.ray_angles(simulation_frequency, start_angle)
    e = np.radians(el)[:, None]
    a = np.radians(az)[None, :]
    dirs = np.stack(np.broadcast_arrays(np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)), axis=-1)
    dirs = np.ascontiguousarray(dirs.reshape(-1, 3))
    dirs.flags.writeable = False
    return dirs


def lidar_directions(cfg: LidarConfig, simulation_frequency: float = 20.0, start_angle: float = 0.0) -> np.ndarray:
    """Unit ray directions ``(channels · M, 3)`` of one tick in the sensor frame, channel-major (read-only, cached).

    >>> lidar_directions(LidarConfig.fogdrive()).shape
    (65024, 3)
    """
    return _lidar_directions(cfg, float(_simulation_frequency(simulation_frequency)), float(start_angle))


def _transform(sensor_to_world: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    m = np.asarray(sensor_to_world, np.float64)
    if m.shape != (4, 4) or not np.all(np.isfinite(m)):
        raise ValueError(f"sensor_to_world must be a finite 4x4 matrix, got shape {m.shape}")
    return m[:3, :3], m[:3, 3].copy()


@njit(cache=True)
def _lidar_points(dirs, dist, index, noise, uniform, attenuation, limit, alpha, beta):
    """Kept returns as (N, 4) float32 x, y, z, intensity; ``noise`` / ``uniform`` empty when switched off.

    Intensity and the drop-off test are float32, as CARLA computes them."""
    n = dirs.shape[0]
    intensity = np.empty(n, dtype=np.float32)
    keep = np.zeros(n, dtype=np.bool_)
    neg_a = np.float32(-attenuation)
    limit32 = np.float32(limit)
    alpha32 = np.float32(alpha)
    beta32 = np.float32(beta)
    count = 0
    for i in range(n):
        if index[i] == MISS:
            continue
        value = np.exp(neg_a * dist[i])
        intensity[i] = value
        if value > limit32 or uniform.shape[0] == 0 or uniform[i] < alpha32 * value + beta32:
            keep[i] = True
            count += 1
    out = np.empty((count, 4), dtype=np.float32)
    k = 0
    for i in range(n):
        if keep[i]:
            r = np.float64(dist[i])
            if noise.shape[0] > 0:
                r += noise[i]
            out[k, 0] = dirs[i, 0] * r
            out[k, 1] = dirs[i, 1] * r
            out[k, 2] = dirs[i, 2] * r
            out[k, 3] = intensity[i]
            k += 1
    return out


@njit(cache=True)
def _semantic_points(dirs, dist, index, cosine, rotation, origin, insts, tags, grid, gx0, gy0, res, surface_tags):
    """Returns as (N, 6) float32 x, y, z, cos, id, tag; ground tags from the surface grid (as SurfaceMap.class_at)."""
    n = dirs.shape[0]
    count = 0
    for i in range(n):
        if index[i] != MISS:
            count += 1
    out = np.empty((count, 6), dtype=np.float32)
    rows, cols = grid.shape
    k = 0
    for i in range(n):
        p = index[i]
        if p == MISS:
            continue
        d = np.float64(dist[i])
        out[k, 0] = dirs[i, 0] * d
        out[k, 1] = dirs[i, 1] * d
        out[k, 2] = dirs[i, 2] * d
        out[k, 3] = cosine[i]
        if p >= 0:
            out[k, 4] = insts[p]
            out[k, 5] = tags[p]
        else:
            ux, uy, uz = dirs[i, 0], dirs[i, 1], dirs[i, 2]
            wx = origin[0] + d * (rotation[0, 0] * ux + rotation[0, 1] * uy + rotation[0, 2] * uz)
            wy = origin[1] + d * (rotation[1, 0] * ux + rotation[1, 1] * uy + rotation[1, 2] * uz)
            col = int(np.floor((wx - gx0) / res))
            row = int(np.floor((wy - gy0) / res))
            cls = grid[row, col] if 0 <= row < rows and 0 <= col < cols else 0
            out[k, 4] = 0.0
            out[k, 5] = surface_tags[cls]
        k += 1
    return out


_NONE = np.zeros(0)


def simulate_lidar(
    cfg: LidarConfig,
    sensor_to_world: np.ndarray,
    prims: Primitives | Mapping[str, Any],
    surface: SurfaceMap | None,
    rng: np.random.Generator,
    simulation_frequency: float = 20.0,
    start_angle: float = 0.0,
) -> np.ndarray:
    """One tick of a ray-cast LiDAR: ``(N, 4)`` float32 x, y, z, intensity in the sensor frame.

    Follows CARLA: each ray is first skipped with probability ``dropoff_general_rate``; a hit within ``range``
    gets intensity ``I = exp(−atmosphere_attenuation_rate · d)`` from the exact distance ``d``; with
    ``noise_stddev > 0`` the point moves along its ray by N(0, σ); then it is kept if ``I >
    dropoff_intensity_limit``, else with probability ``I · dropoff_zero_intensity / dropoff_intensity_limit +
    1 − dropoff_zero_intensity``. Misses give no point. Points are in laser order (channel-major).
    ``surface`` is not used (CARLA's intensity has no reflectivity term); it keeps the LiDAR signatures alike.
    The random draws (a uniform per ray for the general drop-off, then per traced ray a normal for the noise and a
    uniform for the intensity drop-off, each only when switched on) all come from ``rng``: a seed fixes the result.

    >>> cfg = LidarConfig.fogdrive(dropoff_general_rate=0.0, dropoff_zero_intensity=0.0)
    >>> pts = simulate_lidar(cfg, sensor_to_world(cfg.pose), Primitives.empty(), None, np.random.default_rng(0))
    >>> len(pts) // 1016, bool(np.allclose(pts[:, 2], -2.0, atol=1e-4))  # the 48 rings that meet the ground in 120 m
    (48, True)
    >>> bool(np.allclose(pts[:, 3], np.exp(-0.004 * np.linalg.norm(pts[:, :3], axis=1)), atol=1e-6))
    True
    """
    rot, origin = _transform(sensor_to_world)
    dirs = lidar_directions(cfg, simulation_frequency, start_angle)
    if cfg.dropoff_general_rate > _EPS:  # rays skipped before tracing
        dirs = dirs.take(np.flatnonzero(rng.random(dirs.shape[0]) >= cfg.dropoff_general_rate), axis=0)
    n = dirs.shape[0]
    hits = cast_rays(origin, dirs, cfg.range, prims, rotation=rot)
    noise = rng.normal(0.0, cfg.noise_stddev, n) if cfg.noise_stddev > _EPS else _NONE
    uniform = rng.random(n) if cfg.dropoff_zero_intensity > 0.0 else _NONE
    limit = cfg.dropoff_intensity_limit
    alpha = cfg.dropoff_zero_intensity / limit if limit > 0.0 else 0.0
    return _lidar_points(dirs, hits.distance, hits.index, noise, uniform, cfg.atmosphere_attenuation_rate, limit,
                         alpha, 1.0 - cfg.dropoff_zero_intensity)  # fmt: skip


def simulate_semantic_lidar(
    cfg: LidarConfig,
    sensor_to_world: np.ndarray,
    prims: Primitives | Mapping[str, Any],
    surface: SurfaceMap,
    rng: np.random.Generator | None = None,
    simulation_frequency: float = 20.0,
    start_angle: float = 0.0,
) -> np.ndarray:
    """One tick of a semantic LiDAR: ``(N, 6)`` float32 x, y, z, cos(incidence), object id, semantic tag.

    Same ray pattern as :func:`simulate_lidar` but no intensity, drop-off or noise, so ``rng`` is not used.
    The object id is the primitive's ``insts`` (vehicle id; 0 for the static world and the ground); the ground's
    tag is ``SURFACE_TAGS[surface.class_at(x, y)]`` at the hit. cos(incidence) is ``|ray · surface normal|``.

    >>> from fog_gym.scenery import SurfaceMap
    >>> surface = SurfaceMap(np.zeros((10, 10), np.uint8), (-5.0, -5.0), 1.0)
    >>> box = {"centers": np.array([[10.0, 0, 1]]), "halves": np.array([[1.0, 1, 1]]), "yaws": np.zeros(1),
    ...        "tags": np.array([14], np.uint8), "insts": np.array([7], np.uint16)}
    >>> cfg = LidarConfig.fogdrive_semantic()
    >>> pts = simulate_semantic_lidar(cfg, sensor_to_world(cfg.pose), box, surface)
    >>> car = pts[pts[:, 4] == 7]
    >>> round(float(car[:, 0].min()), 3), set(car[:, 5].tolist())
    (9.0, {14.0})
    """
    rot, origin = _transform(sensor_to_world)
    dirs = lidar_directions(cfg, simulation_frequency, start_angle)
    prims = Primitives.coerce(prims)
    hits = cast_rays(origin, dirs, cfg.range, prims, rotation=rot)
    grid = np.ascontiguousarray(surface.grid, np.uint8)
    return _semantic_points(
        dirs, hits.distance, hits.index, hits.cos_incidence, rot, origin,
        prims.insts, prims.tags, grid,
        float(surface.origin[0]), float(surface.origin[1]), float(surface.resolution), SURFACE_TAGS,
    )  # fmt: skip


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
    :class:`~fog_gym.world.VehicleState`; ids it lacks count as standing still. Azimuth (positive to the right)
    and altitude come from the ray direction in the sensor frame; depth is the hit distance.

    >>> box = {"centers": np.array([[22.0, 0, 1]]), "halves": np.array([[2.0, 1, 1]]), "yaws": np.zeros(1),
    ...        "tags": np.array([14], np.uint8), "insts": np.array([5], np.uint16)}
    >>> cfg = RadarConfig.fogdrive()
    >>> det = simulate_radar(cfg, sensor_to_world(cfg.pose), box, np.random.default_rng(0), {5: (-3.0, 0, 0)})
    >>> bool(len(det) > 0 and np.all(det[:, 0] < 0) and np.all(det[:, 3] >= 18.0))
    True
    """
    rot, origin = _transform(sensor_to_world)
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

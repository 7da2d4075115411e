"""``LIDAR_TOP``: a CARLA-style rotating ray-cast LiDAR (x, y, z, intensity) — its config, its physics and its sensor.

Pure functions of the render primitives (upright boxes, see :mod:`fog_gym.world.scene`), a sensor→world transform
and a seeded ``numpy.random.Generator``; nothing here imports the environment. The model follows CARLA's
``sensor.lidar.ray_cast`` (RayCastLidar.cpp; research note fog_physics.md §4.2):

* ray pattern: ``channels`` lasers evenly spaced from ``upper_fov`` down to ``lower_fov``; each shoots
  ``round(points_per_second / (simulation_frequency · channels))`` rays per tick, evenly spaced over the
  ``rotation_frequency · horizontal_fov / simulation_frequency`` degrees the head turns in one tick
  (one full sweep when the rotation frequency equals the simulation frequency);
* intensity ``exp(−a · d)``, general and intensity drop-off, Gaussian range noise.

Points are in the sensor frame: left-handed, +x forward, +y right, +z up (as CARLA's ``raw_data``). Pass
primitives without the ego's own boxes (``Scene.primitives`` leaves them out); a sensor inside a box sees through
it in any case, as a line trace that starts inside a mesh. The semantic LiDAR (:mod:`fog_gym.sensors.semantic_lidar`)
shares the ray pattern; its config type :class:`SemanticLidarConfig` lives here beside the LiDAR's.

Example:
    >>> s = LidarSensor(LidarConfig.fogdrive())
    >>> s.channels, s.layout()["LIDAR_TOP"].folder, s.layout()["LIDAR_TOP_FOG_DENSE"].folder, s.space().shape[1]
    (('LIDAR_TOP',), 'lidar', 'lidar_fog_dense', 4)
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numba import njit

from fog_gym._numba import defer, readonly
from fog_gym.checks import finite, interval, positive
from fog_gym.channels.spec import FOG_LEVELS, LIDAR_MOTIONS, lidar_channel, lidar_columns
from fog_gym.geometry import Pose, sensor_to_world, transform_matrix
from fog_gym.sensors.base import PointSensor, point_space, register
from fog_gym.channels.packing import LIDAR
from fog_gym.sensors.raycast import GROUND, MISS, RayHits, cast_ray_slices, cast_rays
from fog_gym.world.motion import SliceWorlds
from fog_gym.world.primitives import Primitives
from fog_gym.world.scenery import ROAD, SurfaceMap

_EPS = float(np.finfo(np.float32).eps)  # CARLA switches drop-off / noise on above float epsilon


def simulation_frequency_hz(value: Any) -> float:
    """A simulation frequency [Hz] > 0 (every point sensor's ray count depends on it)."""
    return positive("simulation_frequency", value)


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
    #: "carla": CARLA's ``exp(−attenuation · d)`` (FogDrive's data); "reflectance": the surface's LiDAR reflectivity
    #: (its material, or the road surface's class) × |cos incidence| × ``exp(−attenuation · d)``
    intensity: str = "carla"
    #: The echo a beam reports in fog (:mod:`fog_gym.fog.returns`): "strongest" (FogDrive's, today's output),
    #: "last" or "dual" (both, with a ``return`` column). A LiDAR in "last" or "dual" mode names its channels
    #: ``<name>_LAST`` / ``<name>_DUAL`` (and their fog variants ``<name>_DUAL_FOG_<LEVEL>``).
    returns: str = "strongest"
    #: The sweep's timing (:mod:`fog_gym.sensors.motion`): "instant" (FogDrive's: the whole sweep at the keyframe's
    #: instant, as CARLA's synchronous mode) or "continuous" (each azimuth fires at its time within the sweep, the ego
    #: and every vehicle where they are then; a ``time`` column; channels ``<name>_MOTION``)
    motion: str = "instant"

    def __post_init__(self) -> None:
        object.__setattr__(self, "pose", Pose.coerce(self.pose))
        ch = self.channels
        if isinstance(ch, bool) or not isinstance(ch, (int, np.integer, float)) or (
            isinstance(ch, float) and not ch.is_integer()
        ) or ch < 1:
            raise ValueError(f"channels must be an integer >= 1, got {ch!r}")
        object.__setattr__(self, "channels", int(ch))
        for name in ("range", "points_per_second", "rotation_frequency"):
            object.__setattr__(self, name, positive(name, getattr(self, name)))
        upper = interval("upper_fov", self.upper_fov, -90.0, 90.0)
        lower = interval("lower_fov", self.lower_fov, -90.0, 90.0)
        if upper <= lower:
            raise ValueError(
                f"upper_fov must be greater than lower_fov, got upper_fov={upper!r} and lower_fov={lower!r}"
            )
        object.__setattr__(self, "upper_fov", upper)
        object.__setattr__(self, "lower_fov", lower)
        object.__setattr__(self, "horizontal_fov", interval("horizontal_fov", self.horizontal_fov, 0.0, 360.0, True))
        for name in ("dropoff_general_rate", "dropoff_intensity_limit", "dropoff_zero_intensity"):
            object.__setattr__(self, name, interval(name, getattr(self, name), 0.0, 1.0))
        for name in ("atmosphere_attenuation_rate", "noise_stddev"):
            v = finite(name, getattr(self, name))
            if v < 0.0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)!r}")
            object.__setattr__(self, name, v)
        if self.intensity not in INTENSITY_MODELS:
            raise ValueError(f"intensity must be one of {INTENSITY_MODELS}, got {self.intensity!r}")
        from fog_gym.fog.returns import check_mode

        check_mode(self.returns)
        if self.motion not in LIDAR_MOTIONS:
            raise ValueError(f"motion must be one of {LIDAR_MOTIONS}, got {self.motion!r}")
        if self.motion != "instant" and type(self).__name__ == "SemanticLidarConfig":
            raise ValueError("motion: the semantic LiDAR sweeps instantaneously (motion='instant'); 'continuous' is the LiDAR's")

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
        f = simulation_frequency_hz(simulation_frequency)
        return int(math.floor(self.points_per_second / (f * self.channels) + 0.5))

    def tick_angle(self, simulation_frequency: float = 20.0) -> float:
        """Degrees the head turns in one tick: ``rotation_frequency · horizontal_fov / simulation_frequency``.

        >>> LidarConfig.fogdrive().tick_angle(20)
        360.0
        """
        return self.rotation_frequency * self.horizontal_fov / simulation_frequency_hz(simulation_frequency)

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
    return _lidar_directions(cfg, float(simulation_frequency_hz(simulation_frequency)), float(start_angle))


def split_transform(sensor_to_world: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(rotation (3, 3), origin (3,))`` of a 4×4 sensor→world transform, which must be finite."""
    m = np.asarray(sensor_to_world, np.float64)
    if m.shape != (4, 4) or not np.all(np.isfinite(m)):
        raise ValueError(f"sensor_to_world must be a finite 4x4 matrix, got shape {m.shape}")
    return m[:3, :3], m[:3, 3].copy()


#: Values of :attr:`LidarConfig.intensity`.
INTENSITY_MODELS: tuple[str, ...] = ("carla", "reflectance")


@njit(cache=True, nogil=True)
def _kept_rays(u, rate, dirs):
    """``rays = np.flatnonzero(u >= rate)`` and ``dirs.take(rays, axis=0)``: the rays the general drop-off keeps, in
    one call (numpy's comparison, ``flatnonzero`` and ``take`` each release the GIL, which in the pixel vector env
    another world's thread then holds for its whole stretch of Python)."""
    n = 0
    for i in range(u.shape[0]):
        if u[i] >= rate:
            n += 1
    rays = np.empty(n, np.int64)
    out = np.empty((n, 3), dirs.dtype)
    k = 0
    for i in range(u.shape[0]):
        if u[i] >= rate:
            rays[k] = i
            out[k, 0], out[k, 1], out[k, 2] = dirs[i, 0], dirs[i, 1], dirs[i, 2]
            k += 1
    return rays, out


@njit(cache=True, nogil=True)
def _lidar_points(dirs, dist, index, noise, uniform, attenuation, limit, alpha, beta, reflect, extra):
    """Kept returns as (N, 4) float32 x, y, z, intensity; ``noise`` / ``uniform`` empty when switched off;
    ``reflect`` (N,) float32 the reflectivity × incidence factor of each ray's hit, or empty (CARLA's model);
    ``extra`` (N,) float32 a fifth column (each ray's time), or empty.

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
        if reflect.shape[0] > 0:
            value = value * reflect[i]
        intensity[i] = value
        if value > limit32 or uniform.shape[0] == 0 or uniform[i] < alpha32 * value + beta32:
            keep[i] = True
            count += 1
    out = np.empty((count, 4 if extra.shape[0] == 0 else 5), dtype=np.float32)
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
            if extra.shape[0] > 0:
                out[k, 4] = extra[i]
            k += 1
    return out


@njit(cache=True, nogil=True)
def _slice_sort(rays, dirs, col_slice, slice_time, order, sorted_dirs, bounds, ray_time):
    """The traced rays of a sweep that takes time sorted by slice, stably (laser order within a slice):
    ``rays`` the traced rays' laser indices, ascending (channel-major: ``len(col_slice)`` columns a channel),
    ``dirs`` their directions, ``col_slice`` each column's slice (non-decreasing), ``slice_time`` each slice's time.
    Writes ``order`` (each sorted ray's position in ``rays``), ``sorted_dirs`` (its direction), ``bounds`` (slice
    ``k`` is ``bounds[k]:bounds[k + 1]``) and ``ray_time`` (each traced ray's time): what
    :func:`fog_gym.sensors.motion.sweep_order` and a take give. A slice's rays in one channel are a run of ``rays``
    (found by bisection), so the sort copies runs."""
    n, m, n_slices = rays.shape[0], col_slice.shape[0], bounds.shape[0] - 1
    first = np.full(n_slices + 1, m, np.int64)  # each slice's first column (m: none, or past the last)
    for c in range(m - 1, -1, -1):
        first[col_slice[c]] = c
    for k in range(n_slices - 1, -1, -1):
        first[k] = min(first[k], first[k + 1])
    n_channels = rays[n - 1] // m + 1 if n > 0 else 0
    start = np.empty((n_channels, n_slices + 1), np.int64)  # run (c, k) is rays[start[c, k]:start[c, k + 1]]
    for c in range(n_channels):
        for k in range(n_slices + 1):
            start[c, k] = np.searchsorted(rays, c * m + first[k])
    bounds[0] = 0
    for k in range(n_slices):
        size = 0
        for c in range(n_channels):
            size += start[c, k + 1] - start[c, k]
        bounds[k + 1] = bounds[k] + size
    for k in range(n_slices):
        p = bounds[k]
        t = slice_time[k]
        for c in range(n_channels):
            for i in range(start[c, k], start[c, k + 1]):
                order[p] = i
                sorted_dirs[p, 0] = dirs[i, 0]
                sorted_dirs[p, 1] = dirs[i, 1]
                sorted_dirs[p, 2] = dirs[i, 2]
                ray_time[i] = t
                p += 1


_NONE = np.zeros(0)


@functools.lru_cache(maxsize=16)
def _slice_plan(n_columns: int, simulation_frequency: float) -> tuple[np.ndarray, np.ndarray]:
    """A sweep that takes time's slices: each azimuth column's slice (int32) and each slice's time (read-only)."""
    from fog_gym.sensors.motion import column_slices, slice_count, slice_times

    n_slices = slice_count(n_columns)
    col_slice = column_slices(np.arange(n_columns), n_columns, n_slices).astype(np.int32)
    times = slice_times(simulation_frequency, n_slices)
    col_slice.flags.writeable = times.flags.writeable = False
    return col_slice, times


def simulate_lidar(
    cfg: LidarConfig,
    sensor_to_world: np.ndarray,
    prims: Primitives | Mapping[str, Any],
    surface: SurfaceMap | None,
    rng: np.random.Generator,
    simulation_frequency: float = 20.0,
    start_angle: float = 0.0,
    motion: Callable[[float], tuple[np.ndarray, Primitives]] | tuple[np.ndarray, SliceWorlds] | None = None,
) -> np.ndarray:
    """One tick of a ray-cast LiDAR: ``(N, 4)`` float32 x, y, z, intensity in the sensor frame.

    Follows CARLA: each ray is first skipped with probability ``dropoff_general_rate``; a hit within ``range``
    gets intensity ``I = exp(−atmosphere_attenuation_rate · d)`` from the exact distance ``d``; with
    ``noise_stddev > 0`` the point moves along its ray by N(0, σ); then it is kept if ``I >
    dropoff_intensity_limit``, else with probability ``I · dropoff_zero_intensity / dropoff_intensity_limit +
    1 − dropoff_zero_intensity``. Misses give no point. Points are in laser order (channel-major).
    ``surface`` gives the ground's reflectivity for ``cfg.intensity == "reflectance"`` (CARLA's intensity has no
    reflectivity term): then ``I = ρ · |cos θ| · exp(−attenuation · d)`` with ``ρ`` the surface's LiDAR reflectivity.
    The random draws (a uniform per ray for the general drop-off, then per traced ray a normal for the noise and a
    uniform for the intensity drop-off, each only when switched on) all come from ``rng``: a seed fixes the result.
    ``motion`` (a sweep that takes time, :mod:`fog_gym.sensors.motion`): ``motion(t)`` gives the sensor→world
    transform and the primitives at ``t`` seconds from the tick's end (or, at the slices' times
    :func:`~fog_gym.sensors.motion.slice_times`, the pair of the transforms ``(S, 4, 4)`` and a
    :class:`~fog_gym.world.motion.SliceWorlds`); each slice of azimuth columns is cast from there, and a fifth
    column holds each point's time (the same draws: in a still world the first four columns equal the
    instantaneous sweep's).

    >>> cfg = LidarConfig.fogdrive(dropoff_general_rate=0.0, dropoff_zero_intensity=0.0)
    >>> pts = simulate_lidar(cfg, sensor_to_world(cfg.pose), Primitives.empty(), None, np.random.default_rng(0))
    >>> len(pts) // 1016, bool(np.allclose(pts[:, 2], -2.0, atol=1e-4))  # the 48 rings that meet the ground in 120 m
    (48, True)
    >>> bool(np.allclose(pts[:, 3], np.exp(-0.004 * np.linalg.norm(pts[:, :3], axis=1)), atol=1e-6))
    True
    """
    rot, origin = split_transform(sensor_to_world)
    dirs = lidar_directions(cfg, simulation_frequency, start_angle)
    rays = None
    if cfg.dropoff_general_rate > _EPS:  # rays skipped before tracing
        rays, dirs = defer(_kept_rays)(rng.random(dirs.shape[0]), float(cfg.dropoff_general_rate), dirs)
    n = dirs.shape[0]
    times = None
    if motion is None:
        hits = cast_rays(origin, dirs, cfg.range, prims, rotation=rot)
        reflect = _NONE32 if cfg.intensity == "carla" else reflectance(hits, dirs, rot, origin, surface, prims.colors)
    else:  # a sweep that takes time: each slice of columns from where the sensor and the world are at its time
        m = cfg.points_per_channel(simulation_frequency)
        col_slice, times_of = _slice_plan(m, float(simulation_frequency))
        n_slices = len(times_of)
        if callable(motion):  # each slice's sensor → world and world
            at = [motion(float(t)) for t in times_of]
            s2w, worlds = np.array([np.asarray(a, np.float64) for a, _ in at]), [w for _, w in at]
        else:
            s2w, worlds = np.asarray(motion[0], np.float64), motion[1]
        if s2w.shape != (n_slices, 4, 4) or not np.all(np.isfinite(s2w)):
            raise ValueError(f"motion: each of the {n_slices} slices needs a finite 4x4 sensor_to_world, got "
                             f"{s2w.shape}")  # fmt: skip
        order, bounds, sorted_dirs = np.empty(n, np.int64), np.empty(n_slices + 1, np.int64), np.empty((n, 3))
        times = np.empty(n, np.float32)
        _slice_sort(np.arange(n) if rays is None else rays, dirs, col_slice, times_of.astype(np.float32), order,
                    sorted_dirs, bounds, times)  # fmt: skip  (the slices' rays contiguous: each slice casts a view)
        # every slice in one call, each with bins over its own sector only
        hits = cast_ray_slices(s2w[:, :3, 3], s2w[:, :3, :3], sorted_dirs, bounds, cfg.range, worlds,
                               n_azimuth_bins=SLICE_AZIMUTH_BINS, order=order)  # fmt: skip  (in laser order)
        reflect = _NONE32 if cfg.intensity == "carla" else np.empty(n, np.float32)
        colors = (worlds.prims if isinstance(worlds, SliceWorlds) else Primitives.coerce(worlds[0])).colors
        for k in range(n_slices if reflect.size else 0):
            lo, hi = bounds[k], bounds[k + 1]
            if lo < hi:
                rows = order[lo:hi]
                reflect[rows] = reflectance(RayHits(*(a[rows] for a in hits)), sorted_dirs[lo:hi], s2w[k, :3, :3],
                                            s2w[k, :3, 3], surface, colors)  # fmt: skip
    noise = rng.normal(0.0, cfg.noise_stddev, n) if cfg.noise_stddev > _EPS else _NONE
    uniform = rng.random(n) if cfg.dropoff_zero_intensity > 0.0 else _NONE
    limit = cfg.dropoff_intensity_limit
    alpha = cfg.dropoff_zero_intensity / limit if limit > 0.0 else 0.0
    return defer(_lidar_points)(readonly(dirs), hits.distance, hits.index, noise, uniform,
                                cfg.atmosphere_attenuation_rate, limit, alpha, 1.0 - cfg.dropoff_zero_intensity, reflect,
                                _NONE32 if times is None else times)  # fmt: skip


_NONE32 = np.zeros(0, np.float32)


#: Azimuth bins of the ray caster over one slice of a sweep that takes time (``cast_rays(sector=True)``: the bins
#: cover the slice's 16th of the turn; the hits do not depend on the bins)
SLICE_AZIMUTH_BINS = 64


def paint_reflectivity(colors: np.ndarray) -> np.ndarray:
    """LiDAR reflectivity of paint of albedo ``colors`` (N, 3): 0.05 + 0.6 × its luminance (dark paint ≈ 0.1, white
    paint ≈ 0.6).

    >>> paint_reflectivity(np.array([[0.08, 0.08, 0.09], [0.92, 0.92, 0.92]])).round(2).tolist()
    [0.1, 0.6]
    """
    return 0.05 + 0.6 * (np.asarray(colors, np.float64) @ np.array([0.2126, 0.7152, 0.0722]))


def reflectance(hits, dirs: np.ndarray, rot: np.ndarray, origin: np.ndarray, surface: SurfaceMap | None,
                colors: np.ndarray) -> np.ndarray:  # fmt: skip
    """Each ray's reflectivity × |cos incidence| (float32): a surface's LiDAR reflectivity from the material it hit
    (:data:`fog_gym.world.mesh.MATERIAL_REFLECTIVITY`; a material that shows the primitive's colour, such as a car's
    paint, takes :func:`paint_reflectivity` of ``colors[primitive]`` for that share), on the ground from the road
    surface's class (lane markings' retroreflective paint, asphalt, pavement, grass:
    :data:`fog_gym.world.scenery.SURFACE_REFLECTIVITY`)."""
    from fog_gym.world.mesh import MATERIAL_PAINT, MATERIAL_REFLECTIVITY
    from fog_gym.world.scenery import SURFACE_REFLECTIVITY

    rho = np.zeros(len(hits.index), np.float64)
    obj = np.flatnonzero(hits.index >= 0)
    mat = np.minimum(hits.material[obj], len(MATERIAL_REFLECTIVITY) - 1)
    share = MATERIAL_PAINT[mat]
    rho[obj] = MATERIAL_REFLECTIVITY[mat] * (1.0 - share) + share * paint_reflectivity(colors[hits.index[obj]])
    ground = np.flatnonzero(hits.index == GROUND)
    if len(ground):
        if surface is None:
            rho[ground] = SURFACE_REFLECTIVITY[ROAD]
        else:
            p = origin + (dirs[ground] @ rot.T) * hits.distance[ground, None]
            rho[ground] = SURFACE_REFLECTIVITY[surface.class_at(p[:, 0], p[:, 1])]
    return (rho * hits.cos_incidence).astype(np.float32)


def lidar_space(cfg, simulation_frequency: float, semantic: bool) -> Any:
    """Box of a (semantic) LiDAR channel: one row per ray cast in a tick."""
    capacity = cfg.channels * cfg.points_per_channel(simulation_frequency)
    reach = cfg.range + 10.0 * cfg.noise_stddev + 1.0
    if semantic:  # x, y, z, cos(incidence), object id, tag
        low, high = [-reach, -reach, -reach, 0.0, 0.0, 0.0], [reach, reach, reach, 1.0, 65535.0, 255.0]
    else:  # x, y, z, intensity
        low, high = [-reach, -reach, -reach, 0.0], [reach, reach, reach, 1.0]
    return point_space(capacity, low, high)


@register(LidarConfig)
class LidarSensor(PointSensor):
    kind = "lidar"
    default_channel, columns, default_folder = LIDAR, 4, "lidar"

    def __init__(self, config: Any, simulation_frequency: float = 20.0, channel: str | None = None) -> None:
        super().__init__(config, simulation_frequency, channel)
        if self.channel == self.default_channel:  # LIDAR_TOP_LAST / _DUAL / _MOTION: not FogDrive's data
            self.channel = lidar_channel(self.default_channel, config.returns, config.motion)
        #: x, y, z, intensity; then ``time`` (a sweep that takes time) and ``return`` (dual: 0 a beam's strongest
        #: echo, 1 its last where it differs) — :func:`fog_gym.channels.spec.lidar_columns`
        self.columns = len(lidar_columns(config.returns, config.motion))
        #: ``(S + 1, 4)`` rows of ``(t, x, y, yaw)``: the ego's pose at each slice of the latest continuous sweep
        #: and at the keyframe (None for an instantaneous sweep)
        self.ego_poses: np.ndarray | None = None
        self._mount: np.ndarray | None = None

    @classmethod
    def build(cls, name: str, config: Any, simulation_frequency: float = 20.0, far: float = 1000.0) -> PointSensor:
        """The sensor of a rig entry ``(name, config)``: its channel is ``name`` (``name_LAST`` / ``name_DUAL`` in
        the other return modes and ``…_MOTION`` for a sweep that takes time: their data are not FogDrive's)."""
        return cls(config, simulation_frequency, channel=lidar_channel(name, config.returns, config.motion))

    def layout(self):
        """The clean channel and its fog variants ``<channel>_FOG_<LEVEL>`` in ``<folder>_fog_<level>``."""
        out = super().layout()
        for lv in FOG_LEVELS:
            out[f"{self.channel}_FOG_{lv}"] = out[self.channel]._replace(folder=f"{self.folder}_fog_{lv.lower()}")
        return out

    def space(self):
        box = lidar_space(self.config, self.simulation_frequency, semantic=False)
        cfg = self.config
        low, high, capacity = list(box.low[0]), list(box.high[0]), box.shape[0]
        if cfg.motion == "continuous":  # the time column: within the tick before the keyframe
            low, high = low + [-1.0 / self.simulation_frequency], high + [0.0]
        if cfg.returns == "dual":  # a second echo per beam at most; the return column in [0, 1]
            low, high, capacity = low + [0.0], high + [1.0], 2 * capacity
        if len(low) == 4:
            return box
        return point_space(capacity, low, high)

    def measure(self, scene, prims, rng: np.random.Generator, tick: int) -> dict[str, np.ndarray]:
        cfg = self.config
        motion = None
        if cfg.motion == "continuous":
            from fog_gym.sensors.motion import pose_matrices
            from fog_gym.world.motion import SceneMotion

            if self._mount is None:  # sensor_to_world's mount, once
                mp = Pose.coerce(cfg.pose)
                self._mount = transform_matrix(mp.location, mp.rotation)
            sm = SceneMotion(scene.vehicles, getattr(scene, "previous", None))
            times = np.append(_slice_plan(cfg.points_per_channel(self.simulation_frequency),
                                          float(self.simulation_frequency))[1], 0.0)  # each slice's, the keyframe's
            poses = sm.ego_poses_during(times, scene.ego_id)
            # each slice's sensor → world and world, from one pass over the slices
            motion = (pose_matrices(poses[:-1]) @ self._mount, sm.slice_worlds(prims, times[:-1]))
            self.ego_poses = np.c_[times, poses]
        pts = simulate_lidar(cfg, sensor_to_world(cfg.pose, scene.ego_pose), prims, scene.static.surface, rng,
                             self.simulation_frequency, self.start_angle(tick), motion)  # fmt: skip
        if cfg.returns == "dual":  # in clear air a beam's strongest echo is its last: one row, return 0
            pts = np.concatenate([pts, np.zeros((len(pts), 1), np.float32)], axis=1)
        return {self.channel: pts}

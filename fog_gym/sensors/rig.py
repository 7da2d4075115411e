"""The sensor rig: :class:`RigConfig` (an ordered sequence of named sensor configs, FogDrive's preset in
:meth:`RigConfig.fogdrive`), the sensors it builds (:func:`rig_sensors`), its dataset layout (:func:`rig_layout`)
and its point sensors measured together (:class:`PointSensors`).

Example:
    >>> rig = RigConfig.fogdrive(resolution=(320, 240), cameras=("CAM_FRONT",))
    >>> rig.cameras[0].width, rig.cameras[0].pose.z
    (320, 1.2)
    >>> sorted(PointSensors(RigConfig.fogdrive(cameras=[])).channels)
    ['LIDAR_TOP', 'RADAR_FRONT', 'SEM_LIDAR_TOP']
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from fog_gym.checks import parse_resolution
from fog_gym.channels.spec import BBOX_3D, CAMERA_NAMES, FOGDRIVE_CHANNELS, ChannelSpec, check_layout
from fog_gym.geometry import Pose
from fog_gym.sensors.base import REGISTRY, build_sensor, check_sensor_name, registered_type
from fog_gym.sensors.camera import FOGDRIVE_CAMERA_POSES, CameraConfig, CameraSensor
from fog_gym.sensors.lidar import LidarConfig, SemanticLidarConfig
from fog_gym.sensors.radar import RadarConfig
from fog_gym.world.primitives import Primitives
from fog_gym.world.scene import Scene

#: The sensor names of the FogDrive point sensors, which :class:`RigConfig`'s named accessors look up.
LIDAR_NAME, SEMANTIC_LIDAR_NAME, RADAR_NAME = "LIDAR_TOP", "SEM_LIDAR_TOP", "RADAR_FRONT"
_ROLES = (("lidar", LIDAR_NAME), ("semantic_lidar", SEMANTIC_LIDAR_NAME), ("radar", RADAR_NAME))
_UNSET: Any = object()


@dataclass(frozen=True, init=False)
class RigConfig:
    """The sensor rig: one ordered sequence of named sensor configs, ``sensors=((name, config), ...)``.

    Each config's type picks its sensor class (:func:`fog_gym.sensors.sensor_class`: :class:`CameraConfig` →
    camera, :class:`~fog_gym.sensors.lidar.LidarConfig` → LiDAR, :class:`~fog_gym.sensors.lidar.SemanticLidarConfig` → semantic
    LiDAR, :class:`~fog_gym.sensors.radar.RadarConfig` → radar, and any registered type). The env's observation, the fog
    wrapper, labels, the dataset layout, the writer, ``validate`` and the loaders all follow the sequence. A
    point sensor's name is its channel; a camera's name is its :attr:`CameraConfig.name` (channels ``N``,
    ``N_DEPTH``, ``N_SEM``). A bare :class:`CameraConfig` stands for ``(config.name, config)``.

    :meth:`fogdrive` is the FogDrive preset (Table 2, supplementary D5). The named views :attr:`cameras`,
    :attr:`lidar` (``LIDAR_TOP``), :attr:`semantic_lidar` (``SEM_LIDAR_TOP``), :attr:`radar` (``RADAR_FRONT``)
    and :attr:`extra` (every other sensor) are read-only; the keywords of the same names (the pre-sequence
    constructor, and ``dataclasses.replace(rig, lidar=...)``) replace that part of the sequence: a sensor present
    is replaced in place (``None`` removes it), an absent one is inserted in FogDrive order (cameras, LiDAR,
    semantic LiDAR, radar), ``extra`` replaces the other sensors at the end.

    >>> [c.name for c in RigConfig.fogdrive().cameras]
    ['CAM_FRONT', 'CAM_BACK', 'CAM_LEFT', 'CAM_RIGHT']
    >>> rig = RigConfig.fogdrive(resolution=(64, 48), cameras=["CAM_FRONT"])
    >>> rig.names
    ('CAM_FRONT', 'LIDAR_TOP', 'SEM_LIDAR_TOP', 'RADAR_FRONT')
    >>> RigConfig(rig.sensors) == rig
    True
    >>> narrow = CameraConfig("CAM_FRONT_NARROW", Pose(1.8, 0, 1.2), 64, 48, fov=40.0)
    >>> rig.with_sensor(narrow.name, narrow).names[-1]
    'CAM_FRONT_NARROW'
    """

    sensors: tuple[tuple[str, Any], ...] = ()

    def __init__(self, sensors: Sequence[Any] = (), *, cameras: Sequence[CameraConfig] | None = None,
                 lidar: Any = _UNSET, semantic_lidar: Any = _UNSET, radar: Any = _UNSET,
                 extra: Sequence[tuple[str, Any]] | None = None) -> None:  # fmt: skip
        if isinstance(sensors, (str, bytes)) or not isinstance(sensors, Sequence):
            raise ValueError(f"sensors must be a sequence of (name, config) pairs, got {sensors!r}")
        entries = [_entry(e) for e in sensors]
        if cameras is not None or extra is not None or any(v is not _UNSET for v in (lidar, semantic_lidar, radar)):
            entries = _merge_named(entries, cameras, {"lidar": lidar, "semantic_lidar": semantic_lidar, "radar": radar}, extra)
        names = [n for n, _ in entries]
        if len(set(names)) != len(names):
            dup = sorted({n for n in names if names.count(n) > 1})
            raise ValueError(f"sensor names must be unique in a rig (camera names too), got {dup} more than once")
        for name, cfg in entries:
            _check_config_type(name, cfg)
        object.__setattr__(self, "sensors", tuple(entries))

    # -- read-only views --------------------------------------------------------------------------------
    @property
    def names(self) -> tuple[str, ...]:
        """The sensor names in rig order."""
        return tuple(n for n, _ in self.sensors)

    @property
    def cameras(self) -> tuple[CameraConfig, ...]:
        """Every camera of the rig, in rig order."""
        return tuple(c for _, c in self.sensors if isinstance(c, CameraConfig))

    @property
    def lidar(self) -> Any:
        """The config of ``LIDAR_TOP``, or None."""
        return self._named(LIDAR_NAME)

    @property
    def semantic_lidar(self) -> Any:
        """The config of ``SEM_LIDAR_TOP``, or None."""
        return self._named(SEMANTIC_LIDAR_NAME)

    @property
    def radar(self) -> Any:
        """The config of ``RADAR_FRONT``, or None."""
        return self._named(RADAR_NAME)

    @property
    def extra(self) -> tuple[tuple[str, Any], ...]:
        """The sensors that are neither cameras nor ``LIDAR_TOP``, ``SEM_LIDAR_TOP``, ``RADAR_FRONT``."""
        named = {n for _, n in _ROLES}
        return tuple((n, c) for n, c in self.sensors if not isinstance(c, CameraConfig) and n not in named)

    def _named(self, name: str) -> Any:
        return next((c for n, c in self.sensors if n == name), None)

    def sensor(self, name: str) -> Any:
        """The config of the sensor ``name``."""
        for n, c in self.sensors:
            if n == name:
                return c
        raise KeyError(f"no sensor named {name!r} in the rig (sensors: {list(self.names)})")

    def camera(self, name: str) -> CameraConfig:
        for c in self.cameras:
            if c.name == name:
                return c
        raise KeyError(name)

    # -- new rigs ---------------------------------------------------------------------------------------
    def with_sensor(self, name: str, config: Any) -> RigConfig:
        """The same rig with one more sensor at the end (a camera's ``name`` is its config's)."""
        return RigConfig((*self.sensors, (name, config)))

    @classmethod
    def fogdrive(
        cls,
        resolution: Sequence[int] = (1280, 960),
        cameras: Sequence[str] | None = None,
        fov: float = 100.0,
        poses: Mapping[str, Any] | None = None,
        lidar: bool = True,
        semantic_lidar: bool = True,
        radar: bool = True,
    ) -> RigConfig:
        """The FogDrive rig (Table 2, D5), optionally at another resolution, with a subset of cameras, other camera
        poses, or without the LiDAR, semantic LiDAR or radar. Sensor order: cameras, ``LIDAR_TOP``,
        ``SEM_LIDAR_TOP``, ``RADAR_FRONT``."""
        
        w, h = parse_resolution(resolution)
        names = CAMERA_NAMES if cameras is None else tuple(cameras)
        for n in names:
            if n not in CAMERA_NAMES:
                raise ValueError(f"camera name must be one of {CAMERA_NAMES}, got {n!r}")
        poses = dict(poses or {})
        for n in poses:
            if n not in CAMERA_NAMES:
                raise ValueError(f"poses: camera name must be one of {CAMERA_NAMES}, got {n!r}")
        sensors: list[tuple[str, Any]] = [
            (n, CameraConfig(n, Pose.coerce(poses.get(n, FOGDRIVE_CAMERA_POSES[n])), w, h, fov)) for n in names
        ]
        if lidar:
            sensors.append((LIDAR_NAME, LidarConfig.fogdrive()))
        if semantic_lidar:
            sensors.append((SEMANTIC_LIDAR_NAME, LidarConfig.fogdrive_semantic()))
        if radar:
            sensors.append((RADAR_NAME, RadarConfig.fogdrive()))
        return cls(tuple(sensors))

    def with_resolution(self, resolution: Sequence[int]) -> RigConfig:
        """The same rig with every camera at ``(width, height)`` (intrinsics scale with it)."""
        w, h = parse_resolution(resolution)
        return RigConfig(tuple((n, replace(c, width=w, height=h) if isinstance(c, CameraConfig) else c)
                               for n, c in self.sensors))  # fmt: skip


def _entry(e: Any) -> tuple[str, Any]:
    """One ``(name, config)`` entry of a rig (a bare :class:`CameraConfig` is named by itself)."""
    if isinstance(e, CameraConfig):
        return (e.name, e)
    if not (isinstance(e, (tuple, list)) and len(e) == 2):
        raise ValueError(f"sensors must hold (name, config) pairs or CameraConfig instances, got {e!r}")
    name, cfg = e
    check_sensor_name(name)
    if isinstance(cfg, CameraConfig) and cfg.name != name:
        raise ValueError(f"a camera's sensor name is its config's name: got ({name!r}, CameraConfig({cfg.name!r}, ...))")
    return (name, cfg)


#: The config type each FogDrive point-sensor name needs (the type picks the sensor class, so a FogDrive name
#: built by another class would store other data under a FogDrive channel).
_FOGDRIVE_TYPES = {LIDAR_NAME: LidarConfig, SEMANTIC_LIDAR_NAME: SemanticLidarConfig, RADAR_NAME: RadarConfig}


def _check_config_type(name: str, cfg: Any) -> None:
    """A built-in config type or one registered with :func:`fog_gym.sensors.register`; FogDrive names keep their
    FogDrive type (the channel and folder rules of the whole rig are checked by ``fog_gym.sensors.rig_layout``
    when an env or recorder is built)."""
    builtin = (CameraConfig, LidarConfig, RadarConfig)
    if not isinstance(cfg, builtin) and registered_type(type(cfg)) is None:
        known = ", ".join(sorted({t.__name__ for t in (*builtin, SemanticLidarConfig, *REGISTRY)}))
        raise ValueError(f"sensor {name!r}: config type must be one of the registered sensor configs ({known}), "
                         f"got {type(cfg).__name__}")  # fmt: skip
    want = _FOGDRIVE_TYPES.get(name)
    if want is not None and not (isinstance(cfg, want) and (want is not LidarConfig or not isinstance(cfg, SemanticLidarConfig))):
        raise ValueError(f"sensor {name!r} is FogDrive's and needs a {want.__name__}, got {type(cfg).__name__}")
    if name in CAMERA_NAMES and not isinstance(cfg, CameraConfig):
        raise ValueError(f"sensor {name!r} is a FogDrive camera and needs a CameraConfig, got {type(cfg).__name__}")


def _merge_named(entries: list[tuple[str, Any]], cameras: Any, named: dict[str, Any], extra: Any) -> list[tuple[str, Any]]:
    """Apply the pre-sequence keywords (``cameras``, ``lidar``, ``semantic_lidar``, ``radar``, ``extra``)."""
    out = list(entries)
    if cameras is not None:
        cams = tuple(cameras)
        for cam in cams:
            if not isinstance(cam, CameraConfig):
                raise ValueError(f"cameras must be CameraConfig instances, got {cam!r}")
        cam_names = [c.name for c in cams]
        if len(set(cam_names)) != len(cam_names):
            raise ValueError(f"camera names must be unique, got {cam_names}")
        at = next((i for i, (_, c) in enumerate(out) if isinstance(c, CameraConfig)), 0)
        out = [e for e in out if not isinstance(e[1], CameraConfig)]
        out[at:at] = [(c.name, c) for c in cams]
    kinds = {"lidar": LidarConfig, "semantic_lidar": LidarConfig, "radar": RadarConfig}
    for i, (role, name) in enumerate(_ROLES):
        value = named[role]
        if value is _UNSET:
            continue
        if value is not None and not isinstance(value, kinds[role]):
            raise ValueError(f"{role} must be a {kinds[role].__name__} or None, got {type(value).__name__}")
        if role == "semantic_lidar" and value is not None and not isinstance(value, SemanticLidarConfig):
            value = SemanticLidarConfig(**{f: getattr(value, f) for f in value.__dataclass_fields__})
        where = next((j for j, (n, _) in enumerate(out) if n == name), None)
        if where is not None:
            if value is None:
                del out[where]
            else:
                out[where] = (name, value)
        elif value is not None:  # after the cameras and the FogDrive sensors before it
            before = {n for _, n in _ROLES[:i]}
            at = max((j + 1 for j, (n, c) in enumerate(out) if isinstance(c, CameraConfig) or n in before), default=0)
            out.insert(at, (name, value))
    if extra is not None:
        pairs = []
        for e in extra:
            if not (isinstance(e, (tuple, list)) and len(e) == 2 and isinstance(e[0], str) and e[0]):
                raise ValueError(f"extra must hold (channel name, sensor config) pairs, got {e!r}")
            pairs.append(_entry(tuple(e)))
        roles = {n for _, n in _ROLES}
        out = [e for e in out if isinstance(e[1], CameraConfig) or e[0] in roles] + pairs
    return out


def rig_sensors(rig, simulation_frequency: float = 20.0, far: float = 1000.0) -> tuple:
    """Every sensor of a rig, in rig order, each built by the class registered for its config type.

    >>> from fog_gym.envs.config import RigConfig
    >>> [s.channels[0] for s in rig_sensors(RigConfig.fogdrive(cameras=["CAM_BACK"]))]
    ['CAM_BACK', 'LIDAR_TOP', 'SEM_LIDAR_TOP', 'RADAR_FRONT']
    """
    return tuple(build_sensor(name, cfg, simulation_frequency, far) for name, cfg in rig.sensors)


def rig_layout(rig) -> dict[str, ChannelSpec]:
    """The dataset layout of a rig: every sensor's channels in rig order, then the ground truth ``BBOX_3D``.

    What the recorder writes, records in the dataset (``index/channels.json`` where it is not FogDrive's own
    layout) and ``validate`` and the loaders read back. Names and folders must not clash, and a FogDrive channel
    name keeps its FogDrive storage; a clash raises :class:`ValueError` naming it.

    >>> from fog_gym.envs.config import RigConfig
    >>> rig_layout(RigConfig.fogdrive()) == FOGDRIVE_CHANNELS
    True
    """
    pairs = []
    for s in rig_sensors(rig):
        pairs += list(s.layout().items())
    pairs.append((BBOX_3D, FOGDRIVE_CHANNELS[BBOX_3D]))
    try:
        return check_layout(pairs)
    except ValueError as e:
        raise ValueError(f"rig {list(rig.names)}: {e}") from None


class PointSensors:
    """Every point sensor of a rig (every sensor but the cameras), in rig order.

    :meth:`measure` returns each sensor's points for the tick that ends at the scene's instant, in the sensor
    frame, with CARLA's semantics (see :mod:`fog_gym.sensors.lidar`); the sensors draw from one generator in rig order.
    """

    def __init__(self, rig, simulation_frequency: float = 20.0) -> None:
        self.rig = rig
        self.simulation_frequency = float(simulation_frequency)
        self.sensors = tuple(s for s in rig_sensors(rig, simulation_frequency) if not isinstance(s, CameraSensor))
        self.channels = tuple(c for s in self.sensors for c in s.channels)

    def observation_spaces(self):
        return {k: v for s in self.sensors for k, v in s.observation_spaces().items()}

    def measure(self, scene: Scene, prims: Primitives, rng: np.random.Generator, tick: int) -> dict[str, np.ndarray]:
        """Points per channel for simulation tick ``tick`` (0-based); ``prims`` exclude the ego's own body."""
        out: dict[str, np.ndarray] = {}
        for s in self.sensors:
            out.update(s.measure(scene, prims, rng, tick))
        return out

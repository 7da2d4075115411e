"""Typed, validated configuration: sensor poses, cameras, the rig and the environment.

Every dataclass validates itself in ``__post_init__`` and raises :class:`ValueError` naming the
argument and the allowed values, so bad input fails at construction before any work starts.

Example:
    >>> rig = RigConfig.fogdrive(resolution=(320, 240), cameras=("CAM_FRONT",))
    >>> rig.cameras[0].width, rig.cameras[0].pose.z
    (320, 1.2)
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

from fog_gym.camera_config import CAMERA_NAMES, FOGDRIVE_CAMERA_POSES, CameraConfig, check_sensor_name
from fog_gym.labels import LabelConfig
from fog_gym.lidar import LidarConfig, RadarConfig, SemanticLidarConfig
from fog_gym.pose import Pose
from fog_gym.pose import finite as _finite

__all__ = ["CAMERA_NAMES", "FOGDRIVE_CAMERA_POSES", "TIMES_OF_DAY", "TOWNS", "TRAFFIC_MODES", "CameraConfig", "FogDriveConfig",
           "RigConfig", "check_sensor_name", "check_traffic_mode", "parse_resolution"]  # fmt: skip

#: Towns in FogDrive order; a town's FogDrive number ``T<n>`` is its 1-based position.
TOWNS: tuple[str, ...] = ("highway", "merge", "roundabout", "intersection", "racetrack", "exit")
TIMES_OF_DAY: tuple[str, ...] = ("day", "night")
#: Allowed values of the ``traffic=`` argument of FogDrive environments.
TRAFFIC_MODES: tuple[str, ...] = ("fast", "reference")


def check_traffic_mode(traffic: str) -> str:
    """Validate a ``traffic=`` value.

    >>> check_traffic_mode("fast")
    'fast'
    >>> check_traffic_mode("numba")
    Traceback (most recent call last):
    ...
    ValueError: traffic must be one of ('fast', 'reference'), got 'numba'
    """
    if not isinstance(traffic, str) or traffic not in TRAFFIC_MODES:
        raise ValueError(f"traffic must be one of {TRAFFIC_MODES}, got {traffic!r}")
    return traffic


def parse_resolution(resolution: Any) -> tuple[int, int]:
    """Validate a ``(width, height)`` pair of positive integers."""
    try:
        w, h = resolution
    except (TypeError, ValueError):
        raise ValueError(f"resolution must be a (width, height) pair of positive integers, got {resolution!r}") from None
    for v in (w, h):
        if isinstance(v, bool) or not isinstance(v, int) or v <= 0:
            raise ValueError(f"resolution must be a (width, height) pair of positive integers, got {resolution!r}")
    return int(w), int(h)


#: The sensor names of the FogDrive point sensors, which :class:`RigConfig`'s named accessors look up.
LIDAR_NAME, SEMANTIC_LIDAR_NAME, RADAR_NAME = "LIDAR_TOP", "SEM_LIDAR_TOP", "RADAR_FRONT"
_ROLES = (("lidar", LIDAR_NAME), ("semantic_lidar", SEMANTIC_LIDAR_NAME), ("radar", RADAR_NAME))
_UNSET: Any = object()
@dataclass(frozen=True, init=False)
class RigConfig:
    """The sensor rig: one ordered sequence of named sensor configs, ``sensors=((name, config), ...)``.

    Each config's type picks its sensor class (:func:`fog_gym.sensors.sensor_class`: :class:`CameraConfig` →
    camera, :class:`~fog_gym.lidar.LidarConfig` → LiDAR, :class:`~fog_gym.lidar.SemanticLidarConfig` → semantic
    LiDAR, :class:`~fog_gym.lidar.RadarConfig` → radar, and any registered type). The env's observation, the fog
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
    from fog_gym.registry import REGISTRY, registered_type

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


@dataclass(frozen=True)
class HazardConfig:
    """Stalled vehicles ahead of the ego: a task where seeing far enough decides the episode.

    At every reset, stopped vehicles are placed on the ego's road, the first ``first`` = (min, max) metres ahead of
    the ego, each next one ``gap`` = (min, max) metres further, up to ``span`` metres ahead, each in a lane drawn
    uniformly; traffic within ``clearance`` metres of a stalled vehicle in its lane is removed. Distances and lanes
    come from the reset's seed.

    >>> HazardConfig().first, HazardConfig().gap
    ((60.0, 120.0), (70.0, 140.0))
    >>> HazardConfig(first=(50.0, 40.0))
    Traceback (most recent call last):
    ...
    ValueError: first must be (min, max) metres with 0 < min <= max, got (50.0, 40.0)
    """

    first: tuple[float, float] = (60.0, 120.0)
    gap: tuple[float, float] = (70.0, 140.0)
    span: float = 700.0
    clearance: float = 25.0

    def __post_init__(self) -> None:
        for name in ("first", "gap"):
            v = getattr(self, name)
            ok = isinstance(v, (tuple, list)) and len(v) == 2
            if ok:
                lo, hi = (_finite(name, x) for x in v)
                ok = 0 < lo <= hi
            if not ok:
                raise ValueError(f"{name} must be (min, max) metres with 0 < min <= max, got {v!r}")
            object.__setattr__(self, name, (float(v[0]), float(v[1])))
        if not _finite("span", self.span) > 0:
            raise ValueError(f"span must be > 0 metres, got {self.span!r}")
        if not _finite("clearance", self.clearance) >= 0:
            raise ValueError(f"clearance must be >= 0 metres, got {self.clearance!r}")


@dataclass(frozen=True)
class FogDriveConfig:
    """Everything that defines a FogDrive-v0 environment apart from the seed.

    ``highway_config`` is passed to the highway-env scenario on top of fog-gym's settings (for example
    ``{"vehicles_count": 30}`` or ``{"action": {"type": "ContinuousAction"}}``).

    >>> FogDriveConfig(town="roundabout", time_of_day="night").episode_steps
    200
    """

    town: str = "highway"
    time_of_day: str = "day"
    rig: RigConfig = field(default_factory=RigConfig.fogdrive)
    simulation_frequency: int = 20
    keyframe_frequency: int = 10
    episode_seconds: float = 20.0
    highway_config: Mapping[str, Any] = field(default_factory=dict)
    surface_resolution: float = 0.1  # metres per cell of the road-surface map
    far_distance: float = 1000.0  # camera far plane; sky depth, as CARLA's depth camera saturates at 1 km
    labels: LabelConfig | None = field(default_factory=lambda: _default_labels())  # None: no boxes in info
    traffic: str = "fast"  # "fast": fog_gym.traffic core; "reference": highway-env's own Python path
    hazards: HazardConfig | None = None  # stalled vehicles ahead of the ego (the RL hazard preset)

    def __post_init__(self) -> None:
        if self.town not in TOWNS:
            raise ValueError(f"town must be one of {TOWNS}, got {self.town!r}")
        check_traffic_mode(self.traffic)
        if self.hazards is not None and not isinstance(self.hazards, HazardConfig):
            raise ValueError(f"hazards must be a HazardConfig or None, got {type(self.hazards).__name__}")
        if self.time_of_day not in TIMES_OF_DAY:
            raise ValueError(f"time_of_day must be one of {TIMES_OF_DAY}, got {self.time_of_day!r}")
        if not isinstance(self.rig, RigConfig):
            raise ValueError(f"rig must be a RigConfig, got {type(self.rig).__name__}")
        for name in ("simulation_frequency", "keyframe_frequency"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v <= 0:
                raise ValueError(f"{name} must be a positive integer (Hz), got {v!r}")
        if self.simulation_frequency % self.keyframe_frequency:
            raise ValueError(
                "simulation_frequency must be a multiple of keyframe_frequency, got "
                f"{self.simulation_frequency} and {self.keyframe_frequency}"
            )
        secs = _finite("episode_seconds", self.episode_seconds)
        if secs <= 0:
            raise ValueError(f"episode_seconds must be > 0, got {self.episode_seconds!r}")
        if not isinstance(self.highway_config, Mapping):
            raise ValueError(f"highway_config must be a mapping, got {type(self.highway_config).__name__}")
        res = _finite("surface_resolution", self.surface_resolution)
        if not 0.01 <= res <= 1.0:
            raise ValueError(f"surface_resolution must lie in [0.01, 1.0] metres, got {self.surface_resolution!r}")
        far = _finite("far_distance", self.far_distance)
        if far <= 1.0:
            raise ValueError(f"far_distance must be > 1 m, got {self.far_distance!r}")

        if self.labels is not None and not isinstance(self.labels, LabelConfig):
            raise ValueError(f"labels must be a LabelConfig or None, got {type(self.labels).__name__}")
        if self.labels is not None and self.labels.visibility == "lidar" and self.rig.semantic_lidar is None:
            raise ValueError(
                "labels: visibility='lidar' (FogDrive's rule) needs the semantic LiDAR in the rig; "
                "use visibility='camera', or labels=None for no boxes"
            )

    @property
    def episode_steps(self) -> int:
        """Env steps (keyframes) per episode."""
        return int(round(self.episode_seconds * self.keyframe_frequency))

    @property
    def town_number(self) -> int:
        """FogDrive town number (``T<n>``), the 1-based position in :data:`TOWNS`."""
        return TOWNS.index(self.town) + 1


def _default_labels():

    return LabelConfig()

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

from fog_gym.labels import LabelConfig
from fog_gym.lidar import LidarConfig, RadarConfig
from fog_gym.pose import Pose
from fog_gym.pose import finite as _finite

#: FogDrive camera channel names (Table 3), in the order the rig lists them.
CAMERA_NAMES: tuple[str, ...] = ("CAM_FRONT", "CAM_BACK", "CAM_LEFT", "CAM_RIGHT")
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


@dataclass(frozen=True)
class CameraConfig:
    """One pinhole camera; RGB, depth, semantic and instance buffers share its pose and intrinsics.

    >>> CameraConfig("CAM_FRONT", Pose(1.8, 0, 1.2), 640, 480).intrinsic()[0, 0].round(2)
    np.float64(268.51)
    """

    name: str
    pose: Pose
    width: int = 1280
    height: int = 960
    fov: float = 100.0  # horizontal field of view, degrees

    def __post_init__(self) -> None:
        if self.name not in CAMERA_NAMES:
            raise ValueError(f"camera name must be one of {CAMERA_NAMES}, got {self.name!r}")
        object.__setattr__(self, "pose", Pose.coerce(self.pose))
        for attr in ("width", "height"):
            value = getattr(self, attr)
            if isinstance(value, bool) or not isinstance(value, (int,)) and not (
                isinstance(value, float) and value.is_integer()
            ):
                raise ValueError(f"resolution {attr} must be a positive integer, got {value!r}")
            if int(value) <= 0:
                raise ValueError(f"resolution {attr} must be a positive integer, got {value!r}")
            object.__setattr__(self, attr, int(value))
        fov = _finite("fov", self.fov)
        if not 0.0 < fov < 180.0:
            raise ValueError(f"fov must lie in the open interval (0, 180) degrees, got {self.fov!r}")
        object.__setattr__(self, "fov", fov)

    def intrinsic(self):
        from fog_gym.geometry import intrinsic_matrix

        return intrinsic_matrix(self.width, self.height, self.fov)


#: Camera poses of FogDrive Table 2.
FOGDRIVE_CAMERA_POSES: dict[str, Pose] = {
    "CAM_FRONT": Pose(1.8, 0.0, 1.2, 0.0, 0.0, 0.0),
    "CAM_BACK": Pose(-2.4, 0.0, 1.2, 0.0, 0.0, 180.0),
    "CAM_LEFT": Pose(0.5, -0.7, 1.5, 0.0, 0.0, -100.0),
    "CAM_RIGHT": Pose(0.5, 0.7, 1.5, 0.0, 0.0, 100.0),
}


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


@dataclass(frozen=True)
class RigConfig:
    """The sensor rig. :meth:`fogdrive` is the FogDrive preset (Table 2, supplementary D5).

    >>> [c.name for c in RigConfig.fogdrive().cameras]
    ['CAM_FRONT', 'CAM_BACK', 'CAM_LEFT', 'CAM_RIGHT']
    """

    cameras: tuple[CameraConfig, ...] = field(default_factory=tuple)
    lidar: LidarConfig | None = None  # LIDAR_TOP
    semantic_lidar: LidarConfig | None = None  # SEM_LIDAR_TOP
    radar: RadarConfig | None = None  # RADAR_FRONT
    #: Further sensors as ``(channel name, config)`` pairs; the config's type picks the sensor class
    #: (:func:`fog_gym.sensors.register`), e.g. ``(("RADAR_BACK", RadarConfig(...)),)``.
    extra: tuple[tuple[str, Any], ...] = ()

    def __post_init__(self) -> None:

        cams = tuple(self.cameras)
        for cam in cams:
            if not isinstance(cam, CameraConfig):
                raise ValueError(f"cameras must be CameraConfig instances, got {cam!r}")
        names = [c.name for c in cams]
        if len(set(names)) != len(names):
            raise ValueError(f"camera names must be unique, got {names}")
        object.__setattr__(self, "cameras", cams)
        extra = tuple(tuple(e) if isinstance(e, (tuple, list)) else e for e in self.extra)
        for e in extra:
            if not (isinstance(e, tuple) and len(e) == 2 and isinstance(e[0], str) and e[0]):
                raise ValueError(f"extra must hold (channel name, sensor config) pairs, got {e!r}")
        object.__setattr__(self, "extra", extra)
        for name, kind in (("lidar", LidarConfig), ("semantic_lidar", LidarConfig), ("radar", RadarConfig)):
            value = getattr(self, name)
            if value is not None and not isinstance(value, kind):
                raise ValueError(f"{name} must be a {kind.__name__} or None, got {type(value).__name__}")

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
        poses, or without the LiDAR, semantic LiDAR or radar."""

        w, h = parse_resolution(resolution)
        names = CAMERA_NAMES if cameras is None else tuple(cameras)
        for n in names:
            if n not in CAMERA_NAMES:
                raise ValueError(f"camera name must be one of {CAMERA_NAMES}, got {n!r}")
        poses = dict(poses or {})
        for n in poses:
            if n not in CAMERA_NAMES:
                raise ValueError(f"poses: camera name must be one of {CAMERA_NAMES}, got {n!r}")
        return cls(
            tuple(CameraConfig(n, Pose.coerce(poses.get(n, FOGDRIVE_CAMERA_POSES[n])), w, h, fov) for n in names),
            lidar=LidarConfig.fogdrive() if lidar else None,
            semantic_lidar=LidarConfig.fogdrive_semantic() if semantic_lidar else None,
            radar=RadarConfig.fogdrive() if radar else None,
        )

    def with_resolution(self, resolution: Sequence[int]) -> RigConfig:
        """The same rig with every camera at ``(width, height)`` (intrinsics scale with it)."""
        w, h = parse_resolution(resolution)
        return replace(self, cameras=tuple(replace(c, width=w, height=h) for c in self.cameras))

    def camera(self, name: str) -> CameraConfig:
        for c in self.cameras:
            if c.name == name:
                return c
        raise KeyError(name)


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

    def __post_init__(self) -> None:
        if self.town not in TOWNS:
            raise ValueError(f"town must be one of {TOWNS}, got {self.town!r}")
        check_traffic_mode(self.traffic)
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

"""The sensor protocol, the registry that maps a sensor config type to its sensor class, and sensor names.

A sensor declares everything the env and the dataset need to know about it: its channel names, its Gymnasium
observation spaces, ``measure(scene, prims, rng, tick)``, and for each channel the dataset's
:class:`~fog_gym.channels.spec.ChannelSpec` (folder, file format, encoding, column count) that the writer,
``validate`` and the loaders read. The physics stays in :mod:`fog_gym.sensors.lidar` and :mod:`fog_gym.render`.

See :func:`fog_gym.sensors.rig_sensors` for the sensors of a rig and :func:`fog_gym.sensors.rig_layout` for its
dataset layout.
"""

from __future__ import annotations

import re
from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np
from gymnasium import spaces

from fog_gym.channels.spec import ChannelSpec
from fog_gym.world.primitives import Primitives
from fog_gym.world.scene import Scene


_NAME_RE = re.compile(r"[A-Z][A-Z0-9_]*")


def check_sensor_name(name: Any) -> str:
    """A sensor (and channel) name is upper case: letters, digits, underscores, starting with a letter.

    >>> check_sensor_name("RADAR_BACK")
    'RADAR_BACK'
    >>> check_sensor_name("radar back")
    Traceback (most recent call last):
    ...
    ValueError: sensor name must be an upper-case channel name like 'RADAR_BACK', got 'radar back'
    """
    if not isinstance(name, str) or not _NAME_RE.fullmatch(name):
        raise ValueError(f"sensor name must be an upper-case channel name like 'RADAR_BACK', got {name!r}")
    return name


#: Sensor config type → sensor class (see :func:`register`).
REGISTRY: dict[type, type] = {}


def register(config_type: type):
    """Class decorator: a rig's sensors whose config is a ``config_type`` are built by the class (its ``build``)."""
    if not isinstance(config_type, type):
        raise TypeError(f"config_type must be a class, got {config_type!r}")

    def deco(cls: type) -> type:
        REGISTRY[config_type] = cls
        return cls

    return deco


def registered_type(config_type: type) -> type | None:
    """The registered config type that ``config_type`` is (itself or its nearest base along its MRO), or None."""
    for t in getattr(config_type, "__mro__", (config_type,)):
        if t in REGISTRY:
            return t
    return None


def sensor_class(config_type: type) -> type:
    """The sensor class registered for ``config_type`` (the most specific one along its MRO)."""
    t = registered_type(config_type)
    if t is None:
        names = ", ".join(sorted(t.__name__ for t in REGISTRY))
        raise ValueError(f"config type must be one of the registered sensor configs ({names}), got {config_type.__name__}")
    return REGISTRY[t]


@runtime_checkable
class Sensor(Protocol):
    """What the env, observation packing and the dataset ask of a sensor."""

    #: ``camera``, ``lidar``, ``semantic_lidar``, ``radar`` …: picks the fog model (:mod:`fog_gym.fog.models`).
    kind: ClassVar[str]
    config: Any

    @property
    def channels(self) -> tuple[str, ...]:
        """The observation keys the sensor fills; the first is the one a fog model of the sensor's kind fogs
        (a camera's RGB, a LiDAR's points)."""

    def observation_spaces(self) -> dict[str, spaces.Space]:
        """One space per channel."""

    def measure(self, scene: Scene, prims: Primitives, rng: np.random.Generator, tick: int) -> dict[str, np.ndarray]:
        """The channels' arrays for one keyframe (point sensors: exact ``(N, C)`` float32 arrays)."""

    def layout(self) -> dict[str, ChannelSpec]:
        """The dataset channels of the sensor → where and how they are stored."""

    @classmethod
    def build(cls, name: str, config: Any, simulation_frequency: float, far: float) -> Sensor:
        """The sensor of the rig entry ``(name, config)`` (what :func:`fog_gym.sensors.rig_sensors` calls)."""


def build_sensor(name: str, config: Any, simulation_frequency: float = 20.0, far: float = 1000.0):
    """The sensor ``name`` of a rig, built by the class registered for the config's type (:func:`register`).

    >>> sensor_class(object)
    Traceback (most recent call last):
    ...
    ValueError: config type must be one of the registered sensor configs (CameraConfig, LidarConfig, RadarConfig, SemanticLidarConfig), got object
    """
    return sensor_class(type(config)).build(name, config, simulation_frequency, far)


class PointSensor:
    """Base of the sensors that return a point cloud: one channel, a fixed-capacity ``Box`` observation, an
    ``.npy`` file of float32 ``(N, columns)`` in the folder :attr:`folder` (a new sensor's folder is its channel
    name in lower case)."""

    kind: ClassVar[str] = "points"
    #: The default channel name, the columns of one point and the FogDrive folder of the default channel.
    default_channel: ClassVar[str] = ""
    columns: ClassVar[int] = 0
    default_folder: ClassVar[str] = ""

    def __init__(self, config: Any, simulation_frequency: float = 20.0, channel: str | None = None) -> None:
        self.config = config
        self.simulation_frequency = float(simulation_frequency)
        self.channel = self.default_channel if channel is None else channel
        if not isinstance(self.channel, str) or not self.channel:
            raise ValueError(f"channel must be a non-empty channel name, got {channel!r}")

    @classmethod
    def build(cls, name: str, config: Any, simulation_frequency: float = 20.0, far: float = 1000.0) -> PointSensor:
        """The sensor of a rig entry ``(name, config)``: its channel is ``name``."""
        return cls(config, simulation_frequency, channel=name)

    @property
    def channels(self) -> tuple[str, ...]:
        return (self.channel,)

    @property
    def folder(self) -> str:
        return self.default_folder if self.channel == self.default_channel else self.channel.lower()

    def space(self) -> spaces.Box:
        raise NotImplementedError

    def observation_spaces(self) -> dict[str, spaces.Space]:
        return {self.channel: self.space()}

    def layout(self) -> dict[str, ChannelSpec]:
        return {self.channel: ChannelSpec(self.folder, "npy", "points", self.columns)}

    def start_angle(self, tick: int) -> float:
        """Where the head starts in tick ``tick``: a head that turns less than a full sweep per tick resumes where
        the previous tick stopped."""
        cfg = self.config
        return (tick * cfg.tick_angle(self.simulation_frequency)) % cfg.horizontal_fov

    def measure(self, scene: Scene, prims: Primitives, rng: np.random.Generator, tick: int) -> dict[str, np.ndarray]:
        raise NotImplementedError


def point_space(capacity: int, low: list[float], high: list[float]) -> spaces.Box:
    """Box of a point channel: ``capacity`` rows, each between ``low`` and ``high`` (float32)."""
    lo = np.tile(np.asarray(low, np.float32), (capacity, 1))
    hi = np.tile(np.asarray(high, np.float32), (capacity, 1))
    return spaces.Box(lo, hi, dtype=np.float32)

"""The sensor protocol and the registry that maps a sensor config type to its sensor class.

A sensor declares everything the env and the dataset need to know about it: its channel names, its Gymnasium
observation spaces, ``measure(scene, prims, rng, tick)``, and for each channel the dataset's
:class:`~fog_gym.dataset.layout.ChannelSpec` (folder, file format, encoding, column count) that the writer,
``validate`` and the loaders read. The physics stays in :mod:`fog_gym.lidar` and :mod:`fog_gym.render`.

See :func:`fog_gym.sensors.rig_sensors` for the sensors of a rig and :func:`fog_gym.sensors.rig_layout` for its
dataset layout.
"""

from __future__ import annotations

from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np
from gymnasium import spaces

from fog_gym.dataset.layout import ChannelSpec
from fog_gym.registry import REGISTRY, register, sensor_class
from fog_gym.primitives import Primitives
from fog_gym.scene import Scene


@runtime_checkable
class Sensor(Protocol):
    """What the env, observation packing and the dataset ask of a sensor."""

    #: ``camera``, ``lidar``, ``semantic_lidar``, ``radar`` …: picks the fog model (:mod:`fog_gym.fog_models`).
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

"""Sensors of the rig behind one protocol (:mod:`fog_gym.sensors.base`): one module per kind.

:mod:`~fog_gym.sensors.camera` (RGB, depth, semantic tags), :mod:`~fog_gym.sensors.lidar` (``LIDAR_TOP``),
:mod:`~fog_gym.sensors.semantic_lidar` (``SEM_LIDAR_TOP``), :mod:`~fog_gym.sensors.radar` (``RADAR_FRONT``).
A new point sensor is a :class:`~fog_gym.sensors.base.PointSensor` subclass registered for its config type
(:func:`~fog_gym.sensors.base.register`) and listed in :attr:`RigConfig.extra <fog_gym.config.RigConfig>`.

Example:
    >>> from fog_gym.config import RigConfig
    >>> sorted(PointSensors(RigConfig.fogdrive(cameras=[])).channels)
    ['LIDAR_TOP', 'RADAR_FRONT', 'SEM_LIDAR_TOP']
"""

from __future__ import annotations

import numpy as np

from fog_gym.primitives import Primitives
from fog_gym.scene import Scene
from fog_gym.dataset.layout import FOGDRIVE_CHANNELS, register_channel
from fog_gym.points import ADDED
from fog_gym.sensors.base import REGISTRY, PointSensor, Sensor, register, sensor_class
from fog_gym.sensors.camera import LIGHT_RANGE, MAX_TAG, CameraFrame, CameraRig, CameraSensor
from fog_gym.sensors.lidar import LidarSensor
from fog_gym.sensors.radar import RadarSensor
from fog_gym.sensors.semantic_lidar import SemanticLidarSensor


def rig_sensors(rig, simulation_frequency: float = 20.0) -> tuple:
    """The point sensors of a rig in observation order: ``lidar``, ``semantic_lidar``, ``radar``, then
    :attr:`RigConfig.extra`. Every sensor's channels are registered in the dataset layout.

    >>> from fog_gym.config import RigConfig
    >>> [s.channel for s in rig_sensors(RigConfig.fogdrive(cameras=[]))]
    ['LIDAR_TOP', 'SEM_LIDAR_TOP', 'RADAR_FRONT']
    """
    out = []
    for cls, cfg in ((LidarSensor, rig.lidar), (SemanticLidarSensor, rig.semantic_lidar), (RadarSensor, rig.radar)):
        if cfg is not None:
            out.append(cls(cfg, simulation_frequency))
    for name, cfg in rig.extra:
        out.append(sensor_class(type(cfg))(cfg, simulation_frequency, channel=name))
    channels = [c for s in out for c in s.channels]
    if len(set(channels)) != len(channels):
        raise ValueError(f"rig.extra: channel names must be unique across the rig, got {channels}")
    for s in out:
        for name, spec in s.layout().items():
            register_channel(name, spec)
            if spec.encoding == "points" and name not in FOGDRIVE_CHANNELS:
                ADDED.add(name)
    return tuple(out)


class PointSensors:
    """Every point sensor of a rig (``LIDAR_TOP``, ``SEM_LIDAR_TOP``, ``RADAR_FRONT``, then ``rig.extra``).

    :meth:`measure` returns each sensor's points for the tick that ends at the scene's instant, in the sensor
    frame, with CARLA's semantics (see :mod:`fog_gym.lidar`); the sensors draw from one generator in rig order.
    """

    def __init__(self, rig, simulation_frequency: float = 20.0) -> None:
        self.rig = rig
        self.simulation_frequency = float(simulation_frequency)
        self.sensors = rig_sensors(rig, simulation_frequency)
        self.channels = tuple(c for s in self.sensors for c in s.channels)

    def observation_spaces(self):
        return {k: v for s in self.sensors for k, v in s.observation_spaces().items()}

    def measure(self, scene: Scene, prims: Primitives, rng: np.random.Generator, tick: int) -> dict[str, np.ndarray]:
        """Points per channel for simulation tick ``tick`` (0-based); ``prims`` exclude the ego's own body."""
        out: dict[str, np.ndarray] = {}
        for s in self.sensors:
            out.update(s.measure(scene, prims, rng, tick))
        return out


__all__ = ["LIGHT_RANGE", "MAX_TAG", "REGISTRY", "CameraFrame", "CameraRig", "CameraSensor", "LidarSensor",
           "PointSensor", "PointSensors", "RadarSensor", "SemanticLidarSensor", "Sensor", "register", "rig_sensors",
           "sensor_class"]  # fmt: skip

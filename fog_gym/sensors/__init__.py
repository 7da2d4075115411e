"""Sensors of the rig behind one protocol (:mod:`fog_gym.sensors.base`): one module per kind.

:mod:`~fog_gym.sensors.camera` (RGB, depth, semantic tags), :mod:`~fog_gym.sensors.lidar` (``LIDAR_TOP``),
:mod:`~fog_gym.sensors.semantic_lidar` (``SEM_LIDAR_TOP``), :mod:`~fog_gym.sensors.radar` (``RADAR_FRONT``).
A rig (:class:`~fog_gym.config.RigConfig`) is a sequence of ``(name, config)``; the config's type picks the
sensor class from :data:`~fog_gym.sensors.base.REGISTRY`. A new sensor is a class registered for its config
type (:func:`~fog_gym.sensors.base.register`) and one more entry of the sequence; a new camera is a
:class:`~fog_gym.config.CameraConfig` with a name of its own.

Example:
    >>> from fog_gym.config import RigConfig
    >>> sorted(PointSensors(RigConfig.fogdrive(cameras=[])).channels)
    ['LIDAR_TOP', 'RADAR_FRONT', 'SEM_LIDAR_TOP']
"""

from __future__ import annotations

import numpy as np

from fog_gym.primitives import Primitives
from fog_gym.scene import Scene
from fog_gym.dataset.layout import BBOX_3D, FOGDRIVE_CHANNELS, ChannelSpec, check_layout
from fog_gym.sensors.base import REGISTRY, PointSensor, Sensor, build_sensor, register, sensor_class
from fog_gym.sensors.camera import LIGHT_RANGE, MAX_TAG, CameraFrame, CameraRig, CameraSensor
from fog_gym.sensors.lidar import LidarSensor
from fog_gym.sensors.radar import RadarSensor
from fog_gym.sensors.semantic_lidar import SemanticLidarSensor


def rig_sensors(rig, simulation_frequency: float = 20.0, far: float = 1000.0) -> tuple:
    """Every sensor of a rig, in rig order, each built by the class registered for its config type.

    >>> from fog_gym.config import RigConfig
    >>> [s.channels[0] for s in rig_sensors(RigConfig.fogdrive(cameras=["CAM_BACK"]))]
    ['CAM_BACK', 'LIDAR_TOP', 'SEM_LIDAR_TOP', 'RADAR_FRONT']
    """
    return tuple(build_sensor(name, cfg, simulation_frequency, far) for name, cfg in rig.sensors)


def rig_layout(rig) -> dict[str, ChannelSpec]:
    """The dataset layout of a rig: every sensor's channels in rig order, then the ground truth ``BBOX_3D``.

    What the recorder writes, records in the dataset (``index/channels.json`` where it is not FogDrive's own
    layout) and ``validate`` and the loaders read back. Names and folders must not clash, and a FogDrive channel
    name keeps its FogDrive storage; a clash raises :class:`ValueError` naming it.

    >>> from fog_gym.config import RigConfig
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
    frame, with CARLA's semantics (see :mod:`fog_gym.lidar`); the sensors draw from one generator in rig order.
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


__all__ = ["LIGHT_RANGE", "MAX_TAG", "REGISTRY", "CameraFrame", "CameraRig", "CameraSensor", "LidarSensor",
           "PointSensor", "PointSensors", "RadarSensor", "SemanticLidarSensor", "Sensor", "build_sensor", "register",
           "rig_layout", "rig_sensors", "sensor_class"]  # fmt: skip

"""Sensors: one module per kind, each with its config beside its class and its physics.

:mod:`~fog_gym.sensors.camera` (RGB, depth, semantic tags), :mod:`~fog_gym.sensors.lidar` (``LIDAR_TOP``),
:mod:`~fog_gym.sensors.semantic_lidar` (``SEM_LIDAR_TOP``), :mod:`~fog_gym.sensors.radar` (``RADAR_FRONT``), behind
one protocol (:mod:`~fog_gym.sensors.base`); the ray caster they share (:mod:`~fog_gym.sensors.raycast`), the
fixed-shape packing of point clouds in observations (:mod:`~fog_gym.channels.packing`) and the rig
(:mod:`~fog_gym.sensors.rig`); what real sensors add: camera noise and motion blur
(:mod:`~fog_gym.sensors.camera_noise`, :mod:`~fog_gym.sensors.motion_blur`, :mod:`~fog_gym.sensors.camera_effects`)
and a LiDAR sweep that takes time, with :func:`deskew` (:mod:`~fog_gym.sensors.motion`). A rig (:class:`RigConfig`) is a sequence of ``(name, config)``; the config's type
picks the sensor class from :data:`REGISTRY`. A new sensor is a class registered for its config type
(:func:`register`) and one more entry of the sequence; a new camera is a :class:`CameraConfig` with a name of its own.

Example:
    >>> sorted(PointSensors(RigConfig.fogdrive(cameras=[])).channels)
    ['LIDAR_TOP', 'RADAR_FRONT', 'SEM_LIDAR_TOP']
"""

from __future__ import annotations

from fog_gym.sensors.base import REGISTRY, PointSensor, Sensor, build_sensor, register, sensor_class
from fog_gym.sensors.camera import (CAMERA_NAMES, FOGDRIVE_CAMERA_POSES, LIGHT_RANGE, MAX_TAG, CameraConfig,
                                    CameraFrame, CameraRig, CameraSensor)  # fmt: skip
from fog_gym.sensors.camera_noise import CameraNoise
from fog_gym.sensors.lidar import LidarConfig, LidarSensor, SemanticLidarConfig
from fog_gym.sensors.motion import deskew
from fog_gym.channels.packing import pack_points, unpack_points
from fog_gym.sensors.radar import RadarConfig, RadarSensor
from fog_gym.sensors.rig import PointSensors, RigConfig, rig_layout, rig_sensors
from fog_gym.sensors.semantic_lidar import SemanticLidarSensor

__all__ = ["CAMERA_NAMES", "FOGDRIVE_CAMERA_POSES", "LIGHT_RANGE", "MAX_TAG", "REGISTRY", "CameraConfig", "CameraFrame",
           "CameraNoise", "CameraRig", "CameraSensor", "LidarConfig", "LidarSensor", "PointSensor", "PointSensors", "RadarConfig",
           "RadarSensor", "RigConfig", "SemanticLidarConfig", "SemanticLidarSensor", "Sensor", "build_sensor",
           "deskew", "pack_points", "register", "rig_layout", "rig_sensors", "sensor_class", "unpack_points"]  # fmt: skip

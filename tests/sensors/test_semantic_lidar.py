"""The semantic LiDAR sensor: six columns, FogDrive's folder, the env's sweep."""

from __future__ import annotations

import numpy as np

import fog_gym
from fog_gym.dataset.layout import FOGDRIVE_CHANNELS
from fog_gym.sensors.lidar import LidarConfig
from fog_gym.sensors import SemanticLidarSensor


def test_declares_the_fogdrive_semantic_lidar_channel():
    s = SemanticLidarSensor(LidarConfig.fogdrive_semantic())
    assert s.layout() == {"SEM_LIDAR_TOP": FOGDRIVE_CHANNELS["SEM_LIDAR_TOP"]}
    assert s.layout()["SEM_LIDAR_TOP"].columns == 6 and s.space().shape[1] == 6


def test_the_env_sweep_is_the_sensor_sweep_with_the_same_generator_state():
    env = fog_gym.FogDriveEnv(resolution=(32, 24), cameras=[], episode_seconds=0.2)
    env.reset(seed=2)
    prims = env.cameras.primitives(env.scene)
    a = env.point_sensors.measure(env.scene, prims, np.random.default_rng(7), 0)["SEM_LIDAR_TOP"]
    rng = np.random.default_rng(7)
    env.point_sensors.sensors[0].measure(env.scene, prims, rng, 0)  # the LiDAR draws first
    b = env.point_sensors.sensors[1].measure(env.scene, prims, rng, 0)["SEM_LIDAR_TOP"]
    np.testing.assert_array_equal(a, b)
    env.close()

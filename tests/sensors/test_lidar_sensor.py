"""The LiDAR sensor: channel, fog variants and layout; measure within its space; the head's resume angle."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import fog_gym
from fog_gym.dataset.layout import FOGDRIVE_CHANNELS
from fog_gym.dataset.packing import pack_points
from fog_gym.sensors.lidar import LidarConfig
from fog_gym.sensors import LidarSensor, sensor_class


def test_fogdrive_lidar_declares_its_fogdrive_channels_and_fog_variants():
    layout = LidarSensor(LidarConfig.fogdrive()).layout()
    assert sorted(layout) == ["LIDAR_TOP", "LIDAR_TOP_FOG_DENSE", "LIDAR_TOP_FOG_LIGHT", "LIDAR_TOP_FOG_MODERATE"]
    assert all(FOGDRIVE_CHANNELS[k] == v for k, v in layout.items())


def test_a_second_lidar_is_stored_under_its_own_name():
    s = LidarSensor(LidarConfig.fogdrive(), channel="LIDAR_REAR")
    assert s.layout()["LIDAR_REAR"].folder == "lidar_rear"
    assert s.layout()["LIDAR_REAR_FOG_DENSE"].folder == "lidar_rear_fog_dense"
    assert sensor_class(LidarConfig) is LidarSensor


def test_start_angle_resumes_where_the_previous_tick_stopped():
    cfg = LidarConfig.fogdrive()
    s = LidarSensor(cfg, 20.0)
    step = cfg.tick_angle(20.0)
    assert s.start_angle(0) == 0.0
    assert s.start_angle(3) == pytest.approx((3 * step) % cfg.horizontal_fov)


def test_measure_returns_points_inside_the_space():
    env = fog_gym.FogDriveEnv(resolution=(32, 24), cameras=[], episode_seconds=0.2)
    env.reset(seed=1)
    s = LidarSensor(replace(LidarConfig.fogdrive(), channels=16), 20.0)
    pts = s.measure(env.scene, env.cameras.primitives(env.scene), np.random.default_rng(0), 0)["LIDAR_TOP"]
    space = s.space()
    assert pts.dtype == np.float32 and pts.shape[1] == 4 and 0 < len(pts) <= space.shape[0]
    assert space.contains(pack_points(pts, space.shape[0]))
    env.close()


def test_a_channel_name_must_be_a_non_empty_string():
    with pytest.raises(ValueError, match="channel must be"):
        LidarSensor(LidarConfig.fogdrive(), channel="")

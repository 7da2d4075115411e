"""The radar sensor: FogDrive's channel and folder, registry entry, detections inside the space."""

from __future__ import annotations

import fog_gym
from fog_gym.dataset.layout import FOGDRIVE_CHANNELS
from fog_gym.sensors.radar import RadarConfig
from fog_gym.sensors import RadarSensor, sensor_class


def test_declares_the_fogdrive_radar_channel():
    s = RadarSensor(RadarConfig.fogdrive())
    assert s.layout() == {"RADAR_FRONT": FOGDRIVE_CHANNELS["RADAR_FRONT"]}
    assert sensor_class(RadarConfig) is RadarSensor and s.kind == "radar"


def test_env_radar_detections_lie_in_the_space():
    env = fog_gym.FogDriveEnv(resolution=(32, 24), cameras=[], episode_seconds=0.2)
    obs, _ = env.reset(seed=0)
    pts = env.points["RADAR_FRONT"]
    assert pts.shape[1] == 4 and (pts[:, 3] > 0).all()
    assert env.observation_space["RADAR_FRONT"].contains(obs["RADAR_FRONT"])
    env.close()

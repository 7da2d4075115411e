"""The camera sensor: channels, spaces and dataset layout from its config; measure is the rig's render."""

from __future__ import annotations

import numpy as np
import pytest

import fog_gym
from fog_gym.sensors.rig import RigConfig
from fog_gym.dataset.layout import FOG_LEVELS, FOGDRIVE_CHANNELS
from fog_gym.sensors import CameraSensor


def test_fogdrive_cameras_declare_exactly_the_fogdrive_camera_channels():
    for cam in RigConfig.fogdrive(resolution=(32, 24)).cameras:
        layout = CameraSensor(cam).layout()
        assert len(layout) == 4 + len(FOG_LEVELS)  # rgb, fog levels, depth, seg, bbox
        assert all(FOGDRIVE_CHANNELS[k] == v for k, v in layout.items())


def test_spaces_follow_resolution_and_far_distance():
    cam = RigConfig.fogdrive(resolution=(40, 30)).cameras[0]
    sp = CameraSensor(cam, far=500.0).observation_spaces()
    assert sp["CAM_FRONT"].shape == (30, 40, 3) and sp["CAM_FRONT"].dtype == np.uint8
    assert sp["CAM_FRONT_DEPTH"].high.max() == 500.0 and sp["CAM_FRONT_SEM"].dtype == np.uint8


def test_measure_equals_the_batched_rig_render():
    env = fog_gym.FogDriveEnv(resolution=(32, 24), cameras=["CAM_FRONT", "CAM_LEFT"], episode_seconds=0.2)
    obs, _ = env.reset(seed=0)
    prims = env.cameras.primitives(env.scene)
    out = CameraSensor(env.config.rig.camera("CAM_LEFT"), far=env.config.far_distance).measure(env.scene, prims, None, 0)
    for k in ("CAM_LEFT", "CAM_LEFT_DEPTH", "CAM_LEFT_SEM"):
        np.testing.assert_array_equal(out[k], obs[k])
    env.close()


def test_a_camera_sensor_needs_a_camera_config():
    with pytest.raises(TypeError, match="config must be a CameraConfig"):
        CameraSensor("CAM_FRONT")

"""The observation wrappers (``SelectKeys``, ``ResizeCameras``, ``LidarBEV``, ``StackFrames``) compose to the RL
preset's spaces."""

import gymnasium as gym
import numpy as np
import pytest

from fog_gym.wrappers import LidarBEV, ResizeCameras, SelectKeys, StackFrames


def test_observation_wrappers_compose():
    base = gym.make("FogDrive-v0", fog="light", resolution=(80, 60), cameras=["CAM_FRONT", "CAM_BACK"])
    env = StackFrames(SelectKeys(LidarBEV(ResizeCameras(base, (40, 30), grayscale=True), size=16), ["CAM_FRONT", "LIDAR_BEV"]), 3)
    obs, _ = env.reset(seed=0)
    assert obs["CAM_FRONT"].shape == (3, 30, 40) and obs["LIDAR_BEV"].shape == (6, 16, 16)
    assert env.observation_space.contains(obs)
    obs2, *_ = env.step(1)
    assert env.observation_space.contains(obs2)
    np.testing.assert_array_equal(obs2["CAM_FRONT"][:2], obs["CAM_FRONT"][1:])  # oldest frame dropped
    single = SelectKeys(ResizeCameras(base, (20, 20)), ["CAM_FRONT"], single=True)
    assert single.observation_space.shape == (3, 20, 20)
    with pytest.raises(ValueError, match="keys must name observation keys"):
        SelectKeys(base, ["CAM_TOP"])
    with pytest.raises(ValueError, match="k must be an integer"):
        StackFrames(base, 0)

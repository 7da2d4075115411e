"""``FogWrapper``: calibrated fog on the env's cameras and LiDAR, in place or paired, at construction and in vector
envs."""

import math

import gymnasium as gym
import numpy as np
import pytest

import fog_gym
from fog_gym.fog import parse_fog
from fog_gym.wrappers import FogWrapper

from tests.conftest import first_idle

KW = dict(town="highway", resolution=(96, 72))


@pytest.mark.parametrize("bad", ["fog", "heavy", 0, -5, math.nan, True, ["light", "light"], [], ["clear"]])
def test_bad_fog_fails_at_construction(bad):
    with pytest.raises(ValueError, match="fog"):
        gym.make("FogDrive-v0", fog=bad, resolution=(8, 6))


def test_fog_env_sky_is_airlight_and_contrast_falls():
    clean_env = gym.make("FogDrive-v0", **KW)
    clean, _ = clean_env.reset(seed=4)
    stds = [clean["CAM_FRONT"].astype(float).std()]
    for level in ("light", "moderate", "dense"):
        env = gym.make("FogDrive-v0", fog=level, **KW)
        obs, info = env.reset(seed=4)
        assert info["fog"] == {"visibility_m": fog_gym.fog.FOG_PRESETS[level], "alpha": parse_fog(level).alpha}
        wrapper = env.get_wrapper_attr("airlight")
        sky = clean["CAM_FRONT_SEM"] == 11
        assert np.abs(obs["CAM_FRONT"][sky].astype(float) - wrapper["CAM_FRONT"]).max() <= 1.0
        stds.append(obs["CAM_FRONT"].astype(float).std())
        for key in ("CAM_FRONT_DEPTH", "CAM_FRONT_SEM", "SEM_LIDAR_TOP", "RADAR_FRONT"):
            assert obs[key].tobytes() == clean[key].tobytes()  # ground-truth channels untouched
        assert obs["LIDAR_TOP"].tobytes() != clean["LIDAR_TOP"].tobytes()
        assert len(fog_gym.unpack_points(obs, "LIDAR_TOP")) == len(fog_gym.unpack_points(clean, "LIDAR_TOP"))
    assert stds == sorted(stds, reverse=True)


def test_clear_wrapper_returns_clean_bit_for_bit():
    a = gym.make("FogDrive-v0", **KW)
    b = gym.make("FogDrive-v0", fog="clear", **KW)
    oa, _ = a.reset(seed=2)
    ob, info = b.reset(seed=2)
    assert info["fog"]["visibility_m"] == math.inf and info["fog"]["alpha"] == 0.0
    for k in oa:
        assert oa[k].tobytes() == ob[k].tobytes()


def test_in_place_and_paired_are_identical():
    inplace = gym.make("FogDrive-v0", fog="dense", **KW)
    paired = gym.make("FogDrive-v0", fog=["light", "moderate", "dense"], **KW)
    assert inplace.observation_space == gym.make("FogDrive-v0", **KW).observation_space
    assert "CAM_LEFT_FOG_MODERATE" in paired.observation_space.spaces and "LIDAR_TOP_FOG_LIGHT" in paired.observation_space.spaces
    a, _ = inplace.reset(seed=9)
    b, info = paired.reset(seed=9)
    assert set(info["fog"]) == {"light", "moderate", "dense"}
    for _ in range(2):
        for cam in fog_gym.CAMERA_NAMES:
            assert a[cam].tobytes() == b[f"{cam}_FOG_DENSE"].tobytes()
        assert a["LIDAR_TOP"].tobytes() == b["LIDAR_TOP_FOG_DENSE"].tobytes()
        assert paired.observation_space.contains(b)
        a = inplace.step(first_idle(inplace.action_space))[0]
        b = paired.step(first_idle(paired.action_space))[0]


def test_set_fog_applies_from_next_reset_and_night_airlight_comes_from_the_lit_scene():
    from fog_gym.fog import night_airlight

    env = FogWrapper(fog_gym.FogDriveEnv(time_of_day="night", **KW), "light")
    env.reset(seed=0)
    clean = env.unwrapped.frames["CAM_FRONT"]
    np.testing.assert_array_equal(env.airlight["CAM_FRONT"], night_airlight(clean.rgb, clean.depth))
    assert max(env.airlight["CAM_FRONT"]) < 200  # lit fog, not a daylight sky
    env.set_fog(50)
    _, _, _, _, info = env.step(first_idle(env.action_space))
    assert info["fog"]["visibility_m"] == 160.0
    _, info = env.reset()
    assert info["fog"]["visibility_m"] == 50.0
    with pytest.raises(ValueError):
        env.set_fog(-1)


def test_fog_wrapper_in_async_vector_env():
    envs = gym.make_vec("FogDrive-v0", num_envs=2, vectorization_mode="async", fog="moderate", resolution=(32, 24))
    try:
        envs.reset(seed=[0, 1])
        envs.call("set_fog", "dense")
        _, info = envs.reset()
        assert np.all(info["fog"]["visibility_m"] == 50.0)
    finally:
        envs.close()

"""Fog fields on FogDrive-v0 through FogWrapper: paired channels beside level names, the fields' ground truth
(transmittance along each box's ray), radar untouched, the same output for the same seed, and clear errors where a
field is not supported yet."""

import numpy as np
import pytest

from fog_gym.dataset.packing import unpack_points
from fog_gym.envs.fogdrive import FogDriveEnv
from fog_gym.fog.fields import FogBank, HeightFog, field_from_info
from fog_gym.wrappers import FogWrapper

FIELDS = ["light", FogBank(50.0, 40.0, 1000.0, edge=0.0, name="bank"), HeightFog(50.0, 3.0, name="ground"),
          FogBank(50.0, -5000.0, 10000.0, edge=0.0, name="everywhere")]  # fmt: skip


@pytest.fixture(scope="module")
def paired():
    env = FogWrapper(FogDriveEnv(town="highway", resolution=(320, 240)), FIELDS + ["dense"])
    obs, info = env.reset(seed=0)
    yield env, obs, info
    env.close()


def test_fields_sit_beside_level_names_as_paired_channels_and_describe_themselves(paired):
    env, obs, info = paired
    assert {"CAM_FRONT_FOG_BANK", "LIDAR_TOP_FOG_GROUND", "CAM_BACK_FOG_LIGHT"} <= set(obs)
    assert field_from_info(info["fog"]["bank"]) == FIELDS[1]
    assert info["fog"]["light"]["visibility_m"] == 160.0


def test_a_bank_everywhere_is_the_dense_level_and_the_road_before_a_bank_is_clear(paired):
    env, obs, info = paired
    for cam in ("CAM_FRONT", "CAM_LEFT"):
        diff = np.abs(obs[f"{cam}_FOG_EVERYWHERE"].astype(int) - obs[f"{cam}_FOG_DENSE"])
        assert diff.max() <= 1
    clean = unpack_points(obs, "LIDAR_TOP")
    dense, everywhere = unpack_points(obs, "LIDAR_TOP_FOG_DENSE"), unpack_points(obs, "LIDAR_TOP_FOG_EVERYWHERE")
    assert np.array_equal(np.any(dense[:, :3] != clean[:, :3], 1), np.any(everywhere[:, :3] != clean[:, :3], 1))
    bank = unpack_points(obs, "LIDAR_TOP_FOG_BANK")
    ahead = clean[:, 0] < 38.0  # the LiDAR frame at reset is the field frame: u = x
    assert np.array_equal(bank[ahead], clean[ahead])


def test_box_transmittance_follows_each_fields_optical_depth(paired):
    env, obs, info = paired
    b3 = info["boxes_3d"]
    t = b3["transmittance"]
    assert np.allclose(t["everywhere"], t["dense"], rtol=1e-9)
    centre_u = np.asarray(b3["center"])[:, 0]
    assert np.all(t["bank"][centre_u < 39.0] == 1.0) and np.all(t["bank"][centre_u > 41.0] < 1.0)
    assert np.all((t["ground"] > 0.0) & (t["ground"] < 1.0))
    for cam, b in info["boxes_2d"].items():
        assert np.allclose(b["transmittance"]["everywhere"], b["transmittance"]["dense"], rtol=1e-9), cam


def test_radar_is_the_same_in_every_field_and_the_same_seed_gives_the_same_fog():
    a = FogWrapper(FogDriveEnv(town="merge", resolution=(160, 120)), FogBank(30.0, 20.0, 60.0))
    b = FogWrapper(FogDriveEnv(town="merge", resolution=(160, 120)), HeightFog(30.0, 2.0))
    c = FogWrapper(FogDriveEnv(town="merge", resolution=(160, 120)), "dense")
    outs = [env.reset(seed=3)[0] for env in (a, b, c)]
    assert all(np.array_equal(o["RADAR_FRONT"], outs[0]["RADAR_FRONT"]) for o in outs)
    again = a.reset(seed=3)[0]
    assert all(np.array_equal(again[k], outs[0][k]) for k in ("CAM_FRONT", "LIDAR_TOP"))
    for env in (a, b, c):
        env.close()

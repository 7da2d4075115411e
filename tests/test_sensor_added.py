"""Adding a sensor is one class: a rear radar defined here is observed, recorded, validated and read back."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pytest

import fog_gym
from fog_gym.config import RigConfig
from fog_gym.dataset import FogDrive
from fog_gym.dataset.decode import load_channel
from fog_gym.dataset.layout import CHANNELS, FOGDRIVE_CHANNELS, unregister_channel
from fog_gym.dataset.validate import validate
from fog_gym.lidar import RadarConfig
from fog_gym.points import ADDED
from fog_gym.pose import Pose
from fog_gym.sensors import REGISTRY, RadarSensor, register
from fog_gym.wrappers import RecordFogDrive


@dataclass(frozen=True)
class RearRadarConfig(RadarConfig):
    """A radar config type of its own, so the registry picks :class:`RearRadar` for it."""


class RearRadar(RadarSensor):
    """The new sensor: the radar physics, stored in ``radar_back/``."""

    kind = "rear_radar"  # no fog model for this kind: its data stay clean


@pytest.fixture
def rear_radar():
    register(RearRadarConfig)(RearRadar)
    cfg = RearRadarConfig(**{**vars(RadarConfig.fogdrive()), "pose": Pose(-2.0, 0.0, 1.0, yaw=180.0)})
    yield cfg
    REGISTRY.pop(RearRadarConfig, None)
    unregister_channel("RADAR_BACK")
    ADDED.discard("RADAR_BACK")


def _rig(cfg) -> RigConfig:
    return replace(RigConfig.fogdrive(resolution=(32, 24)), extra=(("RADAR_BACK", cfg),))


def test_an_added_sensor_is_observed_with_its_own_space(rear_radar):
    env = fog_gym.FogDriveEnv(rig=_rig(rear_radar), episode_seconds=0.2)
    obs, _ = env.reset(seed=3)
    assert env.observation_space["RADAR_BACK"] == env.observation_space["RADAR_FRONT"]
    assert env.observation_space.contains(obs)
    assert CHANNELS["RADAR_BACK"] == ("radar_back", "npy", "points", 4)
    back = fog_gym.unpack_points(obs, "RADAR_BACK")
    np.testing.assert_array_equal(back, env.points["RADAR_BACK"])
    env.close()


def test_an_added_sensor_leaves_the_fogdrive_channels_byte_identical(rear_radar):
    plain = fog_gym.FogDriveEnv(resolution=(32, 24), episode_seconds=0.2)
    extra = fog_gym.FogDriveEnv(rig=_rig(rear_radar), episode_seconds=0.2)
    a, _ = plain.reset(seed=5)
    b, _ = extra.reset(seed=5)
    assert set(b) - set(a) == {"RADAR_BACK"}
    for k in a:  # the added sensor draws after the FogDrive ones, so their noise is unchanged
        np.testing.assert_array_equal(a[k], b[k], err_msg=k)


def test_a_recorded_set_with_an_added_sensor_validates_and_reads_back_exactly(rear_radar, tmp_path):
    env = RecordFogDrive(fog_gym.FogDriveEnv(rig=_rig(rear_radar), episode_seconds=0.2), tmp_path)
    sweeps = []
    _, _ = env.reset(seed=1)
    sweeps.append(env.unwrapped.points["RADAR_BACK"].copy())
    for _ in range(2):
        env.step(1)
        sweeps.append(env.unwrapped.points["RADAR_BACK"].copy())
    env.close()
    # a three-sample set cannot meet the split shares (validate's dataset-level rule); every file rule holds
    assert [p for p in validate(tmp_path) if not p.startswith("splits:")] == []
    ds = FogDrive(tmp_path)
    assert len(ds.sample) == 3
    recs = sorted((r for r in ds.sample_data if r["channel"] == "RADAR_BACK"), key=lambda r: r["filename"])
    assert [r["filename"].split("/")[-2] for r in recs] == ["radar_back"] * 3
    for rec, sweep in zip(recs, sweeps):
        np.testing.assert_array_equal(load_channel("RADAR_BACK", tmp_path / rec["filename"]), sweep)
    assert {r["channel"] for r in ds.sample_data} == set(FOGDRIVE_CHANNELS) | {"RADAR_BACK"}


def test_validation_applies_the_added_sensors_column_rule(rear_radar, tmp_path):
    env = RecordFogDrive(fog_gym.FogDriveEnv(rig=_rig(rear_radar), episode_seconds=0.2), tmp_path)
    env.reset(seed=2)
    env.step(1)
    env.close()
    victim = sorted((tmp_path / "data_root").glob("*/radar_back/000001.npy"))[0]
    np.save(victim, np.zeros((3, 5), np.float32))  # a wrong column count
    assert any("radar_back/000001.npy" in p for p in validate(tmp_path))


def test_an_unregistered_config_type_is_refused_before_any_work():
    @dataclass(frozen=True)
    class Unknown:
        pass

    with pytest.raises(ValueError, match="registered sensor configs"):
        fog_gym.FogDriveEnv(rig=replace(RigConfig.fogdrive(resolution=(32, 24)), extra=(("X_TOP", Unknown()),)))


def test_an_extra_entry_must_be_a_name_and_config_pair():
    with pytest.raises(ValueError, match="extra must hold"):
        RigConfig.fogdrive(resolution=(32, 24)).__class__(extra=(RadarConfig.fogdrive(),))

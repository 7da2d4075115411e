"""The sensor protocol, its registry and the channel table it feeds: conformance and clear errors."""

from __future__ import annotations

import pytest

from fog_gym.config import RigConfig
from fog_gym.dataset.layout import CHANNELS, FOGDRIVE_CHANNELS, ChannelSpec, register_channel, unregister_channel
from fog_gym.lidar import LidarConfig, RadarConfig
from fog_gym.sensors import CameraSensor, LidarSensor, RadarSensor, SemanticLidarSensor, Sensor, register, rig_sensors


def test_every_built_in_sensor_satisfies_the_protocol():
    rig = RigConfig.fogdrive(resolution=(32, 24))
    sensors = [CameraSensor(rig.cameras[0]), LidarSensor(LidarConfig.fogdrive()),
               SemanticLidarSensor(LidarConfig.fogdrive_semantic()), RadarSensor(RadarConfig.fogdrive())]  # fmt: skip
    assert all(isinstance(s, Sensor) for s in sensors)
    assert [s.kind for s in sensors] == ["camera", "lidar", "semantic_lidar", "radar"]


def test_the_fogdrive_rig_declares_exactly_the_35_fogdrive_channels():
    rig = RigConfig.fogdrive(resolution=(32, 24))
    declared = {k: v for c in rig.cameras for k, v in CameraSensor(c).layout().items()}
    for s in rig_sensors(rig):
        declared.update(s.layout())
    declared["BBOX_3D"] = FOGDRIVE_CHANNELS["BBOX_3D"]  # ground truth, not a sensor
    assert declared == FOGDRIVE_CHANNELS and len(declared) == 35


def test_register_needs_a_class():
    with pytest.raises(TypeError, match="config_type must be a class"):
        register("RadarConfig")


@pytest.mark.parametrize(
    ("name", "spec", "match"),
    [
        ("radar_back", ChannelSpec("radar_back", "npy", "points", 4), "upper-case channel name"),
        ("RADAR_BACK", ChannelSpec("radar_back", "png", "points", 4), "encoding/format pair"),
        ("RADAR_BACK", ChannelSpec("radar_back", "npy", "points", 0), "columns must be > 0"),
        ("CAM_EXTRA", ChannelSpec("cam_extra", "png", "rgb", 3), "columns must be > 0 for a point channel and 0"),
        ("RADAR_BACK", ChannelSpec("radar", "npy", "points", 4), "already used"),
    ],
)
def test_register_channel_refuses_bad_specs_before_changing_the_table(name, spec, match):
    before = dict(CHANNELS)
    with pytest.raises(ValueError, match=match):
        register_channel(name, spec)
    assert CHANNELS == before


def test_fogdrive_channels_cannot_be_unregistered():
    with pytest.raises(ValueError, match="must not be a FogDrive channel"):
        unregister_channel("LIDAR_TOP")

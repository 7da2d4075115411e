"""The sensor protocol, its registry and the dataset layout a rig derives from it: conformance and clear errors."""

from __future__ import annotations

import pytest

from fog_gym.sensors.rig import RigConfig
from fog_gym.dataset.layout import FOGDRIVE_CHANNELS, ChannelSpec, check_layout
from fog_gym.sensors.lidar import LidarConfig
from fog_gym.sensors.radar import RadarConfig
from fog_gym.sensors import (CameraSensor, LidarSensor, RadarSensor, SemanticLidarSensor, Sensor, register, rig_layout,
                             rig_sensors)  # fmt: skip


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


def test_the_fogdrive_rig_layout_is_the_fogdrive_channel_table_in_its_order():
    layout = rig_layout(RigConfig.fogdrive(resolution=(32, 24)))
    assert list(layout.items()) == list(FOGDRIVE_CHANNELS.items())


def test_every_built_in_config_type_picks_its_sensor_class():
    rig = RigConfig.fogdrive(resolution=(32, 24), cameras=["CAM_LEFT"])
    assert [type(s) for s in rig_sensors(rig)] == [CameraSensor, LidarSensor, SemanticLidarSensor, RadarSensor]
    assert [s.channels[0] for s in rig_sensors(rig)] == list(rig.names)


@pytest.mark.parametrize(
    ("name", "spec", "match"),
    [
        ("radar_back", ChannelSpec("radar_back", "npy", "points", 4), "upper-case channel name"),
        ("RADAR_BACK", ChannelSpec("radar_back", "png", "points", 4), "encoding/format pair"),
        ("RADAR_BACK", ChannelSpec("radar_back", "npy", "points", 0), "columns must be > 0"),
        ("CAM_EXTRA", ChannelSpec("cam_extra", "png", "rgb", 3), "columns must be > 0 for a point channel and 0"),
        ("RADAR_BACK", ChannelSpec("radar", "npy", "points", 4), "already used by 'RADAR_FRONT'"),
        ("RADAR_FRONT", ChannelSpec("radar_front", "npy", "points", 4), "is a FogDrive channel stored as"),
    ],
)
def test_check_layout_refuses_bad_specs_and_clashes_with_fogdrive(name, spec, match):
    with pytest.raises(ValueError, match=match):
        check_layout([(name, spec)])


def test_check_layout_refuses_a_channel_or_folder_declared_twice():
    spec = ChannelSpec("radar_back", "npy", "points", 4)
    with pytest.raises(ValueError, match="declared twice"):
        check_layout([("RADAR_BACK", spec), ("RADAR_BACK", spec)])
    with pytest.raises(ValueError, match="already used by 'RADAR_BACK'"):
        check_layout([("RADAR_BACK", spec), ("RADAR_REAR", spec)])

"""Adding a sensor is one class plus one rig entry: a rear radar defined here, and a second front camera, are
observed, fogged, labelled, recorded, validated and read back, with the layout carried by the dataset."""

from __future__ import annotations

import json
from dataclasses import dataclass, replace

import numpy as np
import pytest

import fog_gym
from fog_gym.sensors.camera import CameraConfig
from fog_gym.sensors.rig import RigConfig
from fog_gym.dataset import FogDrive
from fog_gym.dataset.decode import load_channel
from fog_gym.dataset.torch import load_sample
from fog_gym.dataset.layout import FOGDRIVE_CHANNELS, LAYOUT_FILE
from fog_gym.dataset.validate import validate
from fog_gym.sensors.radar import RadarConfig
from fog_gym.geometry import Pose
from fog_gym.sensors import REGISTRY, RadarSensor, register, rig_layout
from fog_gym.wrappers import FogWrapper, RecordFogDrive


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


def _rig(cfg) -> RigConfig:
    return RigConfig.fogdrive(resolution=(32, 24)).with_sensor("RADAR_BACK", cfg)


def test_an_added_sensor_is_observed_with_its_own_space(rear_radar):
    env = fog_gym.FogDriveEnv(rig=_rig(rear_radar), episode_seconds=0.2)
    obs, _ = env.reset(seed=3)
    assert env.observation_space["RADAR_BACK"] == env.observation_space["RADAR_FRONT"]
    assert env.observation_space.contains(obs)
    assert rig_layout(_rig(rear_radar))["RADAR_BACK"] == ("radar_back", "npy", "points", 4)
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
        np.testing.assert_array_equal(load_channel("RADAR_BACK", tmp_path / rec["filename"], ds.channels["RADAR_BACK"]), sweep)
    assert {r["channel"] for r in ds.sample_data} == set(FOGDRIVE_CHANNELS) | {"RADAR_BACK"}
    assert ds.channels == rig_layout(_rig(rear_radar))  # the set carries its rig's layout (index/channels.json)


def test_a_recorded_set_reads_back_without_the_sensor_class_registered(rear_radar, tmp_path):
    env = RecordFogDrive(fog_gym.FogDriveEnv(rig=_rig(rear_radar), episode_seconds=0.1), tmp_path)
    env.reset(seed=4)
    sweep = env.unwrapped.points["RADAR_BACK"].copy()
    env.close()
    REGISTRY.pop(RearRadarConfig)  # another process, without the sensor's module: the layout is in the set
    assert [p for p in validate(tmp_path) if not p.startswith("splits:")] == []
    ds = FogDrive(tmp_path)
    rec = next(r for r in ds.sample_data if r["channel"] == "RADAR_BACK")
    np.testing.assert_array_equal(load_channel("RADAR_BACK", tmp_path / rec["filename"], ds.channels["RADAR_BACK"]), sweep)


def test_validation_applies_the_added_sensors_column_rule(rear_radar, tmp_path):
    env = RecordFogDrive(fog_gym.FogDriveEnv(rig=_rig(rear_radar), episode_seconds=0.2), tmp_path)
    env.reset(seed=2)
    env.step(1)
    env.close()
    victim = sorted((tmp_path / "data_root").glob("*/radar_back/000001.npy"))[0]
    np.save(victim, np.zeros((3, 5), np.float32))  # a wrong column count
    assert any("radar_back/000001.npy" in p for p in validate(tmp_path))


def test_an_unregistered_config_type_is_refused_when_the_rig_is_built():
    @dataclass(frozen=True)
    class Unknown:
        pass

    with pytest.raises(ValueError, match="'X_TOP': config type must be one of the registered sensor configs"):
        RigConfig.fogdrive(resolution=(32, 24)).with_sensor("X_TOP", Unknown())
    with pytest.raises(ValueError, match="registered sensor configs"):  # the pre-sequence keyword too
        replace(RigConfig.fogdrive(resolution=(32, 24)), extra=(("X_TOP", Unknown()),))


def test_an_extra_entry_must_be_a_name_and_config_pair():
    with pytest.raises(ValueError, match="extra must hold"):
        RigConfig(extra=(RadarConfig.fogdrive(),))


def test_the_pre_sequence_extra_keyword_appends_to_the_sequence(rear_radar):
    assert replace(RigConfig.fogdrive(resolution=(32, 24)), extra=(("RADAR_BACK", rear_radar),)) == _rig(rear_radar)


def test_a_sensor_whose_channel_folder_clashes_is_refused_before_any_work(rear_radar):
    class Squatter(RadarSensor):
        @property
        def folder(self):
            return "lidar"  # LIDAR_TOP's folder

    register(RearRadarConfig)(Squatter)
    with pytest.raises(ValueError, match="folder 'lidar' of channel 'RADAR_BACK' is already used by 'LIDAR_TOP'"):
        fog_gym.FogDriveEnv(rig=_rig(rear_radar), episode_seconds=0.1)


# -- an added camera: one CameraConfig with a name of its own -------------------------------------------------
NARROW = "CAM_FRONT_NARROW"


def _narrow_rig(resolution=(32, 24)) -> RigConfig:
    narrow = CameraConfig(NARROW, Pose(1.8, 0.0, 1.3), *resolution, fov=40.0)
    return RigConfig.fogdrive(resolution=resolution).with_sensor(NARROW, narrow)


def test_an_added_camera_is_observed_labelled_and_fogged_like_the_fogdrive_ones():
    env = FogWrapper(fog_gym.FogDriveEnv(rig=_narrow_rig(), episode_seconds=0.2), ["dense"])
    obs, info = env.reset(seed=2)
    assert env.observation_space.contains(obs)
    for suffix, shape in (("", (24, 32, 3)), ("_DEPTH", (24, 32)), ("_SEM", (24, 32)), ("_FOG_DENSE", (24, 32, 3))):
        assert obs[NARROW + suffix].shape == shape
    assert not np.array_equal(obs[NARROW], obs[f"{NARROW}_FOG_DENSE"])  # the camera fog model applies to it
    base = env.unwrapped
    np.testing.assert_allclose(base.intrinsics[NARROW][0, 0], 16.0 / np.tan(np.radians(20.0)))  # f = (W/2)/tan(fov/2)
    assert set(info["boxes_2d"]) == {*fog_gym.CAMERA_NAMES, NARROW}
    narrow_ids = set(info["boxes_2d"][NARROW]["vehicle_ids"].tolist())
    assert narrow_ids and narrow_ids <= set(info["boxes_2d"]["CAM_FRONT"]["vehicle_ids"].tolist())  # 40° inside 100°
    assert "extrinsic_front_narrow" in info["extrinsics"]
    env.close()


def test_an_added_camera_leaves_the_fogdrive_channels_byte_identical():
    plain = fog_gym.FogDriveEnv(resolution=(32, 24), episode_seconds=0.2)
    extra = fog_gym.FogDriveEnv(rig=_narrow_rig(), episode_seconds=0.2)
    a, ia = plain.reset(seed=6)
    b, ib = extra.reset(seed=6)
    assert set(b) - set(a) == {NARROW, f"{NARROW}_DEPTH", f"{NARROW}_SEM"}
    for k in a:
        np.testing.assert_array_equal(a[k], b[k], err_msg=k)
    np.testing.assert_array_equal(ia["boxes_2d"]["CAM_FRONT"]["bboxes"], ib["boxes_2d"]["CAM_FRONT"]["bboxes"])


def test_a_recorded_set_with_an_added_camera_validates_and_loads_with_its_shape_and_boxes(tmp_path):
    env = RecordFogDrive(fog_gym.FogDriveEnv(rig=_narrow_rig(), episode_seconds=0.2), tmp_path)
    boxes, images = [], []
    _, info = env.reset(seed=1)
    boxes.append(info["boxes_2d"][NARROW]["bboxes"].copy())
    images.append(env.unwrapped.frames[NARROW].rgb.copy())
    for _ in range(2):
        _, _, _, _, info = env.step(1)
        boxes.append(info["boxes_2d"][NARROW]["bboxes"].copy())
        images.append(env.unwrapped.frames[NARROW].rgb.copy())
    env.close()
    assert sum(len(b) for b in boxes) > 0
    assert [p for p in validate(tmp_path) if not p.startswith("splits:")] == []
    assert (tmp_path / LAYOUT_FILE).is_file()
    ds = FogDrive(tmp_path)
    added = {f"{NARROW}{s}" for s in ("", "_FOG_LIGHT", "_FOG_MODERATE", "_FOG_DENSE", "_DEPTH", "_SEM", "_BBOX")}
    assert set(ds.list_channels()) == set(FOGDRIVE_CHANNELS) | added
    assert ds.channels[NARROW].folder == "cam_front_narrow/out_rgb"
    for i, s in enumerate(sorted(ds.sample, key=lambda s: s["timestamp"])):
        data = load_sample(ds, s["token"], [NARROW, f"{NARROW}_FOG_DENSE", f"{NARROW}_BBOX"])
        np.testing.assert_array_equal(data[NARROW], images[i])
        assert data[f"{NARROW}_FOG_DENSE"].shape == (24, 32, 3)
        np.testing.assert_array_equal(data[f"{NARROW}_BBOX"]["bboxes"], boxes[i])
    ext = json.loads(ds.get_extrinsic_config_path(ds.scene[0]["token"]).read_text())
    assert set(ext) == {"extrinsic_front", "extrinsic_back", "extrinsic_left", "extrinsic_right", "extrinsic_front_narrow"}


def test_validation_checks_an_added_cameras_files_and_extrinsics(tmp_path):
    env = RecordFogDrive(fog_gym.FogDriveEnv(rig=_narrow_rig(), episode_seconds=0.1), tmp_path)
    env.reset(seed=0)
    env.close()
    scene = sorted((tmp_path / "data_root").iterdir())[0]
    (scene / "cam_front_narrow" / "out_fog_dense" / "000000.png").write_bytes(b"not a png")
    ext_path = scene / "extrinsic_config" / "extrinsic_config.json"
    ext = json.loads(ext_path.read_text())
    del ext["extrinsic_front_narrow"]
    ext_path.write_text(json.dumps(ext))
    problems = validate(tmp_path)
    assert any("cam_front_narrow/out_fog_dense/000000.png" in p for p in problems)
    assert any("extrinsic_front_narrow is missing" in p for p in problems)


def test_the_torch_loader_stacks_an_added_cameras_images(tmp_path):
    torch = pytest.importorskip("torch")
    from fog_gym.dataset.torch import FogDriveDataset

    env = RecordFogDrive(fog_gym.FogDriveEnv(rig=_narrow_rig(), episode_seconds=0.1), tmp_path)
    env.reset(seed=0)
    env.step(1)
    env.close()
    ds = FogDriveDataset(tmp_path, channels=[NARROW, f"{NARROW}_BBOX"])
    batch = ds.collate([ds[0], ds[1]])
    assert isinstance(batch[NARROW], torch.Tensor) and tuple(batch[NARROW].shape) == (2, 3, 24, 32)
    assert len(batch[f"{NARROW}_BBOX"]) == 2


# -- the layout a set carries ----------------------------------------------------------------------------------
def test_a_set_of_fogdrive_channels_only_carries_no_layout_file(tmp_path):
    env = RecordFogDrive(fog_gym.FogDriveEnv(resolution=(32, 24), episode_seconds=0.1), tmp_path)
    env.reset(seed=0)
    env.close()
    assert not (tmp_path / LAYOUT_FILE).exists() and not list((tmp_path / "data_root").glob("*/channels.json"))
    assert FogDrive(tmp_path).channels == FOGDRIVE_CHANNELS


def test_the_index_refuses_two_scenes_that_store_one_channel_differently(rear_radar, tmp_path):
    from fog_gym.dataset.writer import build_index

    env = RecordFogDrive(fog_gym.FogDriveEnv(rig=_rig(rear_radar), episode_seconds=0.1), tmp_path)
    env.reset(seed=0)
    env.reset(seed=1)
    env.close()
    scenes = sorted((tmp_path / "data_root").iterdir())
    assert len(scenes) == 2
    layout = json.loads((scenes[1] / "channels.json").read_text())
    layout["channels"]["RADAR_BACK"]["columns"] = 5
    (scenes[1] / "channels.json").write_text(json.dumps(layout))
    with pytest.raises(ValueError, match="channel 'RADAR_BACK' is stored as .* here and as .* in an earlier scene"):
        build_index(tmp_path)

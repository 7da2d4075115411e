import math

import gymnasium as gym
import pytest

import fog_gym
from fog_gym.sensors.camera import CameraConfig
from fog_gym.envs.config import FogDriveConfig
from fog_gym.geometry import Pose
from fog_gym.sensors.rig import RigConfig


def test_towns_in_fogdrive_order():
    assert fog_gym.TOWNS == ("highway", "merge", "roundabout", "intersection", "racetrack", "exit")
    assert FogDriveConfig(town="roundabout").town_number == 3


def test_fogdrive_rig_preset_matches_table_2():
    rig = RigConfig.fogdrive()
    poses = {c.name: (c.pose.location, c.pose.rotation, c.width, c.height, c.fov) for c in rig.cameras}
    assert poses["CAM_FRONT"] == ((1.8, 0.0, 1.2), (0.0, 0.0, 0.0), 1280, 960, 100.0)
    assert poses["CAM_RIGHT"][:2] == ((0.5, 0.7, 1.5), (0.0, 0.0, 100.0))
    assert poses["CAM_LEFT"][:2] == ((0.5, -0.7, 1.5), (0.0, 0.0, -100.0))
    assert poses["CAM_BACK"][:2] == ((-2.4, 0.0, 1.2), (0.0, 0.0, 180.0))


def test_resolution_scales_intrinsics():
    rig = RigConfig.fogdrive().with_resolution((640, 480))
    K = rig.camera("CAM_FRONT").intrinsic()
    assert K[0, 0] == pytest.approx(RigConfig.fogdrive().camera("CAM_FRONT").intrinsic()[0, 0] / 2) and (K[0, 2], K[1, 2]) == (320, 240)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"town": "Town10HD"}, r"town must be one of \('highway'"),
        ({"time_of_day": "dusk"}, r"time_of_day must be one of \('day', 'night'\)"),
        ({"resolution": (0, 480)}, "resolution must be a"),
        ({"resolution": (640, -1)}, "resolution must be a"),
        ({"resolution": 640}, "resolution must be a"),
        ({"cameras": ["CAM_TOP"]}, r"camera name must be one of \('CAM_FRONT'"),
        ({"cameras": "CAM_FRONT"}, "sequence of camera names"),
        ({"episode_seconds": -1}, "episode_seconds"),
        ({"simulation_frequency": 15}, "multiple of keyframe_frequency"),
    ],
)
def test_bad_env_arguments_fail_at_construction(kwargs, message):
    with pytest.raises(ValueError, match=message):
        gym.make("FogDrive-v0", **kwargs)


def test_bad_render_mode():
    from fog_gym.envs.fogdrive import FogDriveEnv

    with pytest.raises(ValueError, match="render_mode must be one of"):
        FogDriveEnv(render_mode="human", resolution=(8, 8))


@pytest.mark.parametrize("fov", [0.0, 180.0, -5.0, 200.0, math.nan])
def test_bad_fov(fov):
    with pytest.raises(ValueError, match=r"fov"):
        CameraConfig("CAM_FRONT", Pose(1.8, 0, 1.2), fov=fov)


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf, "x"])
def test_non_finite_pose(bad):
    with pytest.raises(ValueError, match=r"pose\.z must be a finite number"):
        RigConfig.fogdrive(poses={"CAM_FRONT": (1.8, 0.0, bad)})


def test_unknown_camera_in_poses_and_duplicates():
    with pytest.raises(ValueError, match="camera name must be one of"):
        RigConfig.fogdrive(poses={"CAM_UP": (0, 0, 1)})
    cam = CameraConfig("CAM_FRONT", Pose(1.8, 0, 1.2))
    with pytest.raises(ValueError, match="unique"):
        RigConfig((cam, cam))


def test_make_forwards_kwargs():
    env = gym.make("FogDrive-v0", town="merge", time_of_day="night", resolution=(48, 32), cameras=["CAM_BACK"])
    u = env.unwrapped
    assert u.config.town == "merge" and u.config.time_of_day == "night"
    assert set(env.observation_space.spaces) == {
        "CAM_BACK", "CAM_BACK_DEPTH", "CAM_BACK_SEM", "LIDAR_TOP", "SEM_LIDAR_TOP", "RADAR_FRONT"
    }
    assert env.observation_space["CAM_BACK"].shape == (32, 48, 3)
    env.close()


# -- the rig as one sequence of named sensor configs ------------------------------------------------------------
from dataclasses import replace  # noqa: E402

from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from fog_gym.sensors.camera import FOGDRIVE_CAMERA_POSES  # noqa: E402
from fog_gym.sensors.lidar import LidarConfig, SemanticLidarConfig  # noqa: E402
from fog_gym.sensors.radar import RadarConfig


def _fogdrive_sequence(w=1280, h=960):
    cams = [(n, CameraConfig(n, FOGDRIVE_CAMERA_POSES[n], w, h, 100.0)) for n in fog_gym.CAMERA_NAMES]
    return (*cams, ("LIDAR_TOP", LidarConfig.fogdrive()), ("SEM_LIDAR_TOP", LidarConfig.fogdrive_semantic()),
            ("RADAR_FRONT", RadarConfig.fogdrive()))  # fmt: skip


def test_a_rig_built_from_a_sequence_equals_the_fogdrive_preset():
    rig = RigConfig(_fogdrive_sequence())
    preset = RigConfig.fogdrive()
    assert rig == preset and hash(rig) == hash(preset)
    assert rig.names == ("CAM_FRONT", "CAM_BACK", "CAM_LEFT", "CAM_RIGHT", "LIDAR_TOP", "SEM_LIDAR_TOP", "RADAR_FRONT")
    assert (rig.lidar, rig.semantic_lidar, rig.radar) == (LidarConfig.fogdrive(), LidarConfig.fogdrive_semantic(),
                                                          RadarConfig.fogdrive())  # fmt: skip
    assert rig.extra == () and type(rig.semantic_lidar) is SemanticLidarConfig


def test_the_pre_sequence_keyword_constructor_builds_the_same_sequence():
    preset = RigConfig.fogdrive(resolution=(64, 48))
    legacy = RigConfig(preset.cameras, lidar=LidarConfig.fogdrive(), semantic_lidar=LidarConfig.fogdrive(points_per_second=750_000.0),
                       radar=RadarConfig.fogdrive())  # fmt: skip
    assert legacy == preset  # a plain LidarConfig as semantic_lidar becomes the semantic LiDAR's config type
    assert RigConfig(cameras=preset.cameras, lidar=None, radar=None).names == tuple(fog_gym.CAMERA_NAMES)


def test_named_keywords_replace_in_place_remove_with_none_and_reinsert_in_fogdrive_order():
    rig = RigConfig.fogdrive(resolution=(64, 48))
    lidar32 = LidarConfig.fogdrive(channels=32)
    changed = replace(rig, lidar=lidar32)
    assert changed.names == rig.names and changed.lidar == lidar32
    without = replace(rig, lidar=None)
    assert "LIDAR_TOP" not in without.names and without.lidar is None
    assert replace(without, lidar=LidarConfig.fogdrive()) == rig  # back where FogDrive puts it
    assert replace(rig, cameras=rig.cameras[2:3]).names[0] == "CAM_LEFT"
    assert rig.with_resolution((32, 24)).names == rig.names


def test_properties_are_read_only_views_of_the_sequence():
    rig = RigConfig.fogdrive(resolution=(64, 48))
    with pytest.raises(AttributeError):
        rig.lidar = None
    assert rig.sensor("RADAR_FRONT") is rig.radar
    with pytest.raises(KeyError, match="no sensor named 'RADAR_BACK'"):
        rig.sensor("RADAR_BACK")


_POOL = [*_fogdrive_sequence(16, 12), ("RADAR_BACK", RadarConfig.fogdrive()), ("LIDAR_REAR", LidarConfig.fogdrive()),
         ("CAM_FRONT_NARROW", CameraConfig("CAM_FRONT_NARROW", Pose(1.8, 0, 1.2), 16, 12, 40.0))]  # fmt: skip


@settings(max_examples=60, deadline=None)
@given(st.lists(st.sampled_from(_POOL), max_size=12))
def test_any_order_of_sensors_is_a_rig_exactly_when_the_names_are_unique(entries):
    names = [n for n, _ in entries]
    if len(set(names)) == len(names):
        rig = RigConfig(entries)
        assert rig.names == tuple(names) and RigConfig(rig.sensors) == rig
        assert [c.name for c in rig.cameras] == [n for n, c in entries if isinstance(c, CameraConfig)]
    else:
        with pytest.raises(ValueError, match="sensor names must be unique"):
            RigConfig(entries)


@pytest.mark.parametrize(
    ("entry", "match"),
    [
        (RadarConfig.fogdrive(), "pairs or CameraConfig"),
        (("RADAR_BACK", RadarConfig.fogdrive(), "x"), "pairs or CameraConfig"),
        (("radar_back", RadarConfig.fogdrive()), "upper-case channel name"),
        (("RADAR_BACK", object()), "'RADAR_BACK': config type must be one of the registered sensor configs"),
        (("SEM_LIDAR_TOP", LidarConfig.fogdrive()), "'SEM_LIDAR_TOP' is FogDrive's and needs a SemanticLidarConfig"),
        (("LIDAR_TOP", LidarConfig.fogdrive_semantic()), "'LIDAR_TOP' is FogDrive's and needs a LidarConfig"),
        (("CAM_BACK", RadarConfig.fogdrive()), "'CAM_BACK' is a FogDrive camera and needs a CameraConfig"),
        (("CAM_X", CameraConfig("CAM_Y", Pose(0, 0, 1))), "a camera's sensor name is its config's name"),
    ],
)
def test_a_bad_sequence_entry_is_refused_naming_the_problem(entry, match):
    with pytest.raises(ValueError, match=match):
        RigConfig((entry,))

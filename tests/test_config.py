import math

import gymnasium as gym
import pytest

import fog_gym
from fog_gym.config import CameraConfig, FogDriveConfig, Pose, RigConfig


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
    from fog_gym.env import FogDriveEnv

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

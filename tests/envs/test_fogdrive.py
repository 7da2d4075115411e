"""FogDrive-v0 through the Gymnasium API."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import fog_gym
from fog_gym.envs.fogdrive import FogDriveEnv
from fog_gym.world.scenery import SURFACE_TAGS
from fog_gym.world.fleet import CLASS_SPECS, EGO_ID, EGO_SIZE

from tests.conftest import first_idle

SMALL = (96, 72)


def rollout(env, seed, steps=3):
    obs, _ = env.reset(seed=seed)
    frames = [obs]
    idle = first_idle(env.action_space)
    for _ in range(steps):
        obs, *_ = env.step(idle)
        frames.append(obs)
    return frames


def test_observation_space_and_dtypes(small_env):
    obs = small_env.frames and {k: v for k, v in small_env._observe().items()}
    assert set(small_env.observation_space.spaces) == {
        f"{c}{s}" for c in fog_gym.CAMERA_NAMES for s in ("", "_DEPTH", "_SEM")
    } | {"LIDAR_TOP", "SEM_LIDAR_TOP", "RADAR_FRONT"}
    assert small_env.observation_space.contains(obs)
    assert obs["CAM_FRONT"].shape == (120, 160, 3) and obs["CAM_FRONT"].dtype == np.uint8
    assert obs["CAM_FRONT_DEPTH"].dtype == np.float32 and obs["CAM_FRONT_SEM"].dtype == np.uint8


def test_semantic_tags_are_those_of_the_scene(small_env):
    scene = small_env.scene
    present = set(SURFACE_TAGS[np.unique(scene.static.surface.grid)].tolist())
    present |= set(scene.static.props.tags.tolist()) | set(scene.primitives.tags.tolist()) | {11}
    for name in small_env.cameras.names:
        assert set(np.unique(small_env.frames[name].semantic).tolist()) <= present


def test_instance_buffer_matches_vehicles(small_env):
    ids = set(small_env.scene.vehicles.ids.tolist())
    for name, inst in small_env.instance_buffers.items():
        seen = set(np.unique(inst).tolist())
        assert seen <= ids | {0} and EGO_ID not in seen
        sem = small_env.frames[name].semantic
        assert set(np.unique(sem[inst > 0]).tolist()) <= {14, 15}


def test_determinism_by_seed():
    a = rollout(FogDriveEnv(town="highway", resolution=SMALL), seed=7)
    b = rollout(FogDriveEnv(town="highway", resolution=SMALL), seed=7)
    for fa, fb in zip(a, b):
        for k in fa:
            assert fa[k].tobytes() == fb[k].tobytes(), k
    c = rollout(FogDriveEnv(town="highway", resolution=SMALL), seed=8, steps=0)
    assert c[0]["CAM_FRONT"].tobytes() != a[0]["CAM_FRONT"].tobytes()


@pytest.mark.parametrize("town", fog_gym.TOWNS)
def test_every_town_runs_with_fogdrive_classes(town):
    env = FogDriveEnv(town=town, resolution=(32, 24), cameras=["CAM_FRONT"])
    env.reset(seed=1)
    idle = first_idle(env.action_space)
    ids_by_object = {}
    for _ in range(4):
        for v in env.world.vehicles():
            ids_by_object.setdefault(id(v), v._fog_id)
            assert ids_by_object[id(v)] == v._fog_id  # ids are stable
        _, _, terminated, truncated, info = env.step(idle)
        if terminated:
            break
    state = env.world.vehicle_state()
    assert len(set(state.ids.tolist())) == len(state) and state.ids[0] == EGO_ID
    np.testing.assert_allclose(state.sizes[0], EGO_SIZE)
    for v, size, cls in zip(env.world.vehicles(), state.sizes, state.classes):
        assert (v.LENGTH, v.WIDTH) == (size[0], size[1])  # highway-env collides with the rendered box
        assert v.diagonal == pytest.approx(np.hypot(size[0], size[1]))
        if v._fog_id != EGO_ID:
            _, lr, wr, hr = CLASS_SPECS[int(cls)]
            assert lr[0] <= size[0] <= lr[1] and wr[0] <= size[1] <= wr[1] and hr[0] <= size[2] <= hr[1]
    assert set(state.classes.tolist()) <= {0, 1, 4}
    assert info["town_number"] == fog_gym.TOWNS.index(town) + 1
    env.close()


def test_day_and_night_differ_in_light_only_and_the_night_sky_is_dark():
    day = FogDriveEnv(town="intersection", time_of_day="day", resolution=SMALL).reset(seed=3)[0]
    night = FogDriveEnv(town="intersection", time_of_day="night", resolution=SMALL).reset(seed=3)[0]
    for cam in fog_gym.CAMERA_NAMES:
        assert night[cam].mean() < day[cam].mean()  # lamps and beams light the night, the sun lights the day
        sky = day[f"{cam}_SEM"] == 11
        assert night[cam][sky].mean() < 0.1 * day[cam][sky].mean()
        np.testing.assert_array_equal(night[f"{cam}_DEPTH"], day[f"{cam}_DEPTH"])  # same world, other light
        np.testing.assert_array_equal(night[f"{cam}_SEM"], day[f"{cam}_SEM"])


def test_truncation_at_episode_length():
    env = FogDriveEnv(town="roundabout", resolution=(16, 12), cameras=["CAM_FRONT"], episode_seconds=0.3)
    env.reset(seed=0)
    flags = [env.step(first_idle(env.action_space))[2:4] for _ in range(3)]
    assert [t for _, t in flags] == [False, False, True] or any(term for term, _ in flags)


def test_termination_on_collision():
    env = FogDriveEnv(town="highway", resolution=(16, 12), cameras=["CAM_FRONT"])
    env.reset(seed=0)
    ego, other = env.world.vehicles()[:2]
    other.position = ego.position.copy()  # put an NPC on top of the ego
    _, _, terminated, truncated, info = env.step(first_idle(env.action_space))
    assert terminated and info["crashed"] and not truncated


def test_render_composite():
    env = gym.make("FogDrive-v0", town="merge", resolution=SMALL, render_mode="rgb_array")
    env.reset(seed=0)
    frame = env.render()
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3 and frame.shape[1] > frame.shape[0]
    env.close()


def test_check_env_passes():
    env = gym.make("FogDrive-v0", town="roundabout", resolution=(48, 36), render_mode="rgb_array")
    check_env(env.unwrapped, skip_render_check=False)


def test_async_vector_env():
    envs = gym.make_vec("FogDrive-v0", num_envs=2, vectorization_mode="async", resolution=(48, 36))
    try:
        obs, info = envs.reset(seed=[1, 2])
        assert obs["CAM_FRONT"].shape == (2, 36, 48, 3)
        assert obs["CAM_FRONT"][0].tobytes() != obs["CAM_FRONT"][1].tobytes()
        obs, reward, terminated, truncated, info = envs.step(np.array([1, 1]))
        assert obs["CAM_BACK_DEPTH"].shape == (2, 36, 48) and reward.shape == (2,)
    finally:
        envs.close()


@pytest.mark.slow
def test_full_fogdrive_rig():
    env = gym.make("FogDrive-v0")
    obs, _ = env.reset(seed=0)
    assert obs["CAM_FRONT"].shape == (960, 1280, 3)
    K = env.unwrapped.cameras.intrinsics["CAM_FRONT"]
    assert K[0, 0] == pytest.approx(537.09, abs=0.07) and (K[0, 2], K[1, 2]) == (640, 480)
    assert env.unwrapped.config.episode_steps == 200
    env.close()


def test_point_channels_unpack_exactly(small_env):
    obs = small_env._observe()
    assert obs["LIDAR_TOP"].shape == (64 * 1016, 4) and obs["SEM_LIDAR_TOP"].shape == (64 * 586, 6)
    assert obs["RADAR_FRONT"].shape == (900, 4)
    for name, pts in small_env.points.items():
        unpacked = fog_gym.unpack_points(obs, name)
        assert unpacked.dtype == np.float32 and unpacked.tobytes() == pts.tobytes()
    sem = small_env.points["SEM_LIDAR_TOP"]
    ids = set(sem[:, 4].astype(int).tolist())
    assert EGO_ID not in ids and ids <= set(small_env.scene.vehicles.ids.tolist()) | {0}
    assert len(small_env.points["LIDAR_TOP"]) > 20000  # ≈ 65 k rays, 45 % general drop-off, ground everywhere near


def test_unpack_points_rejects_bad_input(small_env):
    obs = small_env._observe()
    with pytest.raises(ValueError, match="point channel"):
        fog_gym.unpack_points(obs, "CAM_FRONT")
    with pytest.raises(ValueError, match="index a vector env"):
        fog_gym.unpack_points(np.zeros((2, 10, 4), np.float32))
    with pytest.raises(KeyError, match="RADAR_FRONT"):
        fog_gym.unpack_points({}, "RADAR_FRONT")


def test_rig_without_point_sensors():
    rig = fog_gym.RigConfig.fogdrive(resolution=(16, 12), cameras=["CAM_FRONT"], lidar=False, radar=False)
    env = FogDriveEnv(rig=rig)
    obs, _ = env.reset(seed=0)
    assert set(obs) == {"CAM_FRONT", "CAM_FRONT_DEPTH", "CAM_FRONT_SEM", "SEM_LIDAR_TOP"}
    with pytest.raises(ValueError, match="lidar must be a LidarConfig or None"):
        fog_gym.RigConfig(lidar="velodyne")

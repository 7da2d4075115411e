"""A LiDAR sweep that takes time: the still world gives the instantaneous sweep, deskew undoes the ego's motion,
the world between keyframes, the env's channels and the fog's handling of the time column."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fog_gym.channels.packing import unpack_points
from fog_gym.envs.fogdrive import FogDriveEnv
from fog_gym.geometry import sensor_to_world
from fog_gym.sensors import LidarConfig, LidarSensor, SemanticLidarConfig, deskew
from fog_gym.sensors.lidar import simulate_lidar
from fog_gym.sensors.motion import MOTION_SLICES, ego_poses_at, sweep_slices
from fog_gym.world.fleet import VehicleState
from fog_gym.world.motion import SceneMotion
from fog_gym.world.primitives import Primitives
from fog_gym.wrappers import FogWrapper

CLEAN = dict(dropoff_general_rate=0.0, dropoff_zero_intensity=0.0, noise_stddev=0.0)


def _wall(x_face: float) -> Primitives:
    """A wall across the road: its near face at x = x_face, 200 m wide, 10 m high."""
    return Primitives.coerce({"centers": np.array([[x_face + 1.0, 0.0, 5.0]]), "halves": np.array([[1.0, 100.0, 5.0]]),
                              "yaws": np.zeros(1)})  # fmt: skip


def test_still_world_gives_the_instantaneous_sweep_bit_for_bit():
    cfg = LidarConfig.fogdrive(noise_stddev=0.02)  # with drop-off and range noise: the same draws in the same order
    s2w = sensor_to_world(cfg.pose, (3.0, -2.0, 0.4))
    prims = _wall(30.0)
    still = simulate_lidar(cfg, s2w, prims, None, np.random.default_rng(5), motion=lambda t: (s2w, prims))
    instant = simulate_lidar(cfg, s2w, prims, None, np.random.default_rng(5))
    assert still.shape == (len(instant), 5)
    assert np.array_equal(still[:, :4], instant)
    assert still[:, 4].min() >= -1 / 20 and still[:, 4].max() <= 0 and len(np.unique(still[:, 4])) == MOTION_SLICES


def test_sensor_in_a_still_scene_equals_the_instantaneous_sensor():
    env = FogDriveEnv(town="merge", resolution=(32, 24), cameras=["CAM_FRONT"], labels=None)
    env.reset(seed=2)
    env.step(env.idle_action)
    scene = env.scene
    still = replace(scene, vehicles=replace(scene.vehicles, velocities=np.zeros_like(scene.vehicles.velocities)), previous=None)
    prims = env.cameras.primitives(still, in_view=False)
    cfg = env.config.rig.lidar
    moving = LidarSensor(replace(cfg, motion="continuous"), 20.0).measure(still, prims, np.random.default_rng(1), 3)
    instant = LidarSensor(cfg, 20.0).measure(still, prims, np.random.default_rng(1), 3)
    (a,), (b,) = moving.values(), instant.values()
    assert list(moving) == ["LIDAR_TOP_MOTION"] and np.array_equal(a[:, :4], b)


def test_deskew_undoes_a_pure_ego_motion_within_a_centimetre():
    cfg = LidarConfig.fogdrive(**CLEAN)
    speed, wall_x = 30.0, 40.0
    mount = sensor_to_world(cfg.pose)

    def at(t):
        return sensor_to_world(cfg.pose, (speed * t, 0.0, 0.0)), _wall(wall_x)

    pts = simulate_lidar(cfg, at(0.0)[0], _wall(wall_x), None, np.random.default_rng(0), motion=at)
    times = np.unique(pts[:, 4])
    poses = np.array([[t, speed * t, 0.0, 0.0] for t in (*times, 0.0)])
    on_wall = np.abs(pts[:, 2] + 2.0) > 1e-3  # not the ground (the LiDAR sits 2 m up)
    raw_err = np.abs(pts[on_wall, 0] - wall_x)
    assert raw_err.max() > 0.5  # the wall ahead fired about 25 ms before the keyframe: 0.75 m the smear
    fixed = deskew(pts, poses, mount)
    assert np.abs(fixed[on_wall, 0] - wall_x).max() < 0.01
    assert np.abs(fixed[~on_wall, 2] + 2.0).max() < 0.01  # the ground stays flat at the mount height
    assert np.array_equal(fixed[:, 3:], pts[:, 3:])


@settings(max_examples=30, deadline=None)
@given(x=st.floats(-50, 50), y=st.floats(-50, 50), yaw=st.floats(-3.1, 3.1), v=st.floats(-40, 40), w=st.floats(-1, 1))
def test_deskew_to_a_time_and_back_is_the_identity(x, y, yaw, v, w):
    rng = np.random.default_rng(0)
    pts = np.c_[rng.normal(0, 20, (50, 3)), rng.uniform(0, 1, 50), rng.uniform(-0.05, 0, 50)].astype(np.float32)
    poses = np.array([[t, x + v * t * np.cos(yaw), y + v * t * np.sin(yaw), yaw + w * t] for t in (-0.05, -0.02, 0.0)])
    there = deskew(pts, poses)
    back = there.copy()
    # back: each point from the frame at 0 to the frame at its own time (deskew with swapped roles)
    for i, t in enumerate(pts[:, 4]):
        back[i] = deskew(np.r_[there[i, :4], 0.0][None].astype(np.float32), poses, reference_time=float(t))[0]
    assert np.abs(back[:, :3] - pts[:, :3]).max() < 1e-3
    assert np.array_equal(deskew(pts, poses[[-1]])[:, :3], pts[:, :3])  # one pose: nothing moved


def test_world_between_keyframes_interpolates_and_moves_boxes_rigidly():
    def state(x, y, yaw):
        return VehicleState(np.array([1, 7]), np.zeros(2, np.int8), np.array([[0.0, 0, 0.75], [x, y, 0.75]]),
                            np.full((2, 3), 2.0), np.array([0.0, yaw]), np.array([[0.0, 0, 0], [20.0, 0, 0]]),
                            np.full((2, 3), 0.5))  # fmt: skip
    prev, cur = state(10.0, 0.0, 0.0), state(12.0, 0.5, 0.2)
    m = SceneMotion(cur, previous=(-0.1, prev))
    assert m.ego_pose_at(-0.1, 7) == pytest.approx((10.0, 0.0, 0.0)) and m.ego_pose_at(0.0, 7) == (12.0, 0.5, 0.2)
    prims = Primitives.coerce({"centers": np.array([[12.0, 0.5, 0.5], [13.5, 0.5, 1.0], [50.0, 5.0, 1.0]]),
                               "halves": np.ones((3, 3)), "yaws": np.array([0.2, 0.2, 0.0]),
                               "insts": np.array([7, 7, 0])})  # fmt: skip
    moved = m.primitives_at(prims, -0.05)
    assert np.allclose(moved.centers[0, :2], [11.0, 0.25]) and moved.yaws[0] == pytest.approx(0.1)
    d0 = np.linalg.norm(prims.centers[0] - prims.centers[1])
    assert np.linalg.norm(moved.centers[0] - moved.centers[1]) == pytest.approx(d0)  # rigid
    assert np.array_equal(moved.centers[2], prims.centers[2])  # the static world stays
    assert m.primitives_at(prims, 0.0) is prims
    times = [-0.1, -0.05, 0.0, -0.0125]  # all slices in one pass: each the world primitives_at gives
    for t, world in zip(times, m.primitives_during(prims, times)):
        one = m.primitives_at(prims, t)
        assert np.array_equal(world.centers, one.centers) and np.array_equal(world.yaws, one.yaws)


def test_a_vehicle_that_appeared_keeps_its_velocity_and_one_that_left_moves_nothing():
    def state(ids, xs, vx):
        n = len(ids)
        return VehicleState(np.array(ids), np.zeros(n, np.int8), np.c_[xs, np.zeros(n), np.full(n, 0.75)],
                            np.full((n, 3), 2.0), np.zeros(n), np.c_[vx, np.zeros((n, 2))],
                            np.full((n, 3), 0.5))  # fmt: skip
    prev = state([3, 9], [0.0, 50.0], [10.0, 10.0])  # 9 leaves
    cur = state([5, 3], [20.0, 1.5], [7.0, 10.0])  # 5 appears; 3 drove 1.5 m in 0.1 s (15 m/s, not its 10)
    m = SceneMotion(cur, previous=(-0.1, prev))
    assert m.ego_pose_at(-0.1, 3) == pytest.approx((0.0, 0.0, 0.0))  # interpolated to where it was
    assert m.ego_pose_at(-0.1, 5) == pytest.approx((19.3, 0.0, 0.0))  # extrapolated at its own velocity
    prims = Primitives.coerce({"centers": np.array([[20.0, 0, 1], [1.5, 0, 1], [50.0, 0, 1]]),
                               "halves": np.ones((3, 3)), "yaws": np.zeros(3),
                               "insts": np.array([5, 3, 9])})  # fmt: skip
    worlds = m.slice_worlds(prims, np.array([-0.05, 0.0]))
    assert np.allclose(worlds.centers[0, :, 0], [19.65, 0.75, 50.0])  # the box of the vehicle that left stays
    assert np.array_equal(worlds.centers[1], prims.centers) and np.array_equal(worlds.yaws[1], prims.yaws)
    with pytest.raises(KeyError):
        m.ego_poses_during([0.0], 9)


def test_env_sweep_in_time_channels_columns_and_fog():
    env = FogWrapper(FogDriveEnv(town="merge", resolution=(32, 24), cameras=["CAM_FRONT"], lidar_motion="continuous",
                                 lidar_returns="dual"), fog=["dense"])  # fmt: skip
    obs, info = env.reset(seed=4)
    obs, *_, info = env.step(env.unwrapped.idle_action)
    assert "LIDAR_TOP_DUAL_MOTION" in obs and "LIDAR_TOP_DUAL_MOTION_FOG_DENSE" in obs and "LIDAR_TOP" not in obs
    clean = unpack_points(obs, "LIDAR_TOP_DUAL_MOTION")
    fog = unpack_points(obs, "LIDAR_TOP_DUAL_MOTION_FOG_DENSE")
    assert clean.shape[1] == fog.shape[1] == 6 and (clean[:, 5] == 0).all()
    n = len(clean)
    assert np.array_equal(fog[:n, 4], clean[:, 4])  # each beam's echo keeps its firing time
    assert set(np.unique(fog[n:, 5])) <= {1.0} and np.isin(fog[n:, 4], clean[:, 4]).all()
    poses = info["lidar_ego_poses"]
    assert poses.shape == (MOTION_SLICES + 1, 4) and poses[-1, 0] == 0.0
    ego = env.unwrapped.scene.ego_pose
    assert poses[-1, 1:] == pytest.approx(ego)
    assert env.observation_space.contains(obs)


def test_sweep_slices_cover_every_ray_once():
    cols = np.random.default_rng(0).integers(0, 1016, 5000)
    slices, times = sweep_slices(cols, 1016, 20.0)
    assert np.array_equal(np.sort(np.concatenate(slices)), np.arange(5000))
    assert np.all(np.diff(times) > 0) and times[0] > -0.05 and times[-1] < 0
    assert all((np.diff(cols[s] * MOTION_SLICES // 1016) == 0).all() for s in slices if s.size)


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 5), st.integers(1, 300), st.integers(1, 40), st.floats(0.0, 0.95), st.integers(0, 2**32))
def test_counting_sort_of_a_sweep_equals_sweep_order_and_a_take(channels, m, n_slices, drop, seed):
    from fog_gym.sensors.lidar import _slice_sort
    from fog_gym.sensors.motion import sweep_order

    rng = np.random.default_rng(seed)
    rays = np.flatnonzero(rng.random(channels * m) >= drop)
    dirs = rng.normal(size=(channels * m, 3))
    s = max(1, min(n_slices, m))
    order, bounds, got = np.empty(len(rays), np.int64), np.empty(s + 1, np.int64), np.empty((len(rays), 3))
    slice_time, ray_time = -np.arange(1, s + 1, dtype=np.float32), np.empty(len(rays), np.float32)
    _slice_sort(rays, dirs[rays], (np.arange(m) * s // m).astype(np.int32), slice_time, order, got, bounds, ray_time)
    want_order, want_bounds = sweep_order(rays % m, m, s)
    assert np.array_equal(order, want_order) and np.array_equal(bounds, want_bounds)
    assert np.array_equal(got, dirs[rays][want_order])
    assert np.array_equal(ray_time, slice_time[(rays % m) * s // m])  # each ray its slice's time


def test_bad_motion_values_are_one_line_errors():
    with pytest.raises(ValueError, match="motion must be one of"):
        LidarConfig(motion="smooth")
    with pytest.raises(ValueError, match="motion: the semantic LiDAR"):
        SemanticLidarConfig(motion="continuous")
    with pytest.raises(ValueError, match="motion must be one of"):
        FogDriveEnv(resolution=(32, 24), cameras=["CAM_FRONT"], lidar_motion="sideways")
    with pytest.raises(ValueError, match="ego_poses"):
        ego_poses_at(np.zeros((2, 3)), np.zeros(1))
    with pytest.raises(ValueError, match="time column"):
        deskew(np.zeros((3, 4), np.float32), np.zeros((1, 4)))
    with pytest.raises(ValueError, match="previous keyframe"):
        SceneMotion(VehicleState(*(np.zeros((1, *s)) for s in ((), (), (3,), (3,), (), (3,), (3,)))), previous=(0.1, None))


def test_generated_sweeps_in_time_validate_and_carry_their_time_column(tmp_path):
    from fog_gym.dataset import FogDrive
    from fog_gym.dataset.decode import load_channel
    from fog_gym.dataset.validate import validate
    from fog_gym.generate import generate, plan_scenes

    plan = plan_scenes(2, towns=("highway",), seed=2, resolution=(32, 24), seconds=0.2, modality="lidar",
                       lidar_motion="continuous", camera_noise="default")  # fmt: skip
    assert plan[0].channels[0] == "LIDAR_TOP_MOTION"
    generate(tmp_path / "m", plan, progress=False)
    assert validate(tmp_path / "m") == []
    ds = FogDrive(tmp_path / "m")
    ch = "LIDAR_TOP_MOTION_FOG_LIGHT"
    s = ds.sample[-1]
    pts = load_channel(ch, ds.get_sample_paths(s["token"], [ch])[ch], ds.channels[ch])
    assert pts.shape[1] == 5 and -0.05 <= pts[:, 4].min() and pts[:, 4].max() <= 0
    with pytest.raises(ValueError, match="camera_noise"):
        plan_scenes(2, camera_noise="loud")
    with pytest.raises(ValueError, match="motion must be one of"):
        plan_scenes(2, lidar_motion="smooth")


@settings(max_examples=12, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(1, 6), st.booleans())
def test_slices_cast_in_one_call_equal_each_slice_cast_alone(seed, n_slices, meshes):
    """cast_ray_slices (a sweep that takes time: every slice in one kernel call, its hits in the caller's order)
    gives each slice cast_rays(sector=True)'s hits bit for bit, from its own place against its own moved world."""
    from fog_gym.sensors.lidar import SLICE_AZIMUTH_BINS
    from fog_gym.sensors.raycast import cast_ray_slices, cast_rays
    from fog_gym.world.meshlib import LIBRARY

    rng = np.random.default_rng(seed)
    n_prims = 40
    base = {"centers": np.c_[rng.uniform(-40, 40, (n_prims, 2)), rng.uniform(0.5, 2.0, n_prims)],
            "halves": rng.uniform(0.3, 2.5, (n_prims, 3)), "yaws": rng.uniform(-np.pi, np.pi, n_prims)}  # fmt: skip
    if meshes:
        base["meshes"] = rng.integers(0, len(LIBRARY.arrays().radius), n_prims).astype(np.int32)
    worlds = [Primitives.coerce({**base, "centers": base["centers"] + [rng.normal(0, 1.0), rng.normal(0, 1.0), 0.0],
                                 "yaws": base["yaws"] + rng.normal(0, 0.2)}) for _ in range(n_slices)]  # fmt: skip
    cuts = np.sort(rng.integers(0, 3000, n_slices - 1))
    bounds = np.r_[0, cuts, 3000]
    az = np.concatenate([np.sort(rng.uniform(2 * np.pi * k / n_slices, 2 * np.pi * (k + 1) / n_slices, hi - lo))
                         for k, (lo, hi) in enumerate(zip(bounds[:-1], bounds[1:]))])  # fmt: skip
    el = rng.uniform(-0.3, 0.05, len(az))
    dirs = np.c_[np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)]
    origins = np.c_[rng.normal(0, 0.5, (n_slices, 2)), np.full(n_slices, 1.8)]
    yaw = rng.normal(0, 0.1, n_slices)
    rotations = np.stack([[[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]] for a in yaw])
    order = rng.permutation(len(dirs))
    got = cast_ray_slices(origins, rotations, dirs, bounds, 80.0, worlds, n_azimuth_bins=SLICE_AZIMUTH_BINS,
                          order=order)  # fmt: skip
    for k, (lo, hi) in enumerate(zip(bounds[:-1], bounds[1:])):
        alone = cast_rays(origins[k], dirs[lo:hi], 80.0, worlds[k], rotation=rotations[k],
                          n_azimuth_bins=SLICE_AZIMUTH_BINS, sector=True)  # fmt: skip
        for a, b in zip(got, alone):
            assert np.array_equal(a[order[lo:hi]], b)
    assert (got.index >= 0).any() and (got.index == -1).any()  # boxes and the ground both hit


def test_slices_cast_reject_bad_bounds_worlds_and_order():
    from fog_gym.sensors.raycast import cast_ray_slices

    world = Primitives.coerce({"centers": np.zeros((1, 3)), "halves": np.ones((1, 3)), "yaws": np.zeros(1)})
    dirs, o, r = np.ones((4, 3)), np.zeros((2, 3)), np.stack([np.eye(3)] * 2)
    with pytest.raises(ValueError, match="bounds must rise"):
        cast_ray_slices(o, r, dirs, [0, 3, 2], 50.0, [world, world])
    with pytest.raises(ValueError, match="bounds must rise"):
        cast_ray_slices(o, r, dirs, [0, 2, 4], 50.0, [world])
    with pytest.raises(ValueError, match="same primitives"):
        cast_ray_slices(o, r, dirs, [0, 2, 4], 50.0, [world, Primitives.empty()])
    with pytest.raises(ValueError, match="order must be a permutation"):
        cast_ray_slices(o, r, dirs, [0, 2, 4], 50.0, [world, world], order=[0, 1, 2, 4])
    with pytest.raises(ValueError, match="max_range"):
        cast_ray_slices(o, r, dirs, [0, 2, 4], -1.0, [world, world])
    from fog_gym.world.motion import SliceWorlds

    with pytest.raises(ValueError, match="centers and yaws must be"):  # the arrays' form: one box, two slices
        cast_ray_slices(o, r, dirs, [0, 2, 4], 50.0, SliceWorlds(world, np.zeros((2, 2, 3)), np.zeros((2, 1))))
    with pytest.raises(ValueError, match="bounds must rise"):
        cast_ray_slices(o, r, dirs, [0, 2, 4], 50.0, SliceWorlds(world, np.zeros((3, 1, 3)), np.zeros((3, 1))))
    cfg = LidarConfig.fogdrive(**CLEAN)
    s2w = sensor_to_world(cfg.pose)
    worlds = SliceWorlds(world, np.zeros((MOTION_SLICES, 1, 3)), np.zeros((MOTION_SLICES, 1)))
    for bad in (np.stack([s2w] * (MOTION_SLICES - 1)), np.stack([s2w * np.nan] * MOTION_SLICES)):
        with pytest.raises(ValueError, match="motion: each of the 16 slices needs a finite 4x4 sensor_to_world"):
            simulate_lidar(cfg, s2w, world, None, np.random.default_rng(0), motion=(bad, worlds))
    stacked = np.stack([s2w] * MOTION_SLICES)
    got = simulate_lidar(cfg, s2w, world, None, np.random.default_rng(0), motion=(stacked, worlds))
    want = simulate_lidar(cfg, s2w, world, None, np.random.default_rng(0), motion=lambda t: (s2w, world))
    assert np.array_equal(got, want)  # the arrays' form is the callable's

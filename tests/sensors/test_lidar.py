"""LiDAR, semantic LiDAR and radar on hand-built scenes with known answers (fog_gym.sensors.lidar, fog_gym.sensors.raycast)."""

import functools
import math

import numpy as np

from fog_gym.world.primitives import Primitives
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fog_gym.geometry import Pose
from fog_gym.geometry import transform_points, yaw_transform
from fog_gym.sensors.lidar import LidarConfig, lidar_directions, simulate_lidar
from fog_gym.sensors.radar import RadarConfig, simulate_radar
from fog_gym.geometry import sensor_to_world
from fog_gym.sensors.semantic_lidar import simulate_semantic_lidar
from fog_gym.sensors.raycast import GROUND, MISS, cast_rays
from fog_gym.world.scenery import SURFACE_TAGS, SurfaceMap
from fog_gym.world.fleet import VehicleState

ROAD = SurfaceMap(np.ones((400, 400), np.uint8), (-200.0, -200.0), 1.0)
NO_DROP = dict(dropoff_general_rate=0.0, dropoff_zero_intensity=0.0)


def boxes(*rows):
    """rows = (center (3,), halves (3,), yaw, tag, inst) → Primitives."""
    if not rows:
        return Primitives.empty()
    return Primitives.coerce({
        "centers": np.array([r[0] for r in rows], float),
        "halves": np.array([r[1] for r in rows], float),
        "yaws": np.array([r[2] for r in rows], float),
        "tags": np.array([r[3] for r in rows], np.uint8),
        "insts": np.array([r[4] for r in rows], np.uint16),
    })


def concat(a, b):
    return Primitives.concat(a, b)


def enclosure():
    """Four 60 m tall walls 30 m from the origin: every LiDAR ray of the FogDrive pattern hits something."""
    return boxes(((30, 0, 30), (0.5, 31, 30), 0, 3, 0), ((-30, 0, 30), (0.5, 31, 30), 0, 3, 0),
                 ((0, 30, 30), (31, 0.5, 30), 0, 3, 0), ((0, -30, 30), (31, 0.5, 30), 0, 3, 0))  # fmt: skip


def far_boxes(n=500, seed=3):
    rng = np.random.default_rng(seed)
    c = np.c_[rng.uniform(600, 2000, n) * rng.choice([-1, 1], n), rng.uniform(-2000, 2000, n), rng.uniform(0, 10, n)]
    return Primitives.coerce({"centers": c, "halves": rng.uniform(0.5, 20, (n, 3)), "yaws": rng.uniform(-3, 3, n),
                              "tags": np.full(n, 3, np.uint8), "insts": rng.integers(0, 60, n).astype(np.uint16)})  # fmt: skip


# --------------------------------------------------------------------------------------------- ray casting


def _brute_force(origin, dirs, max_range, prims):
    dirs = dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
    best = np.full(len(dirs), max_range)
    idx = np.full(len(dirs), MISS)
    with np.errstate(divide="ignore", invalid="ignore"):
        tg = np.where(dirs[:, 2] < 0, -origin[2] / dirs[:, 2], np.inf)
    m = tg < best
    best[m], idx[m] = tg[m], GROUND
    for p in range(len(prims.yaws)):
        c, s = np.cos(prims.yaws[p]), np.sin(prims.yaws[p])
        r = origin - prims.centers[p]
        o = np.array([c * r[0] + s * r[1], -s * r[0] + c * r[1], r[2]])
        d = np.c_[c * dirs[:, 0] + s * dirs[:, 1], -s * dirs[:, 0] + c * dirs[:, 1], dirs[:, 2]]
        h = prims.halves[p]
        with np.errstate(divide="ignore", invalid="ignore"):
            ta, tb = (-h - o) / d, (h - o) / d
        t0 = np.nan_to_num(np.minimum(ta, tb), nan=-np.inf).max(1)
        t1 = np.nan_to_num(np.maximum(ta, tb), nan=np.inf).min(1)
        m = (t0 <= t1) & (t0 >= 1e-6) & (t0 < best)
        best[m], idx[m] = t0[m], p
    return np.where(idx == MISS, np.inf, best), idx


@pytest.mark.parametrize("where", ["outside", "inside_a_box", "above_a_box"])
def test_cast_rays_matches_brute_force(where):
    rng = np.random.default_rng(7)
    n = 80
    prims = boxes(*[(rng.uniform([-40, -40, 0], [40, 40, 4]), rng.uniform(0.1, 5, 3), rng.uniform(-4, 4), 1, 0)
                    for _ in range(n)])  # fmt: skip
    origin = {"outside": np.array([0.3, -0.2, 1.7]), "inside_a_box": prims.centers[0],
              "above_a_box": prims.centers[0] + [0, 0, prims.halves[0, 2] + 1.0]}[where]  # fmt: skip
    dirs = rng.normal(size=(4000, 3))
    dirs[:4] = [[1, 0, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]]  # axis-aligned and vertical rays
    rot = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    ref_d, ref_i = _brute_force(origin, dirs @ rot.T, 45.0, prims)
    for bins in [(512, 16), (5, 3), (1, 1)]:
        hits = cast_rays(origin, dirs, 45.0, prims, rotation=rot, n_azimuth_bins=bins[0], n_elevation_bins=bins[1])
        np.testing.assert_array_equal(hits.index, ref_i)
        np.testing.assert_allclose(hits.distance, ref_d, rtol=1e-6)
    assert (ref_i >= 0).sum() > 500 and (ref_i == MISS).sum() > 100


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), width=st.floats(0.01, 1.2), centre=st.floats(-np.pi, np.pi),
       inside=st.booleans())  # fmt: skip
def test_rays_in_a_sector_hit_what_the_full_turn_and_brute_force_hit(seed, width, centre, inside):
    """sector=True bins only the rays' sector and drops boxes outside it: the same hits (wider than a quarter turn
    falls back to the full turn)."""
    rng = np.random.default_rng(seed)
    prims = boxes(*[(rng.uniform([-40, -40, 0], [40, 40, 4]), rng.uniform(0.1, 5, 3), rng.uniform(-4, 4), 1, 0)
                    for _ in range(120)])  # fmt: skip
    origin = prims.centers[0] if inside else np.array([0.3, -0.2, 1.7])
    az = centre + rng.uniform(-width / 2, width / 2, 1500)
    el = rng.uniform(-0.4, 0.2, 1500)
    dirs = np.c_[np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)]
    rot = yaw_transform(0, 0, rng.uniform(-np.pi, np.pi))[:3, :3]
    ref_d, ref_i = _brute_force(origin, dirs @ rot.T, 45.0, prims)
    full = cast_rays(origin, dirs, 45.0, prims, rotation=rot)
    for bins in (64, 7, 1):
        hits = cast_rays(origin, dirs, 45.0, prims, rotation=rot, n_azimuth_bins=bins, sector=True)
        np.testing.assert_array_equal(hits.index, ref_i)
        np.testing.assert_array_equal(hits.index, full.index)
        np.testing.assert_array_equal(hits.distance, full.distance)
    np.testing.assert_allclose(full.distance, ref_d, rtol=1e-6)


def test_a_ray_the_sectors_sample_missed_is_cast_as_the_full_turn_casts_it():
    """sector=True takes the sector from a sample of the rays (widened a little) and checks every ray against it: a
    ray outside (here one between the samples, 60° off a 2° sector) makes the cast start again from the exact sector,
    so the box only that ray meets is still hit."""
    from fog_gym.sensors import raycast

    n = 4000
    stride = n // raycast._SECTOR_SAMPLES
    az = np.linspace(-0.017, 0.017, n)
    odd = stride // 2  # not a sampled ray (every stride-th and the last are)
    az[odd] = np.radians(60.0)
    dirs = np.c_[np.cos(az), np.sin(az), np.zeros(n)]
    wall = [(np.array([20.0, 0.0, 1.0]), np.array([0.5, 2.0, 2.0]), 0.0, 1, 0)]
    side = [(np.array([10.0, 10.0 * math.sqrt(3.0), 1.0]), np.array([0.5, 0.5, 2.0]), 0.0, 1, 0)]  # at 60°
    prims = boxes(*wall, *side)
    origin = np.array([0.0, 0.0, 1.0])
    sector = cast_rays(origin, dirs, 45.0, prims, n_azimuth_bins=64, sector=True)
    full = cast_rays(origin, dirs, 45.0, prims)
    assert sector.index[odd] == 1 and (np.delete(sector.index, odd) == 0).all()
    np.testing.assert_array_equal(sector.index, full.index)
    np.testing.assert_array_equal(sector.distance, full.distance)


# --------------------------------------------------------------------------------------------- LiDAR


def test_ray_pattern_follows_carla():
    cfg = LidarConfig.fogdrive()
    el, az = cfg.ray_angles(20)
    assert cfg.points_per_channel(20) == 1016 == len(az)  # 1.3e6 / (20 · 64) = 1015.6 → 1016
    np.testing.assert_allclose(el, np.linspace(5.0, -20.0, 64))
    np.testing.assert_allclose(np.diff(az), 360.0 / 1016)
    assert az[0] == -180.0 and az[-1] < 180.0
    # a 10 Hz head at 20 Hz sweeps half a turn per tick
    el, az = LidarConfig.fogdrive(rotation_frequency=10.0).ray_angles(20)
    assert az.max() - az.min() == pytest.approx(180.0 - 180.0 / 1016)
    assert lidar_directions(cfg).shape == (64 * 1016, 3)


@pytest.mark.parametrize("semantic", [False, True])
def test_flat_ground_rings_at_analytic_range(semantic):
    cfg = (LidarConfig.fogdrive_semantic() if semantic else LidarConfig.fogdrive(**NO_DROP))
    pts = (simulate_semantic_lidar(cfg, sensor_to_world(cfg.pose), Primitives.empty(), ROAD) if semantic
           else simulate_lidar(cfg, sensor_to_world(cfg.pose), Primitives.empty(), ROAD, np.random.default_rng(0)))
    el, az = cfg.ray_angles(20)
    rng_ = np.linalg.norm(pts[:, :3].astype(np.float64), axis=1)
    elev = np.degrees(np.arcsin(pts[:, 2] / rng_))
    ring = np.abs(elev[:, None] - el[None, :]).argmin(1)
    analytic = 2.0 / np.sin(np.radians(-el))
    np.testing.assert_allclose(rng_, analytic[ring], rtol=2e-6)
    np.testing.assert_allclose(pts[:, 2], -2.0, atol=1e-4)
    expected = np.where((el < 0) & (analytic < cfg.range), len(az), 0)
    np.testing.assert_array_equal(np.bincount(ring, minlength=len(el)), expected)
    if semantic:
        assert set(pts[:, 5].tolist()) == {1.0} and set(pts[:, 4].tolist()) == {0.0}
        np.testing.assert_allclose(pts[:, 3], 2.0 / rng_, rtol=1e-5)  # cos incidence on the ground = sin(−elev)


@pytest.mark.parametrize("ego", [(0.0, 0.0, 0.0), (100.0, -40.0, math.pi / 2)])
def test_lone_box_at_known_distance(ego):
    """Box 18–22 m ahead, 2–4 m right: returns lie on its rear or left face, with its tag and id, in any ego pose."""
    to_world = yaw_transform(*ego)
    center = transform_points(to_world, np.array([20.0, 3.0, 1.0]))
    prims = boxes((center, (2.0, 1.0, 1.0), ego[2], 14, 7))
    cfg = LidarConfig.fogdrive_semantic()
    pts = simulate_semantic_lidar(cfg, sensor_to_world(cfg.pose, ego), prims, ROAD)
    car = pts[pts[:, 4] == 7].astype(np.float64)
    assert len(car) > 50 and set(car[:, 5].tolist()) == {14.0}
    x, y, z = car[:, 0], car[:, 1], car[:, 2]
    rear, side = np.abs(x - 18.0) < 1e-3, np.abs(y - 2.0) < 1e-3
    assert np.all(rear | side) and rear.sum() > 20 and side.sum() > 20
    assert np.all((x > 18 - 1e-3) & (x < 22 + 1e-3) & (y > 2 - 1e-3) & (y < 4 + 1e-3) & (z > -2 - 1e-3) & (z < 1e-3))
    unit = car[:, :3] / np.linalg.norm(car[:, :3], axis=1, keepdims=True)
    np.testing.assert_allclose(car[rear, 3], np.abs(unit[rear, 0]), atol=1e-5)
    np.testing.assert_allclose(car[side, 3], np.abs(unit[side, 1]), atol=1e-5)
    # nothing else stands on the road: all other returns are ground
    assert np.allclose(pts[pts[:, 4] == 0, 2], -2.0, atol=1e-3)
    # the plain LiDAR sees the same face
    lcfg = LidarConfig.fogdrive(**NO_DROP)
    lpts = simulate_lidar(lcfg, sensor_to_world(lcfg.pose, ego), prims, ROAD, np.random.default_rng(0))
    on_box = lpts[lpts[:, 2] > -2 + 1e-3]
    assert len(on_box) > 50 and np.all((np.abs(on_box[:, 0] - 18) < 1e-3) | (np.abs(on_box[:, 1] - 2) < 1e-3))


def test_ground_tags_follow_surface_map():
    grid = np.zeros((400, 400), np.uint8)
    grid[:, 200:] = 1  # road for x >= 0
    grid[195:205, 200:] = 3  # a marking stripe along y ∈ [-5, 5)
    grid[:, 150:200] = 2  # sidewalk for x ∈ [-50, 0)
    surface = SurfaceMap(grid, (-200.0, -200.0), 1.0)
    cfg = LidarConfig.fogdrive_semantic()
    T = sensor_to_world(cfg.pose, (3.0, 2.0, 0.4))
    pts = simulate_semantic_lidar(cfg, T, Primitives.empty(), surface)
    world = transform_points(T, pts[:, :3])
    np.testing.assert_array_equal(pts[:, 5], SURFACE_TAGS[surface.class_at(world[:, 0], world[:, 1])])
    assert set(pts[:, 5].tolist()) == {10.0, 1.0, 2.0, 24.0}


def test_counts_per_sweep_match_rate():
    T = sensor_to_world(Pose(0, 0, 2))
    lidar = simulate_lidar(LidarConfig.fogdrive(**NO_DROP), T, enclosure(), ROAD, np.random.default_rng(0))
    semantic = simulate_semantic_lidar(LidarConfig.fogdrive_semantic(), T, enclosure(), ROAD)
    assert len(lidar) == 64 * 1016  # 1.3 M pts/s at 20 Hz: every ray of the sweep returns
    assert len(semantic) == 64 * 586  # 750 k pts/s at 20 Hz
    half = simulate_lidar(LidarConfig.fogdrive(rotation_frequency=10.0, **NO_DROP), T, enclosure(), ROAD,
                          np.random.default_rng(0))  # fmt: skip
    assert len(half) == 64 * 1016 and np.all(half[:, 1] <= 1e-3)  # half a turn from −180° covers the left, y ≤ 0
    small = LidarConfig(channels=16, points_per_second=100_000, range=100.0, **NO_DROP)
    assert len(simulate_lidar(small, T, enclosure(), ROAD, np.random.default_rng(0), simulation_frequency=10)) == 10000


def test_intensity_is_atmospheric_attenuation():
    cfg = LidarConfig.fogdrive(**NO_DROP)
    pts = simulate_lidar(cfg, sensor_to_world(cfg.pose), enclosure(), ROAD, np.random.default_rng(0))
    d = np.linalg.norm(pts[:, :3].astype(np.float64), axis=1)
    np.testing.assert_allclose(pts[:, 3], np.exp(-0.004 * d), rtol=2e-6)
    assert d.min() < 6.0 and d.max() > 40.0


def test_noise_moves_points_along_their_ray():
    clean = LidarConfig.fogdrive(**NO_DROP)
    noisy = LidarConfig.fogdrive(noise_stddev=0.1, **NO_DROP)
    T = sensor_to_world(clean.pose)
    a = simulate_lidar(clean, T, enclosure(), ROAD, np.random.default_rng(0)).astype(np.float64)
    b = simulate_lidar(noisy, T, enclosure(), ROAD, np.random.default_rng(0)).astype(np.float64)
    ra, rb = np.linalg.norm(a[:, :3], axis=1), np.linalg.norm(b[:, :3], axis=1)
    np.testing.assert_allclose(a[:, :3] / ra[:, None], b[:, :3] / rb[:, None], atol=1e-5)  # same rays
    assert np.std(rb - ra) == pytest.approx(0.1, rel=0.05)
    np.testing.assert_array_equal(a[:, 3], b[:, 3])  # intensity from the exact distance


def test_dropoff_statistics_match_carla_rule():
    """General drop-off thins rays by 1 − rate; intensity drop-off keeps weak returns with α·I + β."""
    T = sensor_to_world(Pose(0, 0, 2))
    n_rays = 64 * 1016
    general = simulate_lidar(LidarConfig.fogdrive(dropoff_general_rate=0.45, dropoff_zero_intensity=0.0), T,
                             enclosure(), ROAD, np.random.default_rng(1))  # fmt: skip
    p = 0.55
    assert abs(len(general) - n_rays * p) < 5 * math.sqrt(n_rays * p * (1 - p))
    # strong attenuation so that most returns fall under the 0.8 limit
    full = simulate_lidar(LidarConfig.fogdrive(atmosphere_attenuation_rate=0.03, **NO_DROP), T, enclosure(), ROAD,
                          np.random.default_rng(0))  # fmt: skip
    cfg = LidarConfig.fogdrive(atmosphere_attenuation_rate=0.03, dropoff_general_rate=0.0)
    kept = simulate_lidar(cfg, T, enclosure(), ROAD, np.random.default_rng(2))
    intensity = full[:, 3].astype(np.float64)
    weak = intensity <= 0.8
    assert weak.mean() > 0.5
    p_keep = 0.4 / 0.8 * intensity[weak] + 0.6
    expected, sd = p_keep.sum(), math.sqrt((p_keep * (1 - p_keep)).sum())
    assert abs((kept[:, 3] <= 0.8).sum() - expected) < 5 * sd
    assert (kept[:, 3] > 0.8).sum() == (~weak).sum()  # strong returns are always kept
    # fraction kept per intensity band follows α·I + β
    for lo, hi in [(0.1, 0.3), (0.3, 0.5), (0.5, 0.8)]:
        n_full = ((intensity > lo) & (intensity <= hi)).sum()
        n_kept = ((kept[:, 3] > lo) & (kept[:, 3] <= hi)).sum()
        q = (0.5 * intensity[(intensity > lo) & (intensity <= hi)] + 0.6).mean()
        assert abs(n_kept / n_full - q) < 5 * math.sqrt(q * (1 - q) / n_full)


# --------------------------------------------------------------------------------------------- radar


def test_radar_velocity_sign_and_geometry():
    """Ego at 20 m/s; the car ahead at 10 m/s approaches (v < 0), at 30 m/s it recedes (v > 0)."""
    cfg = RadarConfig.fogdrive()
    T = sensor_to_world(cfg.pose)
    target = boxes(((30.0, 0.0, 0.75), (2.3, 0.95, 0.75), 0.0, 14, 5), ((20.0, 12.0, 2.0), (5.0, 0.5, 2.0), 0.0, 28, 0))
    ego_v = np.array([20.0, 0.0, 0.0])
    for v_target, sign in [(10.0, -1), (30.0, 1)]:
        det = simulate_radar(cfg, T, target, np.random.default_rng(0), {5: (v_target, 0.0, 0.0)}, ego_v)
        assert len(det) > 5
        vel, az, alt, depth = det.T.astype(np.float64)
        unit_x = np.cos(alt) * np.cos(az)
        np.testing.assert_allclose(vel, (v_target - 20.0) * unit_x, atol=1e-4)
        assert np.all(np.sign(vel) == sign)
        x = depth * unit_x  # sensor frame: rear face of the target at 30 − 2.3 − 2 = 25.7 m
        assert np.all((x > 25.7 - 1e-3) & (x < 30.3 - 2 + 1e-3))
        assert np.all(np.abs(depth * np.cos(alt) * np.sin(az)) < 0.95 + 1e-3)  # no detection of the static wall


def test_radar_velocity_inputs_agree():
    cfg = RadarConfig.fogdrive()
    prims = boxes(((25.0, 1.0, 0.75), (2.3, 0.95, 0.75), 0.2, 14, 3))
    state = VehicleState(np.array([1, 3], np.int32), np.zeros(2, np.int8), np.zeros((2, 3)), np.ones((2, 3)),
                         np.zeros(2), np.array([[5.0, 0, 0], [-4.0, 1.0, 0]]), np.ones((2, 3)))  # fmt: skip
    args = (cfg, sensor_to_world(cfg.pose), prims)
    a = simulate_radar(*args, np.random.default_rng(4), {3: (-4.0, 1.0, 0.0)}, (5.0, 0, 0))
    b = simulate_radar(*args, np.random.default_rng(4), (state.ids, state.velocities), (5.0, 0, 0))
    c = simulate_radar(*args, np.random.default_rng(4), state, (5.0, 0, 0))
    assert len(a) > 0 and np.all(a[:, 0] < 0)
    assert a.tobytes() == b.tobytes() == c.tobytes()
    assert cfg.rays_per_tick(20) == 900


# --------------------------------------------------------------------------------------------- invariants


def _tick(prims, seed):
    rng = np.random.default_rng(seed)
    lc, rc = LidarConfig.fogdrive(noise_stddev=0.02), RadarConfig.fogdrive()
    return (simulate_lidar(lc, sensor_to_world(lc.pose), prims, ROAD, rng),
            simulate_semantic_lidar(LidarConfig.fogdrive_semantic(), sensor_to_world(lc.pose), prims, ROAD, rng),
            simulate_radar(rc, sensor_to_world(rc.pose), prims, rng, {5: (3.0, 0, 0)}, (10.0, 0, 0)))  # fmt: skip


def _street():
    rng = np.random.default_rng(11)
    rows = [((x, rng.choice([-4.0, 0.0, 4.0]), 0.75), (2.3, 0.95, 0.75), 0.0, 14, i + 2)
            for i, x in enumerate(np.linspace(-100, 100, 24))]  # fmt: skip
    rows += [((x, s * 15.0, 4.0), (6.0, 4.0, 4.0), 0.1, 3, 0) for x in np.linspace(-110, 110, 20) for s in (-1, 1)]
    return boxes(*rows)


def test_determinism_by_seed():
    a, b, c = _tick(_street(), 5), _tick(_street(), 5), _tick(_street(), 6)
    for x, y in zip(a, b):
        assert x.dtype == np.float32 and x.tobytes() == y.tobytes()
    assert a[0].tobytes() != c[0].tobytes() and a[2].tobytes() != c[2].tobytes()
    assert a[1].tobytes() == c[1].tobytes()  # the semantic LiDAR draws nothing
    assert a[0].shape[1] == 4 and a[1].shape[1] == 6 and a[2].shape[1] == 4


def test_boxes_out_of_range_do_not_change_the_result():
    near = _street()
    for x, y in zip(_tick(near, 9), _tick(concat(near, far_boxes()), 9)):
        assert x.tobytes() == y.tobytes()


def test_sensor_inside_a_box_sees_through_it():
    ego = boxes(((0.0, 0.0, 1.0), (2.4, 1.1, 1.0), 0.0, 14, 1))
    cfg = RadarConfig.fogdrive(pose=Pose(1.0, 0.0, 1.0))  # inside the ego's box
    T = sensor_to_world(cfg.pose)
    target = boxes(((30.0, 0.0, 0.75), (2.3, 0.95, 0.75), 0.0, 14, 5))
    a = simulate_radar(cfg, T, target, np.random.default_rng(0))
    b = simulate_radar(cfg, T, concat(ego, target), np.random.default_rng(0))
    assert len(a) > 0 and a.tobytes() == b.tobytes()


BAD_LIDAR = [
    ("channels", 0), ("channels", 2.5), ("channels", True), ("range", 0.0), ("range", float("nan")),
    ("points_per_second", -1), ("rotation_frequency", 0), ("upper_fov", 95.0), ("lower_fov", -91.0),
    ("upper_fov", -30.0),  # not above the default lower_fov
    ("horizontal_fov", 0.0), ("horizontal_fov", 361.0), ("dropoff_general_rate", 1.5),
    ("dropoff_intensity_limit", -0.1), ("dropoff_zero_intensity", 2.0), ("atmosphere_attenuation_rate", -0.004),
    ("noise_stddev", -1.0), ("noise_stddev", "x"), ("pose", (1, 2)),
]  # fmt: skip
BAD_RADAR = [("range", -5), ("points_per_second", 0), ("horizontal_fov", 0), ("vertical_fov", 180), ("pose", "front")]


@pytest.mark.parametrize("name, value", BAD_LIDAR)
def test_bad_lidar_config_raises(name, value):
    with pytest.raises(ValueError, match=rf"^{name}\b"):
        LidarConfig(**{name: value})


@pytest.mark.parametrize("name, value", BAD_RADAR)
def test_bad_radar_config_raises(name, value):
    with pytest.raises(ValueError, match=rf"^{name}\b"):
        RadarConfig(**{name: value})


def test_bad_call_arguments_raise():
    cfg = LidarConfig.fogdrive()
    with pytest.raises(ValueError, match="simulation_frequency"):
        simulate_lidar(cfg, np.eye(4), Primitives.empty(), ROAD, np.random.default_rng(0), simulation_frequency=0)
    with pytest.raises(ValueError, match="sensor_to_world"):
        simulate_semantic_lidar(cfg, np.eye(3), Primitives.empty(), ROAD)
    with pytest.raises(ValueError, match="max_range"):
        cast_rays(np.zeros(3), np.ones((1, 3)), -1.0, Primitives.empty())


@settings(max_examples=40, deadline=None)
@given(n=st.integers(0, 300), rate=st.floats(0.0, 1.0), seed=st.integers(0, 2**32 - 1))
def test_the_rays_the_general_drop_off_keeps_are_numpys_comparison_and_take(n, rate, seed):
    from fog_gym.sensors.lidar import _kept_rays

    rng = np.random.default_rng(seed)
    u, dirs = rng.random(n), rng.normal(size=(n, 3))
    dirs.flags.writeable = False  # as the cached ray pattern is
    rays, kept = _kept_rays(u, rate, dirs)
    want = np.flatnonzero(u >= rate)
    assert rays.dtype == want.dtype and np.array_equal(rays, want)
    assert kept.dtype == dirs.dtype and np.array_equal(kept, dirs.take(want, axis=0))


@functools.lru_cache(maxsize=1)
def _azimuth_pair():
    from numba import njit

    from fog_gym.sensors.raycast import _pseudo_azimuth, _pseudo_azimuth_select

    return njit(lambda a, b: (_pseudo_azimuth(a, b), _pseudo_azimuth_select(a, b)))


_EDGES = [0.0, -0.0, 1.0, -1.0, 1e-300, -1e-300, 5e-324, -5e-324, 1e300, -1e300]


@settings(max_examples=80, deadline=None)
@given(x=st.one_of(st.sampled_from(_EDGES), st.floats(-1e6, 1e6, allow_nan=False)),
       y=st.one_of(st.sampled_from(_EDGES), st.floats(-1e6, 1e6, allow_nan=False)))
def test_the_casts_branch_free_pseudo_azimuth_is_the_same_number_as_the_branching_one(x, y):
    want, got = _azimuth_pair()(x, y)
    assert np.float64(got).tobytes() == np.float64(want).tobytes()

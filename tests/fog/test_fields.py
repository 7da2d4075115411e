"""Fog fields (fog_gym.fog.fields): validated parameters, closed-form optical depth against quadrature, and the
camera and LiDAR physics with a field's local extinction."""

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numba import njit

from fog_gym.fog import fog_images, fog_lidar, parse_fog
from fog_gym.fog.camera import fog_field_images
from fog_gym.fog.depth import _depths, field_pose, origin_constants, origin_depth
from fog_gym.fog.fields import FogBank, FogSum, HeightFog, Homogeneous, field_from_info, field_json
from fog_gym.fog.lidar import BETA_PER_MOR, GAMMA, SPEED_OF_LIGHT, TAU_H, XI_R1, XI_R2, soft_response_table
from fog_gym.fog.lidar_field import KAPPA, fog_lidar_field

LN20 = math.log(20.0)


@njit(cache=False)
def _origin_depths(terms, consts, u0, z0, du, dz, lengths, out):
    for i in range(lengths.shape[0]):
        out[i] = origin_depth(terms, consts, u0, z0, du, dz, lengths[i])


def quad_depth(field, u0, z0, du, dz, length, n=200_001):
    """τ by the trapezoid rule on a fine grid (the reference for the closed forms)."""
    s = np.linspace(0.0, length, n)
    return float(np.trapezoid(field.beta(u0 + s * du, z0 + s * dz), s))


# -- the fields ---------------------------------------------------------------------------------------------------


def test_homogeneous_is_todays_fog_and_names_its_channel():
    assert Homogeneous(50.0) == parse_fog("dense") == parse_fog(50.0)
    assert Homogeneous(75.0, name="haze").channel_suffix == "FOG_HAZE"
    assert FogBank(30.0, 100.0, 50.0, name="wall").channel_suffix == "FOG_WALL"


@pytest.mark.parametrize("make, word", [
    (lambda: HeightFog(0.0, 10.0), "visibility"), (lambda: HeightFog(float("nan"), 10.0), "visibility"),
    (lambda: HeightFog(50.0, 0.0), "scale_height"), (lambda: HeightFog(50.0, -2.0), "scale_height"),
    (lambda: FogBank(-1.0, 10.0, 5.0), "visibility"), (lambda: FogBank(50.0, 10.0, -5.0), "length"),
    (lambda: FogBank(50.0, 10.0, 5.0, edge=-1.0), "edge"), (lambda: FogBank(50.0, float("inf"), 5.0), "start"),
    (lambda: FogBank(50.0, 10.0, 5.0, background=0.0), "background"),
    (lambda: FogBank(50.0, 10.0, 5.0, name="a b"), "name"),
])  # fmt: skip
def test_bad_parameters_raise_a_value_error_naming_the_parameter(make, word):
    with pytest.raises(ValueError, match=word):
        make()


def test_fields_are_hashable_and_their_description_reads_back():
    f = HeightFog(80.0, 5.0) + FogBank(30.0, 120.0, 60.0, edge=10.0, velocity=-2.0, name="wall")
    assert isinstance(f, FogSum) and len({f, f}) == 1
    assert field_from_info(json.loads(field_json(f))) == f
    assert (f + Homogeneous(200.0)).terms[-1] == parse_fog(200.0)  # sums flatten


def test_a_bank_has_full_strength_inside_ramps_centred_on_its_faces_and_its_background_outside():
    b = FogBank(50.0, start=100.0, length=50.0, edge=20.0, background=500.0)
    beta_in, beta_bg = LN20 / 50.0, LN20 / 500.0
    got = b.beta(np.array([80.0, 100.0, 110.0, 150.0, 170.0]), 0.0)
    assert got == pytest.approx([beta_bg, (beta_in + beta_bg) / 2, beta_in, (beta_in + beta_bg) / 2, beta_bg])
    short = FogBank(50.0, start=100.0, length=10.0, edge=20.0)  # the ramps meet: a tent of peak (L + e) / 2e
    assert float(short.beta(105.0, 0.0)) == pytest.approx(beta_in * 30.0 / 40.0)
    drift = FogBank(50.0, start=100.0, length=50.0, velocity=5.0)
    assert float(drift.beta(100.0, 0.0, time=4.0)) == 0.0 and float(drift.beta(130.0, 0.0, time=4.0)) == pytest.approx(beta_in)


def test_height_fog_thins_with_height_and_is_constant_below_the_road():
    f = HeightFog(50.0, 10.0)
    assert f.beta(0.0, np.array([-3.0, 0.0, 10.0, 20.0])) == pytest.approx(LN20 / 50 * np.exp([0.0, 0.0, -1.0, -2.0]))


@given(u0=st.floats(-200, 200), z0=st.floats(-1.0, 8.0), azimuth=st.floats(-math.pi, math.pi),
       elevation=st.floats(-0.6, 0.6), length=st.floats(0.1, 400.0), edge=st.sampled_from([0.0, 0.5, 20.0]),
       height=st.floats(0.5, 40.0))  # fmt: skip
@settings(max_examples=60, deadline=None)
def test_closed_form_optical_depth_equals_quadrature_on_random_rays(u0, z0, azimuth, elevation, length, edge, height):
    du, dz = math.cos(elevation) * math.cos(azimuth), math.sin(elevation)
    field = HeightFog(60.0, height) + FogBank(40.0, 30.0, 25.0, edge=edge, background=800.0) + Homogeneous(900.0)
    closed = float(field.optical_depth(u0, z0, du, dz, length))
    assert closed == pytest.approx(quad_depth(field, u0, z0, du, dz, length), rel=1e-4, abs=1e-6)


@given(u0=st.floats(-200, 200), z0=st.floats(-1.0, 8.0), azimuth=st.floats(-math.pi, math.pi),
       elevation=st.floats(-0.6, 0.6), lengths=st.lists(st.floats(0.0, 400.0), min_size=1, max_size=8),
       edge=st.sampled_from([0.0, 0.5, 20.0]), height=st.floats(0.5, 40.0))  # fmt: skip
@settings(max_examples=60, deadline=None)
def test_depth_from_a_sensors_constants_is_segment_depth(u0, z0, azimuth, elevation, lengths, edge, height):
    du, dz = math.cos(elevation) * math.cos(azimuth), math.sin(elevation)
    banks = (FogBank(40.0, 30.0, 25.0, edge=edge, background=800.0) + FogBank(60.0, -50.0, 70.0, edge=edge)).pack(0.0)
    mixed = (HeightFog(60.0, height) + FogBank(40.0, 30.0, 25.0, edge=edge) + Homogeneous(900.0)).pack(0.0)
    ls = np.array(lengths)
    for terms, exact in ((banks, True), (mixed, False)):
        got, want = np.empty(len(ls)), np.empty(len(ls))
        _origin_depths(terms, origin_constants(terms, u0, z0), u0, z0, du, dz, ls, got)
        _depths(terms, np.full(len(ls), u0), np.full(len(ls), z0), np.full(len(ls), du), np.full(len(ls), dz), ls, want)
        if exact:  # banks and homogeneous terms: segment_depth's bits (the start's integral read, not recomputed)
            assert np.array_equal(got, want)
        else:  # height terms: one exponential, not two; the same to rounding
            np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-300)


def test_a_banks_edge_to_zero_limit_is_the_step():
    rays = (0.0, 1.0, 0.8, 0.0, 200.0)
    step = float(FogBank(50.0, 60.0, 40.0, edge=0.0).optical_depth(*rays))
    assert step == pytest.approx(40.0 / 0.8 * LN20 / 50.0)  # 40 m of bank crossed at 0.8 m along u per metre
    assert [float(FogBank(50.0, 60.0, 40.0, edge=e).optical_depth(*rays)) for e in (1e-3, 1e-6)] == \
        pytest.approx([step, step], rel=1e-6)  # fmt: skip


# -- the camera ---------------------------------------------------------------------------------------------------

W, H = 96, 64
K = np.array([[60.0, 0.0, W / 2], [0.0, 60.0, H / 2], [0.0, 0.0, 1.0]])
#: A camera 1.5 m above the road at the field's origin, looking along its heading (optical frame → world).
CAMERA = np.array([[0.0, 0.0, 1.0, 0.0], [-1.0, 0.0, 0.0, 0.0], [0.0, -1.0, 0.0, 1.5], [0.0, 0.0, 0.0, 1.0]])


def scene():
    rng = np.random.default_rng(3)
    rgb = rng.integers(0, 256, (H, W, 3), dtype=np.uint8)
    depth = np.where(np.arange(H)[:, None] > H / 2, 1.5 * 60.0 / np.maximum(np.arange(H)[:, None] + 0.5 - H / 2, 1e-3),
                     1000.0) * np.ones((1, W))  # the road below the horizon, sky above  # fmt: skip
    return rgb, depth.astype(np.float32)


def test_camera_pixels_follow_koschmieder_with_the_fields_optical_depth():
    rgb, depth = scene()
    airlight = np.array([180.0, 190.0, 200.0])
    fields = [FogBank(50.0, 30.0, 40.0, edge=10.0), HeightFog(40.0, 3.0)]
    out = fog_field_images(rgb, depth, K, fields, airlight, field_pose(CAMERA, (0.0, 0.0, 0.0)))
    v, u = np.mgrid[0:H, 0:W]
    ray = np.stack([(u + 0.5 - K[0, 2]) / K[0, 0], (v + 0.5 - K[1, 2]) / K[1, 1], np.ones((H, W))], -1)
    ell = depth * np.linalg.norm(ray, axis=-1)
    unit = (ray / np.linalg.norm(ray, axis=-1, keepdims=True)) @ CAMERA[:3, :3].T  # world directions
    for img, field in zip(out, fields):
        tau = field.optical_depth(0.0, 1.5, unit[..., 0], unit[..., 2], ell)
        expected = airlight + (rgb - airlight) * np.exp(-tau)[..., None]
        assert np.abs(img - expected).max() <= 0.51 + 1e-3  # rounding only


def test_a_bank_covering_everything_is_homogeneous_fog_within_one_level():
    rgb, depth = scene()
    airlight = np.array([150.0, 160.0, 170.0])
    everywhere = FogBank(50.0, -5000.0, 10000.0, edge=0.0)
    shaped = fog_field_images(rgb, depth, K, [everywhere], airlight, field_pose(CAMERA, (0.0, 0.0, 0.0)))[0]
    flat = fog_images(rgb, depth, K, [parse_fog("dense").alpha], airlight)[0]
    assert np.abs(shaped.astype(int) - flat).max() <= 1


def test_ground_fog_clears_upwards_and_a_bank_ahead_leaves_the_near_road_clear():
    rgb, depth = scene()
    airlight = np.full(3, 200.0)
    pose = field_pose(CAMERA, (0.0, 0.0, 0.0))
    ground, bank = fog_field_images(rgb, depth, K, [HeightFog(30.0, 2.0), FogBank(30.0, 60.0, 100.0, edge=0.0)], airlight,
                                    pose)  # fmt: skip
    grey = np.full_like(rgb, 100)
    g = fog_field_images(grey, depth, K, [HeightFog(30.0, 2.0)], airlight, pose)[0].astype(int)
    assert g[0, W // 2, 0] < g[H // 2 - 2, W // 2, 0]  # the sky straight up sees less fog than along the horizon
    near = depth < 50.0
    assert np.array_equal(bank[near], rgb[near])  # the road short of the bank is as in clear air
    assert np.abs(ground[near].astype(int) - rgb[near]).max() > 0


# -- the LiDAR ----------------------------------------------------------------------------------------------------

LIDAR = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, 1.0, 1.8], [0, 0, 0, 1.0]])  # 1.8 m up, along the heading


def direct_soft_maximum(field, du, dz, r0, z0=1.8, n=40_001):
    """``max_{R ≤ R0} F(R)`` and where, from the LiDAR equation with the local backscatter integrated directly (fine
    Simpson in t at every range node, closed-form τ): the reference of the field path."""
    t = np.linspace(0.0, 2 * TAU_H, n)
    w = np.ones(n)
    w[1:-1:2], w[2:-1:2] = 4.0, 2.0
    w *= (t[1] - t[0]) / 3.0
    pulse = np.sin(np.pi * t / (2 * TAU_H)) ** 2
    best, where = 0.0, 0.0
    for R in np.arange(0.0, r0 + 1e-9, 0.1):
        rp = R - SPEED_OF_LIGHT * t / 2
        xi = np.clip((rp - XI_R1) / (XI_R2 - XI_R1), 0.0, 1.0)
        ok = rp > XI_R1
        rr = np.where(ok, rp, 1.0)
        tau = field.optical_depth(0.0, z0, du, dz, np.maximum(rr, 0.0))
        beta = field.beta(rr * du, z0 + rr * dz)
        f = float(np.sum(w * np.where(ok, pulse * KAPPA * beta * np.exp(-2 * tau) * xi / rr**2, 0.0)))
        if f > best:
            best, where = f, R
    return best, where


@pytest.mark.parametrize("field, direction, r0", [
    (FogBank(40.0, 30.0, 20.0, edge=0.0), (1.0, 0.0), 70.0),
    (FogBank(60.0, 20.0, 200.0, edge=10.0, background=300.0), (0.9, -0.05), 45.0),
    (HeightFog(50.0, 4.0), (0.98, -0.04), 40.0),
    (HeightFog(50.0, 10.0) + FogBank(30.0, 25.0, 10.0, edge=2.0), (0.7, -0.02), 60.0),
])  # fmt: skip
def test_the_lidar_soft_return_equals_a_direct_integration_of_the_lidar_equation(field, direction, r0):
    du, dz = direction
    dy = math.sqrt(max(1.0 - du * du - dz * dz, 0.0))
    point = np.array([[r0 * du, r0 * dy, r0 * dz, 0.9]], np.float32)  # bright: the soft return is what decides
    best, where = direct_soft_maximum(field, du, dz, float(np.linalg.norm(point[0, :3])))
    out = fog_lidar_field(point, field, np.random.default_rng(0), field_pose(LIDAR, (0.0, 0.0, 0.0)), noise=0.0)
    i_orig = round(float(point[0, 3]) * 255)  # (the float32 intensity)
    r = float(np.linalg.norm(point[0, :3]))
    i_soft = min(255.0, best * i_orig * r * r * math.pi / GAMMA)
    if i_soft < 255.0 and np.linalg.norm(out[0, :3]) < r - 1e-3:  # replaced: the intensity is the soft return
        assert float(out[0, 3]) * 255.0 == pytest.approx(i_soft, rel=1e-3)
        assert float(np.linalg.norm(out[0, :3])) == pytest.approx(where, abs=0.11)
    else:
        assert best * i_orig * r * r * math.pi / GAMMA >= 255.0 or np.allclose(out[0, :3], point[0, :3])


def test_lidar_points_in_front_of_a_bank_are_as_in_clear_air_and_behind_a_dense_one_they_are_lost():
    rng = np.random.default_rng(1)
    r = rng.uniform(3.0, 120.0, 4000)
    az = rng.uniform(-0.6, 0.6, r.size)
    pts = np.c_[r * np.cos(az), r * np.sin(az), rng.uniform(-1.7, 0.5, r.size), rng.uniform(0.2, 1.0, r.size)]
    pts = pts.astype(np.float32)
    bank = FogBank(15.0, 60.0, 30.0, edge=0.0)
    out = fog_lidar_field(pts, bank, np.random.default_rng(2), field_pose(LIDAR, (0.0, 0.0, 0.0)), noise=0.0)
    front = pts[:, 0] < 59.0
    assert np.array_equal(out[front], pts[front])
    behind = pts[:, 0] > 95.0  # τ = 12 on the way: every return is the fog's own, from the bank's near face
    assert behind.sum() > 500 and np.all((out[behind, 0] > 59.9) & (out[behind, 0] < 66.0))


def test_a_bank_covering_everything_makes_the_homogeneous_lidar_decisions():
    rng = np.random.default_rng(4)
    r = rng.uniform(1.5, 120.0, 3000)
    az, el = rng.uniform(-np.pi, np.pi, r.size), rng.uniform(-0.35, 0.09, r.size)
    pts = np.c_[r * np.cos(el) * np.cos(az), r * np.cos(el) * np.sin(az), r * np.sin(el), np.exp(-0.004 * r)]
    pts = pts.astype(np.float32)
    flat = fog_lidar(pts, parse_fog("dense"), np.random.default_rng(0))
    shaped = fog_lidar_field(pts, FogBank(50.0, -5000.0, 10000.0, edge=0.0), np.random.default_rng(0),
                             field_pose(LIDAR, (0.0, 0.0, 0.0)))  # fmt: skip
    moved = lambda out: np.any(out[:, :3] != pts[:, :3], axis=1)  # noqa: E731
    assert np.array_equal(moved(flat), moved(shaped))
    assert np.abs(flat[:, 3] - shaped[:, 3]).max() <= 1.5 / 255


def test_same_seed_same_fogged_points_and_the_soft_maximum_matches_hahners_table_for_constant_fog():
    pts = np.array([[40.0, 3.0, -1.0, 0.5], [90.0, -5.0, 0.0, 0.8]], np.float32)
    pose = field_pose(LIDAR, (0.0, 0.0, 0.0))
    bank = HeightFog(50.0, 6.0)
    a = fog_lidar_field(pts, bank, np.random.default_rng(7), pose)
    assert np.array_equal(a, fog_lidar_field(pts, bank, np.random.default_rng(7), pose))
    I, _ = soft_response_table(parse_fog("dense").alpha)
    best, _ = direct_soft_maximum(FogBank(50.0, -5000.0, 10000.0, edge=0.0), 1.0, 0.0, 30.0)
    assert best == pytest.approx(I[-1] * BETA_PER_MOR / 50.0, rel=1e-3)  # κβ·I: Hahner et al.'s constant case


def test_ground_fog_reads_one_curve_per_beam_elevation_and_decides_as_each_beam_alone():
    from fog_gym.fog.lidar_field import FIELD_COARSE, FIELD_STEP, _hahner_field, field_pulse_weights, peak_extinction

    rng = np.random.default_rng(5)
    r = rng.uniform(2.0, 120.0, 6000)
    az = rng.uniform(-np.pi, np.pi, r.size)
    rig = rng.choice(np.linspace(-0.4, 0.1, 64), r.size)  # a rig's 64 elevations, and arbitrary ones
    for el in (rig, rng.uniform(-0.4, 0.1, r.size)):
        pts = np.c_[r * np.cos(el) * np.cos(az), r * np.cos(el) * np.sin(az), r * np.sin(el), rng.uniform(0.1, 1, r.size)]
        pts = pts.astype(np.float32)
        pose, field = field_pose(LIDAR, (0.0, 0.0, 0.0)), HeightFog(40.0, 4.0) + Homogeneous(400.0)
        curves = fog_lidar_field(pts, field, np.random.default_rng(1), pose, noise=0.0)
        alone = np.empty_like(pts)  # every beam integrated on its own (the path of fields with banks)
        _hahner_field(pts, pose, field.pack(), *field_pulse_weights(), *field_pulse_weights(FIELD_STEP * FIELD_COARSE),
                      FIELD_COARSE, FIELD_STEP, 0.0, np.zeros(len(pts)), alone, -1.0,
                      peak_extinction(field.pack()))  # fmt: skip
        moved = lambda out: np.any(out[:, :3] != pts[:, :3], axis=1)  # noqa: E731
        assert np.array_equal(moved(curves), moved(alone)) and 0.1 < moved(alone).mean() < 0.9
        assert np.abs(curves[:, 3] - alone[:, 3]).max() * 255 < 1e-2
        assert np.abs(curves[:, :3] - alone[:, :3]).max() < 0.11  # the fog return's range: within a node


@pytest.mark.parametrize("field, ego_u", [
    (FogBank(50.0, 60.0, 100.0), 0.0),  # ahead (the bench's)
    (FogBank(20.0, 30.0, 30.0, edge=0.0), 0.0),  # a wall
    (FogBank(50.0, -50.0, 100.0), 0.0),  # inside (its plateau: one curve serves every run)
    (FogBank(50.0, -50.0, 100.0), 38.0),  # inside, 2 m short of its far ramp (steep runs read their own curves)
    (FogBank(50.0, 0.5, 100.0), 0.0),  # at its face
    (FogBank(50.0, -120.0, 100.0), 0.0),  # past it
    (FogBank(60.0, 20.0, 200.0, edge=10.0, background=300.0), 0.0),  # in thinner fog
    (FogBank(50.0, 60.0, 100.0) + Homogeneous(500.0), 0.0),
    (FogBank(40.0, 40.0, 60.0, velocity=3.0), 25.0),  # drifting, the sensor moved along u
])  # fmt: skip
def test_a_bank_reads_curves_per_run_along_its_axis_and_decides_as_each_beam_alone(field, ego_u):
    from fog_gym.fog.lidar_field import FIELD_COARSE, FIELD_STEP, _hahner_field, field_pulse_weights, peak_extinction

    rng = np.random.default_rng(6)
    r = rng.uniform(1.5, 120.0, 20_000)
    az = rng.uniform(-np.pi, np.pi, r.size)
    el = rng.choice(np.linspace(-0.4, 0.1, 64), r.size)
    pts = np.c_[r * np.cos(el) * np.cos(az), r * np.cos(el) * np.sin(az), r * np.sin(el), rng.uniform(0.02, 1, r.size)]
    pts = pts.astype(np.float32)
    pose = field_pose(LIDAR @ np.r_[np.c_[np.eye(3), [ego_u, 0.0, 0.0]], [[0, 0, 0, 1]]], (0.0, 0.0, 0.0))
    curves = fog_lidar_field(pts, field, np.random.default_rng(1), pose, time=1.5, noise=0.0)
    alone = np.empty_like(pts)
    terms = field.pack(1.5)
    _hahner_field(pts, pose, terms, *field_pulse_weights(), *field_pulse_weights(FIELD_STEP * FIELD_COARSE),
                  FIELD_COARSE, FIELD_STEP, 0.0, np.zeros(len(pts)), alone, -1.0, peak_extinction(terms))  # fmt: skip
    moved = lambda out: np.any(out[:, :3] != pts[:, :3], axis=1)  # noqa: E731
    assert np.array_equal(moved(curves), moved(alone)) and moved(alone).mean() > 0.005
    assert np.abs(curves[:, 3] - alone[:, 3]).max() * 255 < 1e-2
    assert np.abs(np.linalg.norm(curves[:, :3], axis=1) - np.linalg.norm(alone[:, :3], axis=1)).max() < 0.35


@pytest.mark.parametrize("call, word", [
    (lambda: fog_field_images(*scene(), K, [HeightFog(50.0, 2.0)], np.full(3, 200.0), np.zeros(7)), "pose"),
    (lambda: fog_field_images(*scene(), K, [HeightFog(50.0, 2.0)], np.full(3, 200.0), np.full(8, np.nan)), "pose"),
    (lambda: fog_field_images(*scene(), K, [], np.full(3, 200.0), np.zeros(8)), "fields"),
    (lambda: fog_lidar_field(np.zeros((3, 4), np.float32), HeightFog(50.0, 2.0), np.random.default_rng(0),
                             np.zeros(5)), "pose"),  # fmt: skip
    (lambda: fog_lidar_field(np.zeros((3, 2), np.float32), HeightFog(50.0, 2.0), np.random.default_rng(0),
                             np.zeros(8)), "shape"),  # fmt: skip
])  # fmt: skip
def test_bad_inputs_of_the_field_physics_fail_before_any_work(call, word):
    with pytest.raises(ValueError, match=word):
        call()


@pytest.mark.parametrize("field", [
    HeightFog(50.0, 4.0) + FogBank(50.0, 40.0, 80.0),  # the grid of curves
    HeightFog(40.0, 3.0) + Homogeneous(400.0),  # the curves per beam elevation
    FogBank(50.0, 20.0, 40.0),  # the curves per run along a bank
])  # fmt: skip
def test_a_small_sweep_runs_the_field_kernels_serial_twins_with_the_same_bits(field, monkeypatch):
    import fog_gym._numba

    rng = np.random.default_rng(5)
    r = rng.uniform(1.5, 120.0, 3_000)
    az, el = rng.uniform(-np.pi, np.pi, r.size), rng.choice(np.linspace(-0.35, 0.09, 32), r.size)
    pts = np.c_[r * np.cos(el) * np.cos(az), r * np.cos(el) * np.sin(az), r * np.sin(el), rng.uniform(0.02, 1, r.size)]
    pts = pts.astype(np.float32)
    pose = field_pose(LIDAR, (0.0, 0.0, 0.0))
    rgb, depth = scene()
    runs = []
    for below in (0, 10**12):  # every kernel parallel, then every kernel on one thread
        monkeypatch.setattr(fog_gym._numba, "SERIAL_BELOW", below)
        runs.append((fog_lidar_field(pts, field, np.random.default_rng(1), pose),
                     fog_field_images(rgb, depth, K, [field], np.array([180.0, 190.0, 200.0]),
                                      field_pose(CAMERA, (0.0, 0.0, 0.0)))))  # fmt: skip
    assert np.array_equal(runs[0][0], runs[1][0]) and np.array_equal(runs[0][1], runs[1][1])
    assert np.any(runs[0][0][:, :3] != pts[:, :3])  # (the fog moved points)


@settings(max_examples=60, deadline=None)
@given(low=st.floats(0.02, 0.5), side=st.sampled_from([-1, 0, 1]), dist=st.floats(0.0, 200.0),
       fractions=st.lists(st.floats(0.0, 1.0), min_size=1, max_size=20))  # fmt: skip
def test_a_banks_run_table_finds_the_node_below_each_run_as_a_sorted_search_does(low, side, dist, fractions):
    from fog_gym.fog.lidar_bank import BANK_RATIO, _run_node, _run_tables

    nodes, lut, inv_width, inv_gap, faces = _run_tables(low, side, dist, BANK_RATIO)
    off = len(nodes) // 2 if side == 0 else 0  # inside: −runs reversed, then runs
    runs = nodes[off:]
    assert runs[0] == pytest.approx(low) and runs[-1] == 1.0 and np.all(np.diff(runs) > 0)
    np.testing.assert_allclose(inv_gap, 1.0 / np.diff(nodes))
    if side:
        np.testing.assert_allclose(faces, np.r_[dist / runs, 0.0])
    for g in low + np.array(fractions) * (1.0 - low):
        want = min(int(np.searchsorted(runs, g, side="right")) - 1, len(runs) - 2)
        got = _run_node(g, nodes, off, len(runs), lut, inv_width)
        # (at a bin's edge the table may pick the node just above g, where g lies within rounding of it)
        assert got == want or (got == want + 1 and runs[got] == pytest.approx(g, rel=1e-12))


@pytest.mark.parametrize("field, ego_u", [
    (HeightFog(50.0, 4.0) + FogBank(50.0, 40.0, 80.0), 0.0),  # ground fog under a bank (the bench's)
    (FogBank(50.0, 20.0, 40.0) + FogBank(80.0, 90.0, 60.0), 0.0),  # two banks ahead (the bench's)
    (FogBank(40.0, -30.0, 60.0) + FogBank(60.0, 50.0, 30.0) + Homogeneous(300.0), 0.0),  # inside one, another ahead
    (HeightFog(30.0, 2.0) + FogBank(60.0, -80.0, 60.0, edge=0.0), 10.0),  # past a wall, ground fog
    (FogBank(40.0, 40.0, 60.0, velocity=3.0) + HeightFog(80.0, 6.0) + FogBank(100.0, -60.0, 40.0), 25.0),
])  # fmt: skip
@pytest.mark.parametrize("n", [1_500, 20_000])  # a coarse grid (an RL sweep's) and a fine one
def test_sums_of_fields_read_a_grid_of_curves_and_decide_as_each_beam_alone(field, ego_u, n, monkeypatch):
    from fog_gym.fog import lidar_grid
    from fog_gym.fog.lidar_field import FIELD_COARSE, FIELD_STEP, _hahner_field, field_pulse_weights, peak_extinction
    from fog_gym.fog.lidar_grid import fog_lidar_grid

    rng = np.random.default_rng(7)
    r = rng.uniform(1.5, 120.0, n)
    az = rng.uniform(-np.pi, np.pi, r.size)
    el = rng.choice(np.linspace(-0.35, 0.09, 64), r.size)
    pts = np.c_[r * np.cos(el) * np.cos(az), r * np.cos(el) * np.sin(az), r * np.sin(el), rng.uniform(0.02, 1, r.size)]
    pts = pts.astype(np.float32)
    pose = field_pose(LIDAR @ np.r_[np.c_[np.eye(3), [ego_u, 0.0, 0.0]], [[0, 0, 0, 1]]], (0.0, 0.0, 0.0))
    terms = field.pack(1.5)
    grid = np.empty_like(pts)
    exact = fog_lidar_grid(pts, terms, pose, 0.0, np.zeros(len(pts)), grid, -1.0)
    alone = np.empty_like(pts)
    _hahner_field(pts, pose, terms, *field_pulse_weights(), *field_pulse_weights(FIELD_STEP * FIELD_COARSE),
                  FIELD_COARSE, FIELD_STEP, 0.0, np.zeros(len(pts)), alone, -1.0, peak_extinction(terms))  # fmt: skip
    moved = lambda out: np.any(out[:, :3] != pts[:, :3], axis=1)  # noqa: E731
    assert np.array_equal(moved(grid), moved(alone)) and moved(alone).mean() > 0.005
    assert exact < 0.05 * len(pts)  # the grid decides nearly every point
    assert np.abs(grid[:, 3] - alone[:, 3]).max() * 255 < 0.05  # the fog returns' intensity: a 20th of a level
    assert np.abs(np.linalg.norm(grid[:, :3], axis=1) - np.linalg.norm(alone[:, :3], axis=1)).max() < 5.0
    full = fog_lidar_field(pts, field, np.random.default_rng(1), pose, time=1.5, noise=0.0)  # the entry takes this path
    assert np.array_equal(full, grid)
    # each curve runs only as far as its farthest reader: bit for bit what curves run to the farthest point give
    for kernel in ("_node_tops", "_node_tops_serial"):
        monkeypatch.setattr(lidar_grid, kernel, lambda dus, dzs, ks, *cell_and_tops: cell_and_tops[-1].fill(ks.max()))
    far = np.empty_like(pts)
    assert fog_lidar_grid(pts, terms, pose, 0.0, np.zeros(len(pts)), far, -1.0) == exact and np.array_equal(far, grid)


@pytest.mark.parametrize("field, reflectance, digest", [
    (HeightFog(50.0, 4.0) + FogBank(50.0, 40.0, 80.0), None, "220f8cfcf8802530"),
    (HeightFog(50.0, 4.0) + FogBank(50.0, 40.0, 80.0), 0.004, "1756602be97df593"),
    (FogBank(50.0, 20.0, 40.0) + FogBank(80.0, 90.0, 60.0), None, "265134c84ba2d5fa"),
    (FogBank(50.0, 20.0, 40.0) + FogBank(80.0, 90.0, 60.0), 0.004, "72d3d04f59a3742e"),
])  # fmt: skip
def test_the_grid_path_gives_the_points_it_gave_before_its_vector_loops(field, reflectance, digest):
    # Digests recorded with the grid path of 2026-12-03 (commit f11d9c6, before τ, the hard return and the rule moved
    # into loops that vectorise, with vexp, and before the corners' agreement became a flag): the same bits — vexp's
    # last-place differences never reach a 0–255 level.
    import hashlib

    rng = np.random.default_rng(11)
    n = 30_000
    r, az, el = rng.uniform(1.5, 120.0, n), rng.uniform(-np.pi, np.pi, n), rng.choice(np.linspace(-0.35, 0.09, 64), n)
    pts = np.c_[r * np.cos(el) * np.cos(az), r * np.cos(el) * np.sin(az), r * np.sin(el), rng.uniform(0.02, 1, n)]
    pose = field_pose(LIDAR @ np.eye(4), (0.0, 0.0, 0.0))
    out = fog_lidar_field(pts.astype(np.float32), field, np.random.default_rng(3), pose, reflectance=reflectance)
    assert hashlib.sha256(out.tobytes()).hexdigest()[:16] == digest


@pytest.mark.parametrize("field, digest", [
    (HeightFog(50.0, 4.0) + FogBank(50.0, -40.0, 80.0), "ae33540d6ec8d0e3"),
    (FogBank(50.0, -20.0, 40.0) + FogBank(80.0, 90.0, 60.0), "03d544d7716b6ab8"),
])  # fmt: skip
def test_beams_across_a_banks_axis_give_the_points_they_gave_before(field, digest):
    # A beam whose run along the bank's axis is under 1 µm takes the bank's value where it runs (origin_depth's branch,
    # taken after the block's vector loop): digests recorded at commit f11d9c6, as the test above.
    import hashlib

    from fog_gym.fog.lidar_grid import fog_lidar_grid

    rng = np.random.default_rng(5)
    n = 20_000
    r, az, el = rng.uniform(1.5, 120.0, n), rng.uniform(-np.pi, np.pi, n), rng.choice(np.linspace(-0.35, 0.09, 64), n)
    pts = np.c_[r * np.cos(el) * np.cos(az), r * np.cos(el) * np.sin(az), r * np.sin(el), rng.uniform(0.02, 1, n)]
    pts[:3000, 0] = 0.0  # across the banks' axis (u along x): a run of 0, and of under 1e-8 m per metre
    pts[3000:4000, 0] = rng.uniform(-1e-8, 1e-8, 1000)
    pts = pts.astype(np.float32)
    out = np.empty_like(pts)
    pose = field_pose(LIDAR, (0.0, 0.0, 0.0))
    fog_lidar_grid(pts, field.pack(1.0), pose, math.log(2.0), rng.uniform(-1, 1, n), out, -1.0)
    assert np.any(out[:4000, :3] != pts[:4000, :3], axis=1).mean() > 0.4  # the fog reaches them
    assert hashlib.sha256(out.tobytes()).hexdigest()[:16] == digest

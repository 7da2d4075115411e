"""Fog physics oracles (research note fog_physics.md §6); the wrapper is tested in test_wrapper_fog.py."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import fog_gym
from fog_gym.fog import alpha_from_visibility, atmospheric_light, fog_image, fog_lidar, lidar_crossover_range, parse_fog, ray_length_factor, soft_response_table  # fmt: skip

CROSSOVER = {"light": 91.3, "moderate": 62.5, "dense": 35.6}


def test_alpha_of_visibility():
    assert alpha_from_visibility(50) == pytest.approx(0.059915, abs=1e-6)
    assert alpha_from_visibility(100) == pytest.approx(0.029957, abs=1e-6)
    assert alpha_from_visibility(160) == pytest.approx(0.018723, abs=1e-6)
    assert alpha_from_visibility(math.inf) == 0.0
    assert parse_fog("moderate").visibility_m == 100.0 and parse_fog(75).name == "75m"


@pytest.mark.parametrize(
    "alpha, value, r_tmp, at2, at3",
    [(0.02, 4.347e-9, 4.70, 3.613e-10, 1.940e-9), (0.03, 4.206e-9, 4.70, 3.531e-10, 1.890e-9),
     (0.06, 3.816e-9, 4.60, 3.299e-10, 1.749e-9), (0.1, 3.362e-9, 4.60, 3.012e-10, 1.578e-9)],
)  # fmt: skip
def test_soft_integral_matches_reference_tables(alpha, value, r_tmp, at2, at3):
    I, R = soft_response_table(alpha)
    assert I[-1] == pytest.approx(value, rel=1e-3) and I[50] == pytest.approx(value, rel=1e-3)  # constant ≥ 5 m
    assert R[-1] == pytest.approx(r_tmp, abs=0.06)
    assert I[20] == pytest.approx(at2, rel=2e-3) and I[30] == pytest.approx(at3, rel=2e-3)
    assert np.all(I[:11] == 0.0)  # R0 ≤ 1.0 m


@pytest.mark.parametrize("name", ["light", "moderate", "dense"])
def test_lidar_crossover(name):
    assert lidar_crossover_range(parse_fog(name)) == pytest.approx(CROSSOVER[name], abs=0.1)


def _cloud(n=20000, seed=0):
    rng = np.random.default_rng(seed)
    r = rng.uniform(1.5, 120.0, n)
    az, el = rng.uniform(-np.pi, np.pi, n), rng.uniform(-0.3, 0.08, n)
    xyz = np.c_[r * np.cos(el) * np.cos(az), r * np.cos(el) * np.sin(az), r * np.sin(el)]
    return np.c_[xyz, np.exp(-0.004 * r)].astype(np.float32)


@pytest.mark.parametrize("name", ["light", "moderate", "dense"])
def test_lidar_fog_rule(name):
    level = parse_fog(name)
    pts = _cloud()
    out = fog_lidar(pts, level, np.random.default_rng(1))
    assert out.shape == pts.shape and out.dtype == np.float32  # N out = N in
    r0 = np.linalg.norm(pts[:, :3].astype(np.float64), axis=1)
    moved = np.any(out[:, :3] != pts[:, :3], axis=1)
    assert np.all(moved[r0 > 1.2 * CROSSOVER[name]])  # everything far enough becomes fog
    kept = ~moved
    i255 = np.round(pts[kept, 3].astype(np.float64) * 255)
    np.testing.assert_allclose(out[kept, 3] * 255, np.round(i255 * np.exp(-2 * level.alpha * r0[kept])), atol=1e-3)
    # fog returns stay on their own ray, near the sensor (R_tmp · 2^u, u ∈ [−1, 1]), with intensity ≤ 255
    d_in = pts[moved, :3] / r0[moved, None]
    r_out = np.linalg.norm(out[moved, :3].astype(np.float64), axis=1)
    np.testing.assert_allclose(out[moved, :3] / r_out[:, None], d_in, atol=1e-5)
    assert r_out.max() <= 2 * 4.71 + 1e-3 and out[:, 3].max() <= 1.0


def test_replaced_fraction_monotone_in_alpha():
    pts = _cloud()
    fractions = []
    for v in (400, 160, 100, 50, 30):
        out = fog_lidar(pts, parse_fog(v), np.random.default_rng(0))
        fractions.append(np.mean(np.any(out[:, :3] != pts[:, :3], axis=1)))
    assert fractions == sorted(fractions) and fractions[0] < fractions[-1]


def test_clear_is_identity():
    pts = _cloud(100)
    assert fog_lidar(pts, parse_fog("clear"), np.random.default_rng(0)).tobytes() == pts.tobytes()
    img = np.random.default_rng(0).integers(0, 255, (8, 8, 3), dtype=np.uint8)
    assert fog_image(img, np.full((8, 8), 5.0, np.float32), np.eye(3), 0.0, np.zeros(3)).tobytes() == img.tobytes()


def test_black_object_at_visibility_keeps_five_percent_contrast():
    K = np.array([[1e7, 0, 0.5], [0, 1e7, 0.5], [0, 0, 1]])  # ℓ = depth at the single pixel
    A = np.array([230.0, 230.0, 230.0])
    for v in (50.0, 100.0, 160.0):
        fogged = fog_image(np.zeros((1, 1, 3), np.uint8), np.full((1, 1), v, np.float32), K, alpha_from_visibility(v), A)
        contrast = (A[0] - fogged[0, 0, 0]) / A[0]
        assert contrast == pytest.approx(0.05, abs=0.01)


def test_euclidean_distance_from_planar_depth():
    K = fog_gym.RigConfig.fogdrive().camera("CAM_FRONT").intrinsic()
    f = ray_length_factor(1280, 960, K)
    assert f[480, 640] == pytest.approx(1.0, abs=1e-5)
    u, v = 0.5 - 640, 0.5 - 480
    assert f[0, 0] == pytest.approx(math.sqrt(1 + (u / K[0, 0]) ** 2 + (v / K[1, 1]) ** 2), rel=1e-6)


@given(st.floats(1.0, 500.0), st.integers(0, 255), st.floats(1.0, 1000.0))
@settings(max_examples=60, deadline=None)
def test_transmittance_blend_bounds(v, j, depth):
    """t ∈ [0, 1]: the fogged value lies between the clean value and the airlight."""
    K = np.array([[1e7, 0, 0.5], [0, 1e7, 0.5], [0, 0, 1]])
    out = fog_image(np.full((1, 1, 3), j, np.uint8), np.full((1, 1), depth, np.float32), K, alpha_from_visibility(v),
                    np.array([200.0, 100.0, 0.0]))[0, 0]  # fmt: skip
    for c, a in enumerate((200, 100, 0)):
        assert min(j, a) - 1 <= out[c] <= max(j, a) + 1


def test_atmospheric_light_median_of_brightest_dark_channel():
    img = np.zeros((100, 100, 3), np.uint8)
    img[:40] = (180, 200, 220)  # sky
    img[40:] = (60, 60, 60)
    np.testing.assert_array_equal(atmospheric_light(img), [180, 200, 220])


def test_malloc_tuning_is_applied_and_can_be_disabled(monkeypatch):
    from fog_gym._memory import tune_malloc

    assert tune_malloc() is True  # glibc on Linux: freed frame buffers are kept for reuse
    monkeypatch.setenv("FOG_GYM_MALLOC_TUNING", "0")
    assert tune_malloc() is False

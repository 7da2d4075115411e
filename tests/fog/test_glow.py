"""The night glow on its coarse grid (fog_gym.fog.glow.add_glows) against the previous implementation, a Gaussian of
the full image (kept here as the reference): within 1/255 on real night frames and within 2/255 on random lamps."""

import math

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fog_gym.fog import add_glow, fog_images, glow_sigma_px, night_airlight, parse_fog
from fog_gym.fog.camera import ray_length_factor
from fog_gym.fog.glow import GLOW_FORWARD, GLOW_SOURCE_GAIN, GLOW_THRESHOLD, add_glows, glow_factor, glow_grids

LEVELS = ("light", "moderate", "dense")


def reference_glow(fogged, clean, depth, K, alpha):
    """The glow as fog-gym computed it before the coarse grid: the sources' energy blurred at full resolution."""
    if alpha <= 0.0:
        return fogged
    src = clean.max(axis=2) >= GLOW_THRESHOLD
    if not src.any():
        return fogged
    h, w = depth.shape
    sigma = max(glow_sigma_px(K, alpha), 0.5)
    ell = depth * ray_length_factor(w, h, K)
    weight = np.where(src, GLOW_FORWARD * GLOW_SOURCE_GAIN * (1.0 - np.exp(-alpha * ell)), 0.0).astype(np.float32)
    energy = clean.astype(np.float32) * weight[..., None]
    glow = cv2.GaussianBlur(energy, (0, 0), sigmaX=sigma, sigmaY=sigma, borderType=cv2.BORDER_CONSTANT)
    return np.clip(fogged.astype(np.float32) + glow + 0.5, 0, 255).astype(np.uint8)


@pytest.fixture(scope="module")
def night_frame():
    from fog_gym.envs.fogdrive import FogDriveEnv

    env = FogDriveEnv(town="merge", time_of_day="night", labels=None)
    obs, _ = env.reset(seed=1)
    obs, *_ = env.step(env.idle_action)
    frame = {cam: (obs[cam], obs[f"{cam}_DEPTH"], env.intrinsics[cam]) for cam in env.intrinsics}
    env.close()
    return frame


def test_the_glow_equals_the_full_resolution_gaussian_within_one_level_on_real_night_frames(night_frame):
    alphas = [parse_fog(lv).alpha for lv in LEVELS]
    lit = 0
    for cam, (rgb, depth, K) in night_frame.items():
        fogged = fog_images(rgb, depth, K, alphas, night_airlight(rgb, depth))
        new = add_glows(fogged.copy(), rgb, depth, K, alphas)
        for k, alpha in enumerate(alphas):
            ref = reference_glow(fogged[k], rgb, depth, K, alpha)
            assert np.abs(new[k].astype(int) - ref).max() <= 1, (cam, LEVELS[k])
            lit += int((ref > fogged[k]).sum())
    assert lit > 100_000  # the frames do glow (lamps and headlights)
    assert [glow_factor(glow_sigma_px(K, a)) for a in alphas] == [4, 5, 8]  # the full rig's grids are coarse


@given(st.lists(st.tuples(st.integers(0, 119), st.integers(0, 159), st.integers(1, 6), st.floats(2.0, 300.0)),
                min_size=1, max_size=12), st.floats(200.0, 900.0), st.floats(0.005, 0.08))  # fmt: skip
@settings(max_examples=25, deadline=None)
def test_random_lamps_glow_as_the_full_resolution_gaussian_within_two_levels(lamps, fx, alpha):
    clean = np.full((120, 160, 3), 30, np.uint8)
    depth = np.full((120, 160), 1000.0, np.float32)
    for r, c, size, dist in lamps:  # square lamp heads, some at the image's edges
        clean[r:r + size, c:c + size] = (255, 240, 200)
        depth[r:r + size, c:c + size] = dist
    K = np.array([[fx, 0, 80.0], [0, fx, 60.0], [0, 0, 1]])
    base = np.full_like(clean, 40)
    diff = np.abs(add_glow(base, clean, depth, K, alpha).astype(int) - reference_glow(base, clean, depth, K, alpha))
    assert diff.max() <= 2


def test_the_coarse_grid_keeps_the_glows_energy():
    clean = np.zeros((200, 240, 3), np.uint8)
    clean[97:103, 117:123] = 255
    depth = np.full((200, 240), 60.0, np.float32)
    K = np.array([[600.0, 0, 120.0], [0, 600.0, 100.0], [0, 0, 1]])
    alpha = parse_fog("dense").alpha
    (grid, f), = glow_grids(clean, depth, K, [alpha])
    assert f > 1
    energy = 36 * 255 * GLOW_FORWARD * GLOW_SOURCE_GAIN * (1 - math.exp(-alpha * 60.0 * math.sqrt(1 + (0.5 / 600) ** 2)))
    assert grid[..., 0].sum() * f * f == pytest.approx(energy, rel=1e-3)  # a cell holds the glow per pixel


def test_no_sources_or_clear_air_leave_the_image_unchanged():
    rng = np.random.default_rng(0)
    img = rng.integers(0, 230, (60, 80, 3), dtype=np.uint8)
    depth = np.full((60, 80), 50.0, np.float32)
    K = np.array([[300.0, 0, 40.0], [0, 300.0, 30.0], [0, 0, 1]])
    assert glow_grids(img, depth, K, [0.06]) == []  # no pixel reaches 240
    assert np.array_equal(add_glows(img[None].copy(), img, depth, K, [0.06])[0], img)
    lamp = img.copy()
    lamp[30, 40] = 255
    assert np.array_equal(add_glow(img, lamp, depth, K, 0.0), img)


def test_fog_with_glow_in_one_pass_equals_fog_then_glow_bit_for_bit(night_frame):
    alphas = [parse_fog(lv).alpha for lv in LEVELS]
    for cam, (rgb, depth, K) in night_frame.items():
        A = night_airlight(rgb, depth)
        two_pass = add_glows(fog_images(rgb, depth, K, alphas, A), rgb, depth, K, alphas)
        assert np.array_equal(fog_images(rgb, depth, K, alphas, A, glow=True), two_pass), cam
    dark = np.zeros((64, 96, 3), np.uint8)  # no source: glow=True is plain fog
    d, K = np.full((64, 96), 20.0, np.float32), np.array([[80.0, 0, 48], [0, 80.0, 32], [0, 0, 1]])
    assert np.array_equal(fog_images(dark, d, K, alphas, np.full(3, 90.0), glow=True),
                          fog_images(dark, d, K, alphas, np.full(3, 90.0)))

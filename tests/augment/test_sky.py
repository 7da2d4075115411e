"""Depth above the scan for real images: the image's sky, the column extension, the noise estimate that sets the sky's
smoothness threshold — against brute force and scenes of known layout."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fog_gym.augment import fog_image, image_depth
from fog_gym.augment.depth import SKY_M, complete_depth, extend_up, noise_sigma, sky_mask


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 12), st.integers(1, 12), st.integers(0, 2**32 - 1))
def test_extend_up_equals_a_column_walk(h, w, seed):
    rng = np.random.default_rng(seed)
    d = rng.uniform(0, 50, (h, w)).astype(np.float32)
    m = rng.random((h, w)) < 0.5
    out = extend_up(d, m)
    for j in range(w):
        for i in range(h):
            below = [r for r in range(i, h) if not m[r, j]]
            assert out[i, j] == (d[below[0], j] if below else 0.0)


def _scene(seed: int, noise: float):
    """A 90 × 120 image: a sky (vertical gradient) over a textured ground, a wall reaching the top edge at the right,
    a tree crown standing into the sky at the left."""
    rng = np.random.default_rng(seed)
    h, w = 90, 120
    top, bottom = rng.uniform(60, 200, 3), rng.uniform(60, 230, 3)
    img = np.empty((h, w, 3))
    img[:] = np.linspace(top, bottom, h)[:, None]  # at most ~2 levels a row: smooth
    img[50:] = rng.uniform(40, 140, (40, w, 3))  # textured ground
    wall = rng.uniform(40, 230, 3)
    c = rng.integers(3)  # in one channel the wall is 30+ levels from the sky at every height
    lo, hi = min(top[c], bottom[c]), max(top[c], bottom[c])
    wall[c] = hi + 30 if hi + 30 <= 255 else lo - 30
    img[:, 90:] = wall
    img[10:14, 95:99] = wall * 0.4  # a window
    img[25:50, 10:30] = (30, 110, 40)  # a crown
    truth = np.zeros((h, w), bool)
    truth[:50] = True
    truth[:, 90:] = False
    truth[25:50, 10:30] = False
    img = np.clip(img + rng.normal(0, noise, img.shape), 0, 255).astype(np.uint8)
    return img, truth


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from([0.0, 1.0, 3.0]))
def test_sky_mask_finds_the_sky_and_not_the_wall_or_crown_that_rise_into_it(seed, noise):
    img, truth = _scene(seed, noise)
    candidates = np.zeros(truth.shape, bool)
    candidates[:50] = True  # the empty pixels above the horizon
    sky = sky_mask(img, candidates)
    assert not (sky & ~truth).any()  # never an object
    inner = truth.copy()  # the sky but its pixels next to an object (an edge marks both of its sides as not smooth)
    inner[1:] &= truth[:-1]
    inner[:-1] &= truth[1:]
    inner[:, 1:] &= truth[:, :-1]
    inner[:, :-1] &= truth[:, 1:]
    assert sky[inner].all()


def test_noise_sigma_estimates_gaussian_noise_on_a_smooth_image():
    rng = np.random.default_rng(0)
    ramp = np.linspace(40, 200, 300)[None, :, None] * np.ones((240, 1, 3))
    for sigma in (1.0, 3.0, 8.0):
        img = np.clip(ramp + rng.normal(0, sigma, ramp.shape), 0, 255).astype(np.uint8)
        assert noise_sigma(img) == pytest.approx(sigma, rel=0.12, abs=0.3)
        img[:, :100] = rng.uniform(0, 255, (240, 100, 3))  # a third of the image textured, outside the mask
        mask = np.zeros((240, 300), bool)
        mask[:, 100:] = True
        assert noise_sigma(img, mask) == pytest.approx(sigma, rel=0.12, abs=0.3)
    assert noise_sigma(ramp.astype(np.uint8)) < 0.5


def test_objects_above_the_scan_take_their_columns_depth_and_the_sky_stays_far():
    sparse = np.zeros((60, 80), np.float32)
    sparse[40::2, :40:2] = 12.0  # a building's lower floors, seen by the scan
    sparse[40::2, 40::2] = 30.0  # a farther one
    above = np.zeros((60, 80), bool)
    above[:30] = True
    sky = above.copy()
    sky[:, :40] = False  # the near building rises to the top edge
    d = complete_depth(sparse, sky, extend=above)
    assert np.allclose(d[:30, 2:36], 12.0) and (d[:30, 42:] == SKY_M).all()
    assert np.allclose(d[30:, 2:36], 12.0)  # the pixels between horizon and scan complete as before


def test_the_sky_rule_is_checked_before_any_work():
    K = np.array([[100.0, 0, 40], [0, 100.0, 30], [0, 0, 1]])
    T = np.array([[0, -1.0, 0, 0], [0, 0, -1.0, 0.5], [1.0, 0, 0, 0], [0, 0, 0, 1]])
    pts = np.array([[10.0, 0.0, 0.0, 0.5]])
    img = np.zeros((60, 80, 3), np.uint8)
    with pytest.raises(ValueError, match="sky must be one of"):
        image_depth((80, 60), K, pts, T, rgb=img, sky="clouds")
    with pytest.raises(ValueError, match="sky must be one of"):
        fog_image(img, K, "dense", points=pts, T_cam_lidar=T, sky="clouds")
    with pytest.raises(ValueError, match="rgb must be an image of size"):
        image_depth((80, 60), K, pts, T, rgb=img[:10])
    # without an image the horizon rule holds: every empty pixel above the horizon is sky
    d = image_depth((80, 60), K, pts, T)
    assert (d[:25] == SKY_M).all()

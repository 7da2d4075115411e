"""The RL presets' LiDAR bird's-eye image (:func:`fog_gym.render.birds_eye.lidar_bev`): the compiled kernel gives the
same image as the numpy formula it replaced, point for point, boundaries included."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fog_gym.render.birds_eye import lidar_bev


def numpy_bev(pts, size, metres, ahead, sensor_height):
    """The formula as numpy evaluates it (float32 points, Python-float constants)."""
    height = pts[:, 2] + sensor_height
    above = (height > 0.3) & (height < 4.0)
    scale = size / metres
    col = np.floor(pts[above, 1] * scale + size / 2).astype(np.int64)
    row = np.floor((ahead - pts[above, 0]) * scale + size / 2).astype(np.int64)
    ok = (col >= 0) & (col < size) & (row >= 0) & (row < size)
    img = np.zeros((2, size, size), np.uint8)
    img[0, row[ok], col[ok]] = 255
    h = np.clip(height[above][ok] / 4.0 * 255, 0, 255).astype(np.uint8)
    np.maximum.at(img[1], (row[ok], col[ok]), h)
    return img


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), size=st.sampled_from([8, 32, 64]), metres=st.sampled_from([16.0, 64.0, 50.0]),
       ahead=st.sampled_from([0.0, 12.0, -5.5]))  # fmt: skip
def test_kernel_equals_numpy_formula(seed, size, metres, ahead):
    rng = np.random.default_rng(seed)
    pts = rng.uniform(-metres, metres, (3000, 4)).astype(np.float32)
    pts[:, 2] = rng.uniform(-2.5, 2.5, 3000)
    # points exactly on cell edges and on the height limits
    pts[:200, :2] = np.round(pts[:200, :2] * size / metres) * metres / size
    pts[200:300, 2] = np.float32(0.3) - np.float32(2.0)
    pts[300:400, 2] = np.float32(4.0) - np.float32(2.0)
    assert np.array_equal(lidar_bev(pts, size, metres, ahead), numpy_bev(pts, size, metres, ahead, 2.0))


def test_highest_point_wins_and_empty_cloud_is_blank():
    pts = np.array([[0.5, 0.5, 1.0, 0], [0.5, 0.5, -1.0, 0], [0.5, 0.5, 0.5, 0]], np.float32)
    img = lidar_bev(pts, 4, 4.0)
    assert img[0, 1, 2] == 255 and img[1, 1, 2] == int(np.float32(3.0) / 4 * 255) and img[0].sum() == 255
    assert not lidar_bev(np.zeros((0, 4), np.float32), 4, 4.0).any()


def test_bad_points_fail_with_their_shape():
    with pytest.raises(ValueError, match=r"\(N, >=3\)"):
        lidar_bev(np.zeros((5, 2), np.float32), 4, 4.0)

"""Pictures for people: the bird's-eye view keeps every lane marking, the night preview."""

import numpy as np

from fog_gym.world.scenery import MARKING
from fog_gym.render.birds_eye import _BEV_COLORS, birds_eye_view
from fog_gym.viz.draw import exposure_preview


def test_bev_shows_every_marking_a_fine_scan_crosses(small_env):
    scene = small_env.scene
    size, metres = 480, 100.0
    img = birds_eye_view(scene, size, metres)
    is_marking = np.all(img == _BEV_COLORS[MARKING], axis=-1)
    x, y, yaw = scene.ego_pose
    c, s = np.cos(yaw), np.sin(yaw)
    px = metres / size
    checked = 0
    for row in range(40, size - 40, 37):  # scan rows across the road at 1 cm steps: every marking crossing
        fwd = -(row + 0.5 - size / 2) * px
        right = np.arange(-metres / 2, metres / 2, 0.01)
        cls = scene.static.surface.class_at(x + fwd * c - right * s, y + fwd * s + right * c)
        for k in np.flatnonzero(cls == MARKING):
            col = int((right[k] + metres / 2) / px)
            assert is_marking[row, max(col - 1, 0) : col + 2].any(), (row, col)
            checked += 1
    assert checked > 50  # the highway's lines were crossed many times


def test_exposure_preview_brightens_dark_images_and_leaves_bright_ones():
    dark = np.zeros((10, 10, 3), np.uint8)
    dark[0, 0] = 5
    dark[5:, :] = 10
    img, gain = exposure_preview(dark)
    assert gain > 10 and img.max() > 150 and img.dtype == np.uint8
    bright = np.full((4, 4, 3), 240, np.uint8)
    assert exposure_preview(bright)[1] == 1.0 and np.array_equal(exposure_preview(bright)[0], bright)

"""Anti-aliased cameras: closer to a 4x-supersampled reference than point sampling, the other buffers untouched,
straight axis-aligned shapes untouched, slanted edges blended by coverage, bad values refused."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from fog_gym.envs.fogdrive import FogDriveEnv
from fog_gym.geometry import Pose
from fog_gym.render.antialias import antialias
from fog_gym.sensors.camera import CameraConfig, CameraRig


def _psnr(a: np.ndarray, ref: np.ndarray) -> float:
    return float(10 * np.log10(255.0**2 / np.mean((a.astype(np.float64) - ref) ** 2)))


def _down(img: np.ndarray, f: int) -> np.ndarray:
    h, w, _ = img.shape
    return img.reshape(h // f, f, w // f, f, 3).astype(np.float64).mean(axis=(1, 3))


@pytest.fixture(scope="module")
def scene_and_cams():
    env = FogDriveEnv(town="roundabout", resolution=(320, 240), cameras=["CAM_FRONT", "CAM_LEFT"], labels=None)
    env.reset(seed=3)
    for _ in range(3):
        env.step(env.idle_action)
    return env.scene, env.config.rig.cameras, env.config.far_distance


def _render(scene, cam, far):
    rig = CameraRig([cam], far=far)
    return rig.render(scene, rig.in_view(rig.primitives(scene, in_view=False), scene))[cam.name]


@pytest.mark.parametrize("index", [0, 1])
def test_antialiased_frame_is_2_db_closer_to_the_supersampled_reference(scene_and_cams, index):
    scene, cams, far = scene_and_cams
    cam = cams[index]
    plain, smooth = _render(scene, cam, far), _render(scene, replace(cam, antialias=True), far)
    ref = _down(_render(scene, replace(cam, width=4 * cam.width, height=4 * cam.height), far).rgb, 4)
    assert _psnr(smooth.rgb, ref) >= _psnr(plain.rgb, ref) + 2.0
    for name in ("depth", "semantic", "instance"):  # point-sampled, as CARLA's
        assert np.array_equal(getattr(smooth, name), getattr(plain, name))


def test_night_frames_get_edge_antialiasing_and_keep_their_buffers():
    env = FogDriveEnv(town="merge", resolution=(160, 120), cameras=["CAM_FRONT"], time_of_day="night", labels=None)
    env.reset(seed=1)
    scene, cam, far = env.scene, env.config.rig.cameras[0], env.config.far_distance
    plain, smooth = _render(scene, cam, far), _render(scene, replace(cam, antialias=True), far)
    assert np.array_equal(smooth.depth, plain.depth) and (smooth.rgb != plain.rgb).any()


def test_axis_aligned_shapes_are_left_alone_and_slanted_edges_blend_by_coverage():
    img = np.zeros((40, 60, 3), np.uint8)
    inst = np.zeros((40, 60), np.uint16)
    img[10:25, 15:40] = 180
    inst[10:25, 15:40] = 3  # a rectangle: its corners are corners, not stair steps
    depth = np.ones((40, 60), np.float32)
    sem = np.zeros((40, 60), np.uint8)
    assert np.array_equal(antialias(img, depth, sem, inst), img)
    # a shallow slanted edge, point-sampled, against its 8x8-supersampled coverage
    h, w, f = 40, 80, 8
    y, x = np.mgrid[0 : h * f, 0 : w * f]
    cover = ((y + 0.5) / f > 10 + 0.3 * (x + 0.5) / f).reshape(h, f, w, f).mean(axis=(1, 3))
    yy, xx = np.mgrid[0:h, 0:w]
    inside = (yy + 0.5) > 10 + 0.3 * (xx + 0.5)
    sharp = np.repeat((inside * 200).astype(np.uint8)[..., None], 3, 2)
    out = antialias(sharp, np.ones((h, w), np.float32), np.zeros((h, w), np.uint8), inside.astype(np.uint16))
    ref = np.repeat((cover * 200)[..., None], 3, 2)
    assert _psnr(out, ref) > _psnr(sharp, ref) + 10.0
    assert np.abs(out[..., 0].astype(float) - ref[..., 0]).max() < 60  # each pixel near its coverage


def test_bad_antialias_values_are_one_line_errors():
    with pytest.raises(ValueError, match="antialias must be True or False"):
        CameraConfig("CAM_FRONT", Pose(1.8, 0, 1.2), 8, 6, antialias="yes")
    with pytest.raises(ValueError, match="antialias must be True or False"):
        FogDriveEnv(resolution=(32, 24), cameras=["CAM_FRONT"], antialias=1)
    with pytest.raises(ValueError, match="depth must be"):
        antialias(np.zeros((4, 4, 3), np.uint8), np.zeros((3, 4)), np.zeros((4, 4)), np.zeros((4, 4)))


def test_env_antialias_applies_to_every_camera():
    env = FogDriveEnv(resolution=(64, 48), cameras=["CAM_FRONT", "CAM_BACK"], antialias=True)
    assert all(c.antialias for c in env.config.rig.cameras)
    obs, _ = env.reset(seed=0)
    assert obs["CAM_FRONT"].shape == (48, 64, 3)

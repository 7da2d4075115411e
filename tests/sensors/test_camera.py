"""The camera sensor: channels, spaces and dataset layout from its config; measure is the rig's render."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import fog_gym
from fog_gym.sensors.rig import RigConfig
from fog_gym.dataset.layout import FOG_LEVELS, FOGDRIVE_CHANNELS
from fog_gym.sensors import CameraSensor


def test_fogdrive_cameras_declare_exactly_the_fogdrive_camera_channels():
    for cam in RigConfig.fogdrive(resolution=(32, 24)).cameras:
        layout = CameraSensor(cam).layout()
        assert len(layout) == 4 + len(FOG_LEVELS)  # rgb, fog levels, depth, seg, bbox
        assert all(FOGDRIVE_CHANNELS[k] == v for k, v in layout.items())


def test_spaces_follow_resolution_and_far_distance():
    cam = RigConfig.fogdrive(resolution=(40, 30)).cameras[0]
    sp = CameraSensor(cam, far=500.0).observation_spaces()
    assert sp["CAM_FRONT"].shape == (30, 40, 3) and sp["CAM_FRONT"].dtype == np.uint8
    assert sp["CAM_FRONT_DEPTH"].high.max() == 500.0 and sp["CAM_FRONT_SEM"].dtype == np.uint8


def test_measure_equals_the_batched_rig_render():
    env = fog_gym.FogDriveEnv(resolution=(32, 24), cameras=["CAM_FRONT", "CAM_LEFT"], episode_seconds=0.2)
    obs, _ = env.reset(seed=0)
    prims = env.cameras.primitives(env.scene)
    out = CameraSensor(env.config.rig.camera("CAM_LEFT"), far=env.config.far_distance).measure(env.scene, prims, None, 0)
    for k in ("CAM_LEFT", "CAM_LEFT_DEPTH", "CAM_LEFT_SEM"):
        np.testing.assert_array_equal(out[k], obs[k])
    env.close()


def test_a_camera_sensor_needs_a_camera_config():
    with pytest.raises(TypeError, match="config must be a CameraConfig"):
        CameraSensor("CAM_FRONT")


@pytest.fixture(scope="module")
def mesh_env():
    env = fog_gym.FogDriveEnv(resolution=(32, 24), cameras=["CAM_FRONT", "CAM_LEFT"], geometry="meshes")
    env.reset(seed=2)
    yield env
    env.close()


@settings(max_examples=12, deadline=None)
@given(moves=st.lists(st.tuples(st.floats(-30.0, 80.0), st.floats(-12.0, 12.0), st.floats(-np.pi, np.pi)),
                      min_size=1, max_size=6))  # fmt: skip
def test_the_scenes_primitives_are_the_props_selected_from_the_whole_world(mesh_env, moves):
    """The props each sensor gets (one selection a step, from the props near where the ego was last re-selected)
    are those a selection from the whole static world gives: within the render radius, as their meshes and parts
    within the detail radius, and for the cameras only what some camera can see — the same rows in the same order,
    as the ego drives on (the near set re-selected after NEAR_MARGIN) or jumps."""
    from dataclasses import replace

    from fog_gym.world.primitives import Primitives

    cams = mesh_env.cameras
    scene = mesh_env.scene
    x, y = scene.ego_pose[:2]
    for dx, dy, yaw in moves:
        x, y = x + dx, dy
        moved = replace(scene, ego_pose=(x, y, yaw))
        every, seen = cams.scene_primitives(moved)
        _, boxes, _, (detail, owner) = cams._static_props(moved)
        ego = np.array([x, y])
        within = boxes.near_mask(ego, cams.render_radius)
        close = within & boxes.near_mask(ego, cams.detail_radius)
        props = Primitives.concat(boxes.take(within & ~close), detail.take(close[owner]))
        want = Primitives.concat(props, moved.primitives)
        want_seen = Primitives.concat(cams._in_view(props, moved.ego_pose), moved.primitives)
        for got, ref in ((every, want), (seen, want_seen), (cams.primitives(moved, in_view=False), want)):
            for k in ("centers", "halves", "yaws", "tags", "meshes", "insts"):
                np.testing.assert_array_equal(getattr(got, k), getattr(ref, k))
        assert 0 < len(seen) < len(every)

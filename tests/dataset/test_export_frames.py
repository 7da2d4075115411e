"""The exporters' geometry: the frame reflection, quaternions, points in boxes, occlusion from depth, ring indices."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fog_gym import geometry
from fog_gym.dataset.export.frames import (
    FLIP, boxes_from_corners, camera_intrinsic, kitti_occlusion, matrix_quaternion, occlusion, points_in_boxes,
    reflect_transform, ring_index, yaw_matrix, yaw_quaternion,
)  # fmt: skip

angles = st.floats(-math.pi, math.pi, allow_nan=False)


def _quaternion_matrix(q: np.ndarray) -> np.ndarray:
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])  # fmt: skip


@settings(max_examples=200, deadline=None)
@given(angles, angles, angles)
def test_matrix_quaternion_round_trips_every_rotation(pitch, roll, yaw):
    R = geometry.rotation_matrix(math.degrees(pitch), math.degrees(roll), math.degrees(yaw))
    q = matrix_quaternion(R)
    assert q[0] >= 0 and abs(np.linalg.norm(q) - 1) < 1e-12
    np.testing.assert_allclose(_quaternion_matrix(q), R, atol=1e-9)


@given(angles)
def test_yaw_quaternion_is_the_yaw_matrix(yaw):
    np.testing.assert_allclose(_quaternion_matrix(yaw_quaternion(yaw)), yaw_matrix(yaw), atol=1e-12)


def test_a_reflection_has_no_quaternion():
    with pytest.raises(ValueError, match="wrong handedness"):
        matrix_quaternion(np.diag([1.0, -1.0, 1.0]))


@settings(max_examples=100, deadline=None)
@given(st.floats(-50, 50), st.floats(-50, 50), angles, angles)
def test_reflecting_a_transform_reflects_the_points_it_moves(x, y, yaw, point_yaw):
    T = geometry.yaw_transform(x, y, yaw)
    p = np.array([math.cos(point_yaw) * 7, math.sin(point_yaw) * 7, 1.5, 1.0])
    np.testing.assert_allclose(reflect_transform(T) @ (FLIP @ p), FLIP @ (T @ p), atol=1e-9)
    # a yaw ψ in the left-handed frame is −ψ in the right-handed one
    np.testing.assert_allclose(reflect_transform(T)[:3, :3], yaw_matrix(-yaw), atol=1e-12)


def test_a_fogdrive_extrinsic_composed_with_the_reflection_is_a_proper_rotation():
    from fog_gym.sensors.rig import RigConfig

    rig = RigConfig.fogdrive()
    lidar = geometry.sensor_to_world(rig.lidar.pose)
    for cam in rig.cameras:
        E = geometry.lidar_to_camera(lidar, geometry.sensor_to_world(cam.pose))
        assert np.linalg.det(E[:3, :3]) == pytest.approx(-1.0)  # FogDrive: left-handed LiDAR → right-handed camera
        assert np.linalg.det((E @ FLIP)[:3, :3]) == pytest.approx(1.0)


def test_boxes_from_corners_reflect_centres_and_yaws():
    corners = geometry.box_corners([[10.0, 3.0, 0.8]], [[4.5, 1.9, 1.6]], [0.3])
    centers, sizes, yaws = boxes_from_corners(corners)
    np.testing.assert_allclose(centers, [[10.0, -3.0, 0.8]], atol=1e-12)
    np.testing.assert_allclose(sizes, [[4.5, 1.9, 1.6]], atol=1e-12)
    np.testing.assert_allclose(yaws, [-0.3], atol=1e-12)


def test_points_in_boxes_counts_exactly_the_points_inside():
    rng = np.random.default_rng(0)
    center, size, yaw = np.array([5.0, -2.0, 1.0]), np.array([4.0, 2.0, 1.5]), 0.7
    local = rng.uniform(-1, 1, (2000, 3)) * (size / 2 * 1.5)  # some inside, some outside
    inside = (np.abs(local) <= size / 2).all(axis=1)
    points = local @ yaw_matrix(yaw).T + center
    assert points_in_boxes(points, center[None], size[None], np.array([yaw])).tolist() == [int(inside.sum())]


def test_occlusion_measures_the_hidden_share_of_a_box_from_depth():
    K = camera_intrinsic(200, 100)
    # a 4 m × 2 m × 2 m box 20 m ahead in the camera frame (x right, y down, z forward)
    box = geometry.box_corners([[0.0, 0.0, 20.0]], [[4.0, 2.0, 2.0]], [0.0])[0]
    depth = np.full((100, 200), 1000.0)
    assert occlusion(depth, box, K)[0] == 0.0
    assert occlusion(depth, box, K)[1] == pytest.approx(1.0, abs=0.05)
    depth[:, :100] = 8.0  # something 8 m away hides the left half of the image
    occluded, visible = occlusion(depth, box, K)
    assert occluded == pytest.approx(0.5, abs=0.05) and visible == pytest.approx(0.5, abs=0.05)
    assert kitti_occlusion(occluded) == 2
    depth[:] = 19.5  # nearer than the box's nearest corner (19 m) by less than the margin: not an occluder
    assert occlusion(depth, box, K)[0] == 0.0
    assert occlusion(depth, box - [0.0, 0.0, 30.0], K) == (1.0, 0.0)  # behind the camera


def test_ring_index_recovers_fogdrive_beams():
    elevations = np.radians(5.0 - np.arange(64) * 25.0 / 63)
    points = np.stack([30 * np.cos(elevations), np.zeros(64), 30 * np.sin(elevations)], axis=1)
    assert ring_index(points).tolist() == list(range(64))

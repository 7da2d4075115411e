import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fog_gym import geometry as g


def test_fogdrive_intrinsic():
    # FogDrive prints 537.09; CARLA's formula 640 / tan(50°) gives 537.02: the same lens to 0.013 %.
    K = g.intrinsic_matrix(1280, 960, 100.0)
    np.testing.assert_allclose(K, [[537.09, 0, 640], [0, 537.09, 480], [0, 0, 1]], atol=0.07)
    assert K[0, 0] == pytest.approx(640 / math.tan(math.radians(50)))


def test_yaw_turns_x_towards_y_right_as_carla():
    np.testing.assert_allclose(g.rotation_matrix(0, 0, 90) @ [1, 0, 0], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(g.rotation_matrix(30, 0, 0) @ [1, 0, 0], [math.cos(math.pi / 6), 0, 0.5], atol=1e-12)


@given(st.floats(-180, 180), st.floats(-180, 180), st.floats(-180, 180))
@settings(max_examples=50, deadline=None)
def test_rotation_is_proper(p, r, y):
    R = g.rotation_matrix(p, r, y)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)


def test_front_camera_looks_forward():
    """A point ahead of the ego on the camera's height projects to the principal point."""
    ego = g.yaw_transform(10.0, 5.0, 0.3)
    cam = g.transform_matrix((1.8, 0.0, 1.2), (0, 0, 0))
    M = g.world_to_camera(ego, cam)
    ahead = g.transform_points(ego, np.array([[21.8, 0.0, 1.2]]))
    pc = g.transform_points(M, ahead)
    np.testing.assert_allclose(pc[0], [0, 0, 20.0], atol=1e-9)
    K = g.intrinsic_matrix(1280, 960, 100)
    np.testing.assert_allclose(g.project_points(K, pc)[0], [640, 480], atol=1e-9)
    # +y (right) in the vehicle maps to +x (right) in the image, +z (up) to −y (up in the image)
    right_up = g.transform_points(M, g.transform_points(ego, np.array([[21.8, 1.0, 2.2]])))
    assert right_up[0, 0] > 0 and right_up[0, 1] < 0


def test_lidar_to_camera_extrinsic_matches_chain():
    lidar = g.transform_matrix((0, 0, 2), (0, 0, 0))
    cam = g.transform_matrix((0.5, 0.7, 1.5), (0, 0, 100))
    E = g.lidar_to_camera(lidar, cam)
    ego = g.yaw_transform(3, -2, 1.0)
    p_lidar = np.array([[12.0, -3.0, 0.5]])
    direct = g.transform_points(g.world_to_camera(ego, cam), g.transform_points(ego @ lidar, p_lidar))
    np.testing.assert_allclose(g.transform_points(E, p_lidar), direct, atol=1e-9)


def test_box_corner_order_documented():
    c = g.box_corners(np.array([[0, 0, 1.0]]), np.array([[4.0, 2.0, 2.0]]), np.array([0.0]))[0]
    np.testing.assert_allclose(c[0], [2, 1, 0])  # front-right-bottom
    np.testing.assert_allclose(c[6], [-2, -1, 2])  # rear-left-top
    rotated = g.box_corners(np.array([[0, 0, 1.0]]), np.array([[4.0, 2.0, 2.0]]), np.array([math.pi / 2]))[0]
    np.testing.assert_allclose(rotated[0], [-1, 2, 0], atol=1e-12)  # front now points to +y

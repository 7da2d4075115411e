"""The cameras' ground-plane view test without angles decides as the bearing-and-margin rule it stands for."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fog_gym.render.view_cull import in_views


def bearing_rule(centers, radius, ego_pose, views):
    """The rule as angles: kept when within the radius, or when the bearing is within half + asin(r/d) + 1e-3 of the
    heading; also how far each box lies from that edge (radians; inf for a box that is inside its circle)."""
    ex, ey, eyaw = ego_pose
    c, s = np.cos(eyaw), np.sin(eyaw)
    keep = np.zeros(len(centers), bool)
    edge = np.full(len(centers), np.inf)
    for px, py, yaw, half in views:
        dx, dy = centers[:, 0] - (ex + c * px - s * py), centers[:, 1] - (ey + s * px + c * py)
        dist = np.hypot(dx, dy)
        off = np.abs((np.arctan2(dy, dx) - (eyaw + yaw) + np.pi) % (2 * np.pi) - np.pi)
        theta = half + 1e-3 + np.arcsin(np.clip(radius / np.maximum(dist, 1e-9), 0.0, 1.0))
        keep |= (dist <= radius) | (off <= theta)
        edge = np.minimum(edge, np.where(dist <= radius, np.inf, np.abs(off - np.minimum(theta, np.pi))))
    return keep, edge


@settings(max_examples=80, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n_views=st.integers(1, 6), wide=st.booleans())
def test_the_test_without_angles_decides_as_the_bearing_and_its_margin(seed, n_views, wide):
    rng = np.random.default_rng(seed)
    n = 500
    centers = np.c_[rng.uniform(-200, 200, (n, 2)), rng.uniform(0, 5, n)]
    radius = rng.uniform(0.2, 30.0, n)
    half = rng.uniform(0.05, 3.2 if wide else 1.4, n_views)  # half fields of view up to beyond π (every bearing)
    views = np.c_[rng.uniform(-3, 3, (n_views, 2)), rng.uniform(-np.pi, np.pi, n_views), half]
    pose = (float(rng.uniform(-100, 100)), float(rng.uniform(-100, 100)), float(rng.uniform(-4, 4)))
    got = in_views(centers, radius, pose, views)
    want, edge = bearing_rule(centers, radius, pose, views)
    differ = got != want
    assert not differ.any() or edge[differ].max() < 1e-9  # only where a box's circle touches an edge, to rounding
    assert got.sum() > 0 and (~got).sum() + want.sum() > 0


def test_boxes_ahead_and_behind_are_seen_aside_not_and_a_box_around_a_camera_always():
    views = np.array([[1.5, 0.0, 0.0, np.radians(35.0)], [-1.0, 0.0, np.pi, np.radians(35.0)]])  # front and back
    centers = np.array([[30.0, 0.0, 1.0], [-30.0, 0.0, 1.0], [0.0, 30.0, 1.0], [1.5, 0.3, 1.0], [10.0, 40.0, 0.0]])
    radius = np.array([1.0, 1.0, 1.0, 1.0, 60.0])
    assert in_views(centers, radius, (0.0, 0.0, 0.0), views).tolist() == [True, True, False, True, True]
    # the ego turned a quarter left: the box on its left is now ahead, the camera moved off the small box
    assert in_views(centers, radius, (0.0, 0.0, np.pi / 2), views).tolist() == [False, False, True, False, True]


def test_bad_shapes_are_one_line_errors():
    with pytest.raises(ValueError, match="centres") as err:
        in_views(np.zeros((3, 3)), np.zeros(2), (0.0, 0.0, 0.0), np.zeros((1, 4)))
    assert "\n" not in str(err.value)

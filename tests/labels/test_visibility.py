"""Visibility labels under fog: LiDAR and radar points per box against a brute force, the boxes' contrast against a
brute force on small frames, perceivability by Koschmieder's law, per fog level through the wrapper, and the files
(BBOX_3D, 2D boxes) and the nuScenes export that carry them."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fog_gym.geometry import box_corners
from fog_gym.labels.visibility import CONTRAST_THRESHOLD, box_contrast, perceivable, points_in_boxes, radar_xyz


def _inside_brute(p, corners, tol=1e-9):
    """Inside the box spanned by 8 corners: on the inner side of its six faces (the box is convex), within ``tol``
    (negative: strictly inside by that much)."""
    c = corners.mean(axis=0)
    faces = [(0, 1, 2), (4, 6, 5), (0, 4, 1), (1, 5, 2), (2, 6, 3), (3, 7, 0)]
    for a, b, d in faces:
        n = np.cross(corners[b] - corners[a], corners[d] - corners[a])
        if np.dot(n, c - corners[a]) < 0:
            n = -n
        if np.dot(n / np.linalg.norm(n), p - corners[a]) < -tol:
            return False
    return True


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 10**6))
def test_points_in_boxes_equals_a_brute_force_over_the_faces(seed):
    rng = np.random.default_rng(seed)
    b = rng.integers(1, 4)
    centers = np.c_[rng.uniform(-10, 10, (b, 2)), rng.uniform(-1, 1, b)]
    sizes = np.c_[rng.uniform(2, 6, b), rng.uniform(1.5, 2.5, b), rng.uniform(1.2, 3.5, b)]
    yaws = rng.uniform(-math.pi, math.pi, b)
    pts = np.c_[rng.uniform(-14, 14, (400, 2)), rng.uniform(-3, 3, 400)]
    got = points_in_boxes(pts, centers, sizes, yaws)
    corners = box_corners(centers, sizes, yaws)
    want = [sum(_inside_brute(p, corners[k]) for p in pts) for k in range(b)]
    assert got.tolist() == want


def test_radar_detections_become_points_of_their_frame():
    det = np.array([[-3.0, 0.0, 0.0, 20.0], [1.0, math.pi / 2, 0.0, 5.0], [0.0, 0.0, math.pi / 6, 10.0]])
    np.testing.assert_allclose(radar_xyz(det), [[20, 0, 0], [0, 5, 0], [10 * math.cos(math.pi / 6), 0, 5]], atol=1e-9)


def test_box_contrast_equals_a_brute_force_on_a_small_frame():
    rng = np.random.default_rng(0)
    rgb = rng.integers(0, 256, (24, 32, 3), dtype=np.uint8)
    inst = np.zeros((24, 32), np.int64)
    inst[8:14, 10:20] = 7
    inst[9:12, 12:15] = 0  # a hole: background inside the box
    bbox = np.array([[[10, 8], [19, 13]]])
    got = box_contrast(rgb, inst, bbox, np.array([7]))
    luma = rgb.astype(float) @ [0.2126, 0.7152, 0.0722]
    own, back = [], []
    for y in range(max(0, 8 - 3), min(23, 13 + 3) + 1):  # grown by half the box (6 × 10 px → 3 and 5)
        for x in range(max(0, 10 - 5), min(31, 19 + 5) + 1):
            (own if inst[y, x] == 7 else back).append(luma[y, x])
    want = (np.mean(own) - np.mean(back)) / np.mean(back)
    assert got[0] == pytest.approx(want, rel=1e-12)
    assert box_contrast(rgb, inst, np.array([[[0, 0], [3, 3]]]), np.array([9]))[0] == 0.0  # no own pixel


def test_perceivable_follows_koschmieders_law():
    c = np.array([0.5, -0.5, 0.3, 0.01])
    t = np.array([0.2, 0.09, 1.0, 1.0])
    assert perceivable(c, t).tolist() == [True, False, True, False]
    # a box of contrast C0 is perceivable out to the distance where C0·e^(−αd) = 5 %: d = ln(C0 / 0.05) / α
    alpha = math.log(20) / 50.0
    d = math.log(0.5 / CONTRAST_THRESHOLD) / alpha
    assert perceivable([0.5], [math.exp(-alpha * (d - 0.1))])[0] and not perceivable([0.5], [math.exp(-alpha * (d + 0.1))])[0]


@pytest.fixture(scope="module")
def paired():
    import gymnasium as gym

    import fog_gym  # noqa: F401

    env = gym.make("FogDrive-v0", fog=["light", "dense"], resolution=(160, 120))
    obs, info = env.reset(seed=0)
    return env, obs, info


def test_the_env_counts_clean_lidar_and_radar_points_per_box(paired):
    env, obs, info = paired
    base = env.unwrapped
    b3 = info["boxes_3d"]
    assert len(b3["vehicle_ids"]) > 0
    from fog_gym.geometry import yaw_transform

    lidar_to_world = base.sensor_to_world("LIDAR_TOP")
    world_to_label = np.linalg.inv(yaw_transform(*base.scene.ego_pose) @ base.ego_pose_record()["lidar_to_ego"])
    pts = base.points["LIDAR_TOP"][:, :3]
    m = world_to_label @ lidar_to_world
    p = pts @ m[:3, :3].T + m[:3, 3]
    # returns on the box's own faces (its floor is the road) are in or out by rounding: bracket the count
    strict = [sum(_inside_brute(q, b3["corners"][k], -1e-4) for q in p) for k in range(len(b3["corners"]))]
    loose = [sum(_inside_brute(q, b3["corners"][k], 1e-4) for q in p) for k in range(len(b3["corners"]))]
    got = b3["num_lidar_pts"]["clear"].tolist()
    assert all(a <= g <= b for a, g, b in zip(strict, got, loose, strict=True)) and sum(got) > 0
    assert (b3["num_radar_pts"] >= 0).all() and b3["num_radar_pts"].sum() > 0


def test_fog_lowers_the_counts_and_perceivability_level_by_level(paired):
    _, _, info = paired
    n = info["boxes_3d"]["num_lidar_pts"]
    assert set(n) == {"clear", "light", "dense"}
    assert (n["dense"] <= n["light"]).all() and (n["light"] <= n["clear"]).all() and n["dense"].sum() < n["clear"].sum()
    for cam, b in info["boxes_2d"].items():
        p = b["perceivable"]
        assert set(p) == {"clear", "light", "dense"}
        assert (p["dense"] <= p["light"]).all() and (p["light"] <= p["clear"]).all()
        assert np.array_equal(p["dense"], perceivable(b["contrast"], b["transmittance"]["dense"]))


def test_the_files_and_the_nuscenes_export_carry_the_counts(tmp_path):
    pytest.importorskip("nuscenes")
    from fog_gym.dataset import FogDrive
    from fog_gym.dataset.export import export
    from fog_gym.generate import generate, plan_scenes

    root = tmp_path / "set"
    generate(root, plan_scenes(2, towns=("highway",), seed=2, resolution=(64, 48), seconds=0.2), progress=False)
    ds = FogDrive(root)
    s = ds.sample[-1]
    paths = ds.get_sample_paths(s["token"], ["BBOX_3D", "CAM_FRONT_BBOX"])
    b3 = json.loads(paths["BBOX_3D"].read_text())
    assert set(b3["num_lidar_pts"]) == {"clear", "light", "moderate", "dense"}
    assert len(b3["num_radar_pts"]) == len(b3["vehicle_ids"])
    b2 = json.loads(paths["CAM_FRONT_BBOX"].read_text())
    assert set(b2["perceivable"]) == {"clear", "light", "moderate", "dense"}
    export(root, tmp_path / "nus", "nuscenes", fog="dense", progress=False)
    anns = json.loads((tmp_path / "nus" / "v1.0-trainval" / "sample_annotation.json").read_text())
    assert sum(a["num_radar_pts"] for a in anns) > 0

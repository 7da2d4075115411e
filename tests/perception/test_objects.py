"""The perceived-objects observation: detection physics per sensor, fusion, the observation's format."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import fog_gym  # noqa: F401
from fog_gym.fog.lidar import BETA_PER_MOR, GAMMA, lidar_crossover_range, soft_response_table
from fog_gym.fog.physics import parse_fog
from fog_gym.perception import kernels as PK
from fog_gym.perception.objects import SENSORS, ObjectsConfig


def _boxes(*specs):
    """Ego at the origin (slot 0), then boxes (x, y, length, width, height) facing +x."""
    rows = [(0.0, 0.0, 4.8, 2.1, 1.5), *specs]
    a = np.array(rows, np.float64)
    return len(rows), a[:, 0].copy(), a[:, 1].copy(), np.zeros(len(rows)), a[:, 2].copy(), a[:, 3].copy(), a[:, 4].copy()


#: No fog field (no packed rows; a frame at the origin): the kernels use the homogeneous level.
HOMOGENEOUS_FIELD = (np.zeros((0, 8)), np.zeros(3))


def _lidar(level, *specs, cfg=ObjectsConfig()):
    n, bx, by, byaw, bl, bw, bh = _boxes(*specs)
    ti, tr = soft_response_table(level.alpha) if not level.is_clear else (np.zeros(101), np.zeros(101))
    beta = 0.0 if level.is_clear else BETA_PER_MOR / level.visibility_m / (GAMMA / math.pi)
    az = np.arange(cfg.lidar_beams) * (2 * np.pi / cfg.lidar_beams) - np.pi
    count, cen = np.zeros(n), np.zeros((n, 3))
    PK.lidar_detect(n, bx, by, byaw, bl, bw, bh, 0.0, 0.0, 0.0, cfg.lidar_height, cfg.lidar_elevations(), np.cos(az),
                    np.sin(az), cfg.lidar_range, 7, 0, level.alpha, beta, ti, tr, 0.45, 0.8, 0.4, cfg.max_rays, count,
                    cen, *HOMOGENEOUS_FIELD, np.zeros((1, 1)), np.zeros(1), np.zeros((1, 1)), np.zeros(1), 0.0)  # fmt: skip
    return count, cen


def _camera(level, *specs, color=(0.05, 0.05, 0.05), cam_z=1.2, cfg=ObjectsConfig()):
    n, bx, by, byaw, bl, bw, bh = _boxes(*specs)
    colors = np.tile(np.array(color, np.float64), (n, 1))
    out = [np.zeros(n) for _ in range(4)]
    grid = np.ones((10, 10), np.uint8)  # road everywhere the ground is seen
    surf = 0.2126 * np.array([96.0, 82, 150, 225]) + 0.7152 * np.array([118.0, 82, 146, 225]) + 0.0722 * np.array([68.0, 86, 140, 220])
    PK.camera_detect(n, bx, by, byaw, bl, bw, bh, colors, 0.0, 0.0, 0.0, 1.8, cam_z, cfg.camera_focal, 640, 480,
                     level.alpha, np.array([0.0, 0.0, 1.0]), 1.0, 0.0, 1.0, 216.0, grid, -1e5, -1e5, 2e4, surf,
                     cfg.max_rays, 1e4, *out, *HOMOGENEOUS_FIELD)  # fmt: skip
    return out


def test_a_car_ahead_is_seen_by_the_lidar_from_80_m_in_clear_air_and_not_beyond_the_crossover_in_dense_fog():
    clear, dense = parse_fog("clear"), parse_fog("dense")
    assert _lidar(clear, (85.0, 0.0, 4.5, 1.9, 1.5))[0][1] >= 5
    crossover = lidar_crossover_range(dense)
    for x in (crossover + 2.3 + 1.0, 45.0, 60.0, 85.0):  # the car's rear beyond the crossover range
        assert _lidar(dense, (x, 0.0, 4.5, 1.9, 1.5))[0][1] == 0
    assert _lidar(dense, (20.0, 0.0, 4.5, 1.9, 1.5))[0][1] >= 5


def test_lidar_returns_lie_on_the_vehicle_s_near_surface():
    count, cen = _lidar(parse_fog("clear"), (30.0, 0.0, 4.5, 1.9, 1.5))
    assert count[1] >= 5 and abs(cen[1, 0] - (30.0 - 2.25)) < 0.3 and abs(cen[1, 1]) < 0.5


def test_a_vehicle_hidden_behind_another_is_seen_by_neither_lidar_nor_camera():
    front, hidden = (20.0, 0.0, 9.0, 2.5, 3.6), (40.0, 0.0, 4.5, 1.9, 1.5)
    count, _ = _lidar(parse_fog("clear"), front, hidden)
    pixels = _camera(parse_fog("clear"), front, hidden)[0]
    assert count[1] >= 5 and count[2] == 0
    assert pixels[1] > 0 and pixels[2] == 0


@settings(max_examples=15, deadline=None)
@given(st.floats(min_value=30.0, max_value=250.0))
def test_camera_contrast_is_koschmieder_s_so_a_dark_car_is_seen_to_about_V_and_a_grey_one_less_far(visibility):
    """A car seen against the sky (the camera half a metre below the road's level, so no pixel of the car has ground
    behind it): contrast (J/A − 1)·exp(−αd), so the farthest distance at 5 % is V·ln(20(1 − J/A))/ln 20."""
    level = parse_fog(visibility)
    farthest = {}
    for name, grey in (("dark", 0.05), ("grey", 0.45)):
        j_over_a = grey * 255.0 / 216.0
        d_pred = visibility * math.log(20 * (1 - j_over_a)) / math.log(20)
        for d in (0.9 * d_pred, 1.1 * d_pred):  # the car's rear face d metres from the camera
            pixels, contrast, _, _ = _camera(level, (d + 1.8 + 2.25, 0.0, 4.5, 4.0, 3.0), color=(grey,) * 3, cam_z=-0.5)
            expected = (j_over_a - 1) * math.exp(-level.alpha * d)
            assert pixels[1] > 0 and abs(contrast[1] - expected) < 0.06 * abs(expected) + 1e-3  # rays entering low go farther
            assert (abs(contrast[1]) >= 0.05) == (d < d_pred)
        farthest[name] = d_pred
    assert 0.9 * visibility < farthest["dark"] < visibility and farthest["grey"] < 0.85 * farthest["dark"]


def _episode(fog, seed=3, steps=25, **kw):
    env = gym.make("FogDriveRLHazard-v0", observation="objects", fog=fog, **kw)
    obs, info = env.reset(seed=seed)
    out = [(obs, info)]
    for k in range(steps):
        obs, r, term, trunc, info = env.step([1, 3, 1, 4, 1][k % 5])
        out.append((obs, info))
        if term or trunc:
            break
    return out


def test_radar_detections_are_the_same_in_clear_air_and_every_fog():
    ref = _episode("clear")
    for fog in ("light", "moderate", "dense", 30.0):
        run = _episode(fog)
        assert len(run) == len(ref)
        for (_, a), (_, b) in zip(ref, run):
            for key in ("vehicle_ids", "position"):
                np.testing.assert_array_equal(a["detections"]["radar"][key], b["detections"]["radar"][key])


def test_the_same_seed_gives_the_same_detections_and_fog_shortens_what_lidar_and_camera_see():
    a, b = _episode("moderate"), _episode("moderate")
    for (oa, ia), (ob, ib) in zip(a, b):
        np.testing.assert_array_equal(oa, ob)
        for s in ("camera", "lidar", "radar", "fused"):
            np.testing.assert_array_equal(ia["detections"][s]["position"], ib["detections"][s]["position"])
    reach, seen = {}, {}
    for fog in ("clear", "dense"):
        run = _episode(fog, seed=0)
        reach[fog] = {s: max((i["detections"][s]["distance"].max(initial=0.0) for _, i in run))
                      for s in ("camera", "lidar")}  # fmt: skip
        seen[fog] = {s: sum(i["detections"][s]["count"] for _, i in run) for s in ("camera", "lidar")}
    assert reach["dense"]["lidar"] <= lidar_crossover_range(parse_fog("dense")) + 2 * 5.0 < 80.0 < reach["clear"]["lidar"]
    assert seen["clear"]["camera"] > seen["dense"]["camera"] and seen["clear"]["lidar"] > seen["dense"]["lidar"]


def test_the_observation_is_kinematics_style_ego_first_nearest_first_unused_rows_zero():
    env = gym.make("FogDriveRLHazard-v0", observation="objects", sensors=("lidar", "radar"), max_objects=6)
    obs, info = env.reset(seed=1)
    assert env.observation_space.shape == (6, 8) and obs.dtype == np.float32 and env.observation_space.contains(obs)
    assert obs[0, 0] == 1 and obs[0, 1] == 0 and (obs[0, 6:] == 1).all()  # the ego row
    present = obs[1:, 0] == 1
    rows = obs[1:][present]
    dist = np.hypot(rows[:, 1] * 200.0, rows[:, 2] * 12.0)
    assert np.all(np.diff(dist) >= -1e-6) and not obs[1:][~present].any()
    fused = info["detections"]["fused"]
    assert fused["count"] >= present.sum() and set(info["detections"]) == {"lidar", "radar", "fused"}
    assert set(fused) == {"count", "vehicle_ids", "position", "true_position", "distance"}
    n, cap = fused["count"], len(fused["vehicle_ids"])  # fixed rows: the detected first, then id -1 and zeros
    assert (fused["vehicle_ids"][:n] > 0).all() and (fused["vehicle_ids"][n:] == -1).all()
    assert (fused["distance"][:n] > 0).all() and (fused["distance"][n:] == 0).all()
    assert cap == env.unwrapped.worlds.core.capacity
    # every flagged sensor saw the object: a row flagged only by radar is in the radar list, not the LiDAR one
    assert (rows[:, 6:].sum(axis=1) >= 1).all() and set(np.round(rows[:, 5] * 2).tolist()) <= {-2, -1, 0, 1, 2}


def test_reported_positions_stay_near_the_truth_in_clear_air():
    _, info = _episode("clear", steps=3)[-1]
    for s, tol in (("lidar", 1.5), ("radar", 3.0), ("fused", 3.0)):
        d = info["detections"][s]
        n = d["count"]
        err = np.hypot(*(d["position"][:n] - d["true_position"][:n]).T)
        assert len(err) and np.median(err) < tol, s


@pytest.mark.parametrize("kwargs, match", [
    ({"sensors": ()}, "sensors must be a non-empty subset"),
    ({"sensors": ("sonar",)}, "sensors must be a non-empty subset"),
    ({"sensors": "lidar"}, "sensors must be a non-empty subset"),
    ({"observation": "points"}, "observation must be one of"),
    ({"min_points": 0}, "min_points must be an integer >= 1"),
    ({"max_objects": 0}, "max_objects must be an integer >= 1"),
    ({"max_objects": 1}, "max_objects must be an integer >= 2"),
    ({"min_contrast": 1.5}, "min_contrast must lie in"),
    ({"layout": "grid"}, "layout must be one of"),
])  # fmt: skip
def test_bad_arguments_fail_at_construction_naming_the_argument(kwargs, match):
    kwargs = {"observation": "objects", **kwargs}
    with pytest.raises(ValueError, match=match):
        gym.make("FogDriveRLHazard-v0", **kwargs)


def test_object_arguments_are_refused_on_the_pixel_observation():
    with pytest.raises(ValueError, match="configure observation='objects'"):
        gym.make("FogDriveRL-v0", sensors=("radar",))


def test_the_sensor_flags_follow_the_documented_order():
    assert ObjectsConfig(sensors=("radar", "camera")).features[6:] == ("camera", "radar") and SENSORS[0] == "camera"


def _lanes_from_fused(worlds, w=0):
    """The "lanes" layout recomputed in numpy from world ``w``'s fused list (reported positions and velocities)."""
    from fog_gym.perception.objects import FUSED, LANE_AHEAD, LANE_BEHIND, MAX_SPEED

    c = worlds.core
    n = int(c.counts[w])
    ey, eh, speed = c.floats[w, 0, 1], c.floats[w, 0, 2], c.floats[w, 0, 3]
    lanes = c.lanes
    ego_lane = int(np.clip(round(ey / 4.0), 0, lanes - 1))
    out = np.zeros((4, 5))
    out[0, :4] = 1.0, np.clip((ey - 4.0 * ego_lane) / 2.0, -1, 1), np.clip(speed / MAX_SPEED, -1, 1), ego_lane - 1.0
    seen = np.flatnonzero(worlds.present[w, 1:n, FUSED]) + 1
    p, v = worlds.pos[w, seen, FUSED], worlds.vel[w, seen, FUSED]
    cs, sn = math.cos(eh), math.sin(eh)
    along, lane = p[:, 0] * cs - p[:, 1] * sn, np.round((ey + p[:, 0] * sn + p[:, 1] * cs) / 4.0)
    dv = np.clip((v[:, 0] * cs - v[:, 1] * sn) / MAX_SPEED, -1, 1)
    for row, d in enumerate((-1, 0, 1), start=1):
        if not 0 <= ego_lane + d < lanes:
            continue
        out[row, 0] = 1.0
        ahead = np.flatnonzero((lane == ego_lane + d) & (along > 0) & (along < LANE_AHEAD))
        behind = np.flatnonzero((lane == ego_lane + d) & (along <= 0) & (-along < LANE_BEHIND))
        if len(ahead):
            k = ahead[np.argmin(along[ahead])]
            out[row, 1:3] = 1.0 - along[k] / LANE_AHEAD, dv[k]
        if len(behind):
            k = behind[np.argmax(along[behind])]
            out[row, 3:5] = 1.0 + along[k] / LANE_BEHIND, dv[k]
    return out


def test_the_lanes_layout_is_the_nearest_fused_object_ahead_and_behind_per_lane():
    env = gym.make("FogDriveRLHazard-v0", observation="objects", layout="lanes", fog="light").unwrapped
    obs, _ = env.reset(seed=5)
    assert env.observation_space.shape == (4, 5) and ObjectsConfig(layout="lanes").features[1] == "ahead"
    lanes_seen = set()
    for k in range(40):
        np.testing.assert_allclose(obs, _lanes_from_fused(env.worlds), atol=1e-5)
        assert env.observation_space.contains(obs)
        lanes_seen.add(round(float(obs[0, 3]) + 1))
        obs, _, term, trunc, _ = env.step([0, 3, 2, 1, 2, 3, 0, 0][k % 8])
        if term or trunc:
            obs, _ = env.reset()
    # the edge lanes have no neighbour beyond the road: its row is all zero
    assert 0 in lanes_seen or 2 in lanes_seen


def test_the_layout_changes_the_observation_only_never_what_is_detected():
    a, b = _episode("dense", layout="lanes"), _episode("dense")
    assert len(a) == len(b)
    for (oa, ia), (_, ib) in zip(a, b):
        for s in ("camera", "lidar", "radar", "fused"):
            np.testing.assert_array_equal(ia["detections"][s]["position"], ib["detections"][s]["position"])
        edge = round(float(oa[0, 3]) + 1)
        if edge in (0, 2):
            assert not oa[1 if edge == 0 else 3].any()

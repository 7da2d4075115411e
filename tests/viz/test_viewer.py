"""``fog-gym view``: Rerun recordings of a recorded scene and of a live episode, read back with Rerun's reader."""

import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fog_gym import geometry
from fog_gym.dataset import FogDrive
from fog_gym.generate import generate, plan_scenes
from fog_gym.viz.viewer import box_params, fog_channels, radar_to_xyz, read_rrd, view_dataset, view_live

pytest.importorskip("rerun")  # the viz extra is part of the dev extra: never skipped in CI
from rerun.chunk import RrdReader  # noqa: E402

RES = (32, 24)
CAMS = ("CAM_FRONT", "CAM_BACK", "CAM_LEFT", "CAM_RIGHT")
LEVELS = ("light", "moderate", "dense")
PER_CAMERA = ("rgb", "depth", "semantic", "boxes", *(f"fog_{lv}" for lv in LEVELS))
PER_SAMPLE = (
    [f"/world/ego/lidar/{c}/{k}" for c in CAMS for k in PER_CAMERA]
    + ["/world/ego/lidar/points/clean", *(f"/world/ego/lidar/points/fog_{lv}" for lv in LEVELS)]
    + ["/world/ego/lidar/semantic", "/world/ego/lidar/boxes", "/world/ego/radar"]
)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    root = tmp_path_factory.mktemp("view") / "ds"
    generate(root, plan_scenes(2, towns=("highway",), seed=1, resolution=RES, seconds=0.2), progress=False)
    return root


def _column(path, entity, component):
    """``{sample_time: value}`` of one component of one entity in an .rrd file."""
    out = {}
    for chunk in RrdReader(path).stream().collect().stream():
        if chunk.entity_path != entity:
            continue
        rb = chunk.to_record_batch()
        for t, v in zip(rb.column("sample_time").cast("int64").to_pylist(), rb.column(component).to_pylist(), strict=True):
            out[t] = v
    return out


def test_a_recorded_scene_logs_every_entity_once_per_sample(dataset, tmp_path):
    ds = FogDrive(dataset)
    scene = ds.list_scene_names()[1]
    n = len(ds.get_samples_for_scene(ds.get_scene_by_name(scene)["token"]))
    assert n == 3
    rrd = tmp_path / "scene.rrd"
    assert view_dataset(dataset, scene=scene, save=rrd, progress=False) == n
    times = read_rrd(rrd)
    for entity in PER_SAMPLE:
        assert times.get(entity) == n, entity
    for cam in CAMS:  # the frustum: a static pinhole + transform per camera
        assert times[f"/world/ego/lidar/{cam}"] == 0


def test_logged_points_and_boxes_equal_the_files(dataset, tmp_path):
    ds = FogDrive(dataset)
    scene = ds.get_scene_by_name(ds.list_scene_names()[0])
    rrd = tmp_path / "s.rrd"
    view_dataset(dataset, save=rrd, progress=False)
    from fog_gym.dataset.decode import load_channel

    dense = _column(rrd, "/world/ego/lidar/points/fog_dense", "Points3D:positions")
    centers = _column(rrd, "/world/ego/lidar/boxes", "Boxes3D:centers")
    for i, s in enumerate(ds.get_samples_for_scene(scene["token"])):
        paths = ds.get_sample_paths(s["token"], ["LIDAR_TOP_FOG_DENSE", "BBOX_3D"])
        t = round(i * 0.1 * 1e9)  # duration timeline, nanoseconds
        pts = load_channel("LIDAR_TOP_FOG_DENSE", paths["LIDAR_TOP_FOG_DENSE"])
        mirrored = pts[:, :3] * np.float32([1, -1, 1])  # shown right-handed: y negated
        np.testing.assert_array_equal(np.asarray(dense[t], np.float32), mirrored)
        corners = load_channel("BBOX_3D", paths["BBOX_3D"])["bboxes_3d"]
        np.testing.assert_allclose(np.asarray(centers[t] or np.zeros((0, 3))).reshape(-1, 3),
                                   corners.reshape(-1, 8, 3).mean(axis=1) * [1, -1, 1], atol=1e-5)  # fmt: skip


def test_a_live_episode_logs_the_ego_trajectory_and_each_fog_level(tmp_path):
    rrd = tmp_path / "live.rrd"
    assert view_live("merge", ["dense", 75.0], steps=3, resolution=RES, save=rrd, progress=False) == 3
    times = read_rrd(rrd)
    assert times["/world/ego"] == 3
    assert times["/world/trajectory"] == 2  # a path needs two poses
    for entity in ("/world/ego/lidar/points/fog_dense", "/world/ego/lidar/points/fog_75m",
                   "/world/ego/lidar/CAM_FRONT/fog_75m", "/world/ego/lidar/CAM_BACK/boxes"):  # fmt: skip
        assert times[entity] == 3, entity
    assert "/world/ego/lidar/points/fog_light" not in times


def test_bad_arguments_fail_before_any_work(dataset, tmp_path):
    with pytest.raises(KeyError, match="no scene named 'T9_day_scene001'; the scenes are T1_day"):
        view_dataset(dataset, scene="T9_day_scene001", save=tmp_path / "x.rrd")
    with pytest.raises(ValueError, match="steps must be a positive integer"):
        view_live(steps=0, save=tmp_path / "x.rrd")
    with pytest.raises(ValueError, match="fog"):
        view_live(fog=["clear"], save=tmp_path / "x.rrd")
    assert not (tmp_path / "x.rrd").exists()


def test_without_a_display_the_viewer_asks_for_save(dataset, monkeypatch):
    monkeypatch.setattr(sys, "platform", "linux")
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(ValueError, match="no display to open the viewer on: pass save='FILE.rrd' and open"):
        view_dataset(dataset)
    from fog_gym.cli import main

    with pytest.raises(SystemExit, match="fog-gym view: no display to open the viewer on: pass --save FILE.rrd and open"):
        main(["view", "--root", str(dataset)])  # the command line names the flag


def test_cli_view_saves_an_rrd_and_refuses_a_non_rrd_name(dataset, tmp_path):
    rrd = tmp_path / "cli.rrd"
    run = subprocess.run([sys.executable, "-m", "fog_gym.cli", "view", "--root", str(dataset), "--save", str(rrd)],
                         capture_output=True, text=True)  # fmt: skip
    assert run.returncode == 0, run.stderr
    assert "logged 3 samples" in run.stdout and read_rrd(rrd)["/world/ego/lidar/boxes"] == 3
    bad = subprocess.run([sys.executable, "-m", "fog_gym.cli", "view", "--root", str(dataset), "--save", "x.png"],
                         capture_output=True, text=True)  # fmt: skip
    assert bad.returncode == 1 and bad.stderr.strip() == "fog-gym view: --save must name an .rrd file, got x.png"


@settings(max_examples=50, deadline=None)
@given(st.floats(-50, 50), st.floats(-50, 50), st.floats(0.5, 10), st.floats(0.5, 4), st.floats(0.5, 4),
       st.floats(-3.1, 3.1))  # fmt: skip
def test_box_params_invert_box_corners(x, y, length, width, height, yaw):
    corners = geometry.box_corners([[x, y, height / 2]], [[length, width, height]], [yaw])
    center, half, got_yaw = box_params(corners)
    np.testing.assert_allclose(center[0], [x, y, height / 2], atol=1e-9)
    np.testing.assert_allclose(half[0], [length / 2, width / 2, height / 2], atol=1e-9)
    assert abs(np.angle(np.exp(1j * (got_yaw[0] - yaw)))) < 1e-9


def test_radar_rows_become_points_at_their_depth():
    rows = np.array([[-3.0, 0.3, -0.05, 20.0], [1.0, -0.5, 0.1, 7.5]])
    xyz = radar_to_xyz(rows)
    np.testing.assert_allclose(np.linalg.norm(xyz, axis=1), rows[:, 3])
    np.testing.assert_allclose(np.arctan2(xyz[:, 1], xyz[:, 0]), rows[:, 1])
    assert fog_channels(["LIDAR_TOP", "LIDAR_TOP_FOG_LIGHT"], "LIDAR_TOP") == {"light": "LIDAR_TOP_FOG_LIGHT"}

"""Fog on real data (fog_gym.augment): the API on arrays, profiles, depth completion on a scene of known depth, the
three layouts file for file (the nuScenes devkit and its KITTI reader load the output), determinism, resume after
kill -9, the lock, bad inputs, a full disk — and the simulator as the oracle: augmenting a clear fog-gym set's
exports reproduces the simulator's own fog decisions point for point, and its images within 1/255 with true depth."""

from __future__ import annotations

import hashlib
import json
import math
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fog_gym.augment import PROFILES, complete_depth, fog_image, fog_points, load_profile, project_points
from fog_gym.augment.check import camera_errors, lidar_decisions
from fog_gym.augment.run import MANIFEST, augment
from fog_gym.dataset.export import export
from fog_gym.fog.fields import FogBank
from fog_gym.generate import generate, plan_scenes


def digests(root: Path) -> dict[str, str]:
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file() and ".fog-gym" not in str(p)}  # fmt: skip


@pytest.fixture(scope="module")
def sets(tmp_path_factory):
    """A clear fog-gym set (day and night) and its KITTI and nuScenes exports."""
    base = tmp_path_factory.mktemp("augment")
    src = base / "src"
    generate(src, plan_scenes(2, towns=("highway",), seed=3, resolution=(96, 72), seconds=0.3), progress=False)
    export(src, base / "kitti", "kitti", progress=False)
    export(src, base / "nus", "nuscenes", progress=False)
    return {"src": src, "kitti": base / "kitti", "nuscenes": base / "nus", "base": base}


# -- the API -----------------------------------------------------------------------------------------------------
@settings(max_examples=40, deadline=None)
@given(st.integers(0, 300), st.integers(4, 7), st.sampled_from(["kitti", "nuscenes", "fogdrive"]),
       st.sampled_from(["light", "dense", 75.0]))  # fmt: skip
def test_fog_points_keeps_shape_dtype_and_extra_columns_and_is_seeded(n, cols, profile, fog):
    rng = np.random.default_rng(n)
    scale = PROFILES[profile].intensity_scale
    pts = np.c_[rng.uniform(-80, 80, (n, 3)), rng.uniform(0, scale, n), rng.integers(0, 32, (n, cols - 4))].astype(np.float32)
    a = fog_points(pts, fog, profile, np.random.default_rng(1))
    b = fog_points(pts, fog, profile, np.random.default_rng(1))
    assert a.shape == pts.shape and a.dtype == pts.dtype and np.array_equal(a, b)
    assert np.array_equal(a[:, 4:], pts[:, 4:])  # ring, time … kept
    moved = (a[:, :3] != pts[:, :3]).any(1)
    # a fog return lies on its own ray, nearer than the target
    r0, r1 = np.linalg.norm(pts[moved, :3], axis=1), np.linalg.norm(a[moved, :3], axis=1)
    assert (r1 <= r0 + 1e-3).all()
    cos = (pts[moved, :3] * a[moved, :3]).sum(1) / np.maximum(r0 * r1, 1e-9)
    assert (cos > 1 - 1e-5).all()
    # a kept point's intensity is attenuated (to within the model's 0–255 rounding)
    assert (a[~moved, 3] <= pts[~moved, 3] + 0.5 * scale / 255 + 1e-4 * scale).all()
    clear = fog_points(pts, "clear", profile)
    assert np.array_equal(clear[:, :3], pts[:, :3])


def test_bad_points_and_fog_are_clear_errors():
    with pytest.raises(ValueError, match=r"\(N, >=4\)"):
        fog_points(np.zeros((5, 3)), "dense")
    with pytest.raises(ValueError, match="finite"):
        fog_points(np.full((2, 4), np.nan), "dense")
    with pytest.raises(ValueError, match="fog must be one of"):
        fog_points(np.zeros((2, 4)), "soup")
    with pytest.raises(ValueError, match="profile must be one of"):
        fog_points(np.zeros((2, 4)), "dense", "ouster")
    with pytest.raises(ValueError, match="needs a depth map"):
        fog_image(np.zeros((4, 4, 3), np.uint8), np.eye(3), "dense")


def test_a_user_profile_from_json_and_toml_and_unknown_keys_refused(tmp_path):
    (tmp_path / "p.json").write_text(json.dumps({"name": "os1", "intensity_scale": 65535.0, "mount_height_m": 1.9}))
    (tmp_path / "p.toml").write_text('name = "os1"\nintensity_scale = 65535.0\nchannels = 128\n')
    assert load_profile(tmp_path / "p.json").intensity_scale == 65535.0
    assert load_profile(tmp_path / "p.toml").channels == 128
    (tmp_path / "bad.json").write_text(json.dumps({"name": "x", "colour": "red"}))
    with pytest.raises(ValueError, match=r"unknown profile fields \['colour'\]"):
        load_profile(tmp_path / "bad.json")
    with pytest.raises(ValueError, match="intensity_scale must be a positive number"):
        load_profile(tmp_path / "p.json").__class__(name="x", intensity_scale=0)


def test_depth_completion_recovers_a_scene_of_known_depth():
    """A wall at 30 m and a floor: LiDAR-like sparse rows of it complete to the true depth within 2 % where rows are
    near, and the open sky above the wall comes back as sky."""
    h, w = 120, 160
    K = np.array([[100.0, 0, 80], [0, 100.0, 60], [0, 0, 1]])
    T = np.array([[0, -1.0, 0, 0], [0, 0, -1.0, 0.5], [1.0, 0, 0, 0], [0, 0, 0, 1]])  # LiDAR x fwd, y left, z up
    ys = (np.arange(h) + 0.5 - 60) / 100.0
    truth = np.full((h, w), 30.0, np.float32)  # a wall 30 m ahead ...
    floor = 1.5 / np.maximum(ys, 1e-9)  # ... and the ground 1.5 m below the camera
    truth = np.where((ys[:, None] > 0) & (floor[:, None] < 30.0), floor[:, None], truth).astype(np.float32)
    wall_top = 60 - int(100 * 4.0 / 30.0)  # the wall rises 4 m above the camera
    truth[:wall_top] = 0.0  # sky
    sparse = np.zeros_like(truth)
    sparse[wall_top + 2::3, ::2] = truth[wall_top + 2::3, ::2]  # scan rows every 3 pixels
    sky = np.zeros((h, w), bool)
    sky[:60] = True
    dense = complete_depth(sparse, sky)
    inside = slice(wall_top + 4, h - 4)
    rel = np.abs(dense[inside, 4:-4] - truth[inside, 4:-4]) / truth[inside, 4:-4]
    wall = truth[inside, 4:-4] == 30.0
    assert np.median(rel[wall]) < 1e-3  # a flat wall comes back exactly
    # on the floor the depth changes between scan rows; the method fills a gap with its nearer row (by design)
    assert np.median(rel[~wall]) < 0.04 and np.percentile(rel[~wall], 95) < 0.1
    assert (dense[: wall_top - 8] == 1000.0).all()
    # the projection puts each point on its pixel at its planar depth
    p = np.array([[10.0, 0.0, 0.5, 0.3]])
    sp = project_points(p, K, T, (w, h))
    assert sp[60, 80] == pytest.approx(10.0) and (sp > 0).sum() == 1


def test_fog_image_with_depth_is_the_simulators_koschmieder():
    from fog_gym.fog import fog_image as simulator

    rng = np.random.default_rng(0)
    img = rng.integers(0, 255, (24, 32, 3), dtype=np.uint8)
    depth = rng.uniform(1, 200, (24, 32)).astype(np.float32)
    K = np.array([[20.0, 0, 16], [0, 20.0, 12], [0, 0, 1]])
    A = np.array([200.0, 205.0, 210.0])
    assert np.array_equal(fog_image(img, K, "dense", depth=depth, airlight=A), simulator(img, depth, K, math.log(20) / 50, A))


# -- the layouts and the runner ----------------------------------------------------------------------------------
def test_kitti_output_mirrors_the_input_and_the_devkits_kitti_reader_loads_it(sets, tmp_path):
    pytest.importorskip("nuscenes")
    from nuscenes.utils.kitti import KittiDB

    out = tmp_path / "k"
    r = augment(sets["kitti"], out, "kitti", ["dense"], progress=False)["dense"]
    src_files = {p.relative_to(sets["kitti"]) for p in sets["kitti"].rglob("*") if p.is_file()}
    out_files = {p.relative_to(out) for p in out.rglob("*") if p.is_file() and ".fog-gym" not in str(p)}
    assert out_files == src_files | {Path(MANIFEST)}
    for rel in src_files:
        a, b = sets["kitti"] / rel, out / rel
        if rel.parent.name == "velodyne":
            assert a.stat().st_size == b.stat().st_size  # float32 × 4, as many points
        elif rel.parent.name != "image_2":
            assert os.path.samefile(a, b) or a.read_bytes() == b.read_bytes()  # linked
    assert len(r["files"]) == 2 * len(list((sets["kitti"] / "training" / "velodyne").glob("*.bin"))) and not r["skipped"]
    kitti = KittiDB(root=str(out), splits=("training",))
    token = kitti.tokens[0]
    assert KittiDB.get_pointcloud(token, root=str(out)).points.shape[0] == 4
    manifest = json.loads((out / MANIFEST).read_text())
    assert manifest["fog"]["visibility_m"] == 50.0 and manifest["profile"]["name"] == "kitti"
    assert all(len(f["source_sha256"]) == 64 for f in manifest["files"])


def test_nuscenes_output_loads_in_the_devkit_and_keeps_the_ring_column(sets, tmp_path):
    pytest.importorskip("nuscenes")
    from nuscenes import NuScenes
    from nuscenes.utils.data_classes import LidarPointCloud

    out = tmp_path / "n"
    augment(sets["nuscenes"], out, "nuscenes", ["light", "dense"], progress=False)
    nusc = NuScenes(version="v1.0-trainval", dataroot=str(out / "dense"), verbose=False)
    sd = nusc.get("sample_data", nusc.sample[0]["data"]["LIDAR_TOP"])
    path = out / "dense" / sd["filename"]
    pc = LidarPointCloud.from_file(str(path))
    raw = np.fromfile(path, np.float32).reshape(-1, 5)
    src = np.fromfile(sets["nuscenes"] / sd["filename"], np.float32).reshape(-1, 5)
    assert pc.points.shape[1] == len(src) and np.array_equal(raw[:, 4], src[:, 4])
    assert np.array_equal(raw[:, 3], np.rint(raw[:, 3]))  # intensities stay whole numbers 0–255
    cam = nusc.get("sample_data", nusc.sample[0]["data"]["CAM_FRONT"])
    magic = (sets["nuscenes"] / cam["filename"]).read_bytes()[:4]
    assert (out / "dense" / cam["filename"]).read_bytes()[:4] == magic  # the same encoding (fog-gym's export: PNG)
    assert (out / "dense" / cam["filename"]).read_bytes() != (sets["nuscenes"] / cam["filename"]).read_bytes()


@pytest.mark.parametrize("fmt, level", [("kitti", "dense"), ("nuscenes", "moderate"), ("fogdrive", "light")])
def test_the_lidar_fog_equals_the_simulators_decisions_point_for_point(sets, tmp_path, fmt, level):
    src = sets["src"] if fmt == "fogdrive" else sets[fmt]
    out = tmp_path / fmt
    augment(src, out, fmt, [level], sensors=("lidar",), progress=False)
    r = lidar_decisions(sets["src"], out, fmt, level)
    assert r["points"] > 1000 and r["agree"] == r["points"] and r["kept_points_equal"]
    assert r["replaced_simulator"] > 0


def test_a_fog_bank_on_the_api_reproduces_the_simulators_bank(tmp_path):
    """With the field and the LiDAR's place in the field frame from the set's records, fog_points makes the
    simulator's decisions in a bank."""
    from fog_gym.dataset.access import FogDrive
    from fog_gym.dataset.decode import load_channel
    from fog_gym.fog.fields import field_from_info

    root = tmp_path / "banks"
    generate(root, plan_scenes(2, towns=("highway",), seed=0, resolution=(32, 24), seconds=0.3, fog_fields="banks"),
             progress=False)  # fmt: skip
    ds = FogDrive(root)
    checked = 0
    for s in ds.sample:
        rec, pose = ds.get_fog_field(s["token"]), ds.get_ego_pose(s["token"])
        p = ds.get_sample_paths(s["token"], ["LIDAR_TOP", "LIDAR_TOP_FOG_DENSE"])
        clean, sim = load_channel("LIDAR_TOP", p["LIDAR_TOP"]), load_channel("LIDAR_TOP_FOG_DENSE", p["LIDAR_TOP_FOG_DENSE"])
        c, sn = math.cos(pose.yaw), math.sin(pose.yaw)
        ego_to_world = np.array([[c, -sn, 0, pose.translation[0]], [sn, c, 0, pose.translation[1]],
                                 [0, 0, 1, pose.translation[2]], [0, 0, 0, 1.0]])  # fmt: skip
        x0, y0, h = rec.frame
        ch, sh = math.cos(h), math.sin(h)
        world_to_field = np.array([[ch, sh, 0, -(ch * x0 + sh * y0)], [-sh, ch, 0, sh * x0 - ch * y0], [0, 0, 1, 0],
                                   [0, 0, 0, 1.0]])  # fmt: skip
        s2f = world_to_field @ ego_to_world @ pose.lidar_to_ego
        out = fog_points(clean, field_from_info(rec.fields["dense"]), "fogdrive", sensor_to_field=s2f, time=rec.time)
        m_sim, m_aug = (sim[:, :3] != clean[:, :3]).any(1), (out[:, :3] != clean[:, :3]).any(1)
        assert np.array_equal(m_sim, m_aug)
        checked += m_sim.sum()
    assert checked > 0


def test_fogdrive_images_equal_the_simulators_within_one_level_with_true_depth(sets, tmp_path):
    for level in ("light", "dense"):
        r = camera_errors(sets["src"], level, completed=False)
        assert r["max_abs"] <= 1, level  # day and night (with the glow of lit fog)
    # with LiDAR-completed depth (docs/augment.md's table at 640 × 480: 31.7 / 34.0 / 38.5 dB against the horizon
    # rule's 24.8 / 27.6 / 33.1): at this set's 96 × 72 the image's sky still beats the horizon rule at every level
    for level, margin in (("light", 1.0), ("moderate", 0.5), ("dense", 0.2)):
        image, horizon = camera_errors(sets["src"], level, True), camera_errors(sets["src"], level, True, sky="horizon")
        assert image["psnr"] > horizon["psnr"] + margin, (level, image["psnr"], horizon["psnr"])
    assert image["psnr"] >= 30.0  # dense


def test_runs_are_deterministic_per_seed_and_file(sets, tmp_path):
    a, b, c = tmp_path / "a", tmp_path / "b", tmp_path / "c"
    augment(sets["kitti"], a, "kitti", ["dense"], seed=7, progress=False)
    augment(sets["kitti"], b, "kitti", ["dense"], seed=7, workers=2, progress=False)
    augment(sets["kitti"], c, "kitti", ["dense"], seed=8, progress=False)
    assert digests(a) == digests(b)
    changed = [k for k, v in digests(a).items() if digests(c).get(k) != v and k.endswith(".bin")]
    assert changed  # another seed, other fog-return ranges


def test_resume_after_kill_minus_9_gives_the_uninterrupted_bytes(sets, tmp_path):
    whole = tmp_path / "whole"
    augment(sets["nuscenes"], whole, "nuscenes", ["dense"], seed=1, progress=False)
    part = tmp_path / "part"
    cmd = [sys.executable, "-m", "fog_gym.cli", "augment", str(sets["nuscenes"]), str(part), "--format", "nuscenes",
           "--fog", "dense", "--seed", "1"]  # fmt: skip
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 60
    while time.time() < deadline and not any((part / ".fog-gym-augment").rglob("*.json")):
        time.sleep(0.01)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    with pytest.raises(ValueError, match="not empty; pass --resume"):
        augment(sets["nuscenes"], part, "nuscenes", ["dense"], seed=1, progress=False)
    with pytest.raises(ValueError, match="other settings \\(seed\\)"):
        augment(sets["nuscenes"], part, "nuscenes", ["dense"], seed=2, resume=True, progress=False)
    augment(sets["nuscenes"], part, "nuscenes", ["dense"], seed=1, resume=True, progress=False)
    assert digests(part) == digests(whole)
    assert not [p for p in part.rglob("*") if ".tmp" in p.name or p.name.endswith(".link")]


def test_one_writer_per_output_root(sets, tmp_path):
    from fog_gym.dataset.lock import DatasetLock, DatasetLocked

    out = tmp_path / "locked"
    with DatasetLock(out, "someone else"):
        with pytest.raises(DatasetLocked, match="being written by"):
            augment(sets["kitti"], out, "kitti", ["dense"], progress=False)


def test_bad_input_files_are_named_and_skipped_or_stop_the_run(sets, tmp_path):
    import shutil

    broken = tmp_path / "broken"
    shutil.copytree(sets["kitti"], broken)
    bins = sorted((broken / "training" / "velodyne").glob("*.bin"))
    bins[0].write_bytes(bins[0].read_bytes()[:-6])  # truncated
    calibs = sorted((broken / "training" / "calib").glob("*.txt"))
    calibs[1].unlink()  # missing calibration
    pngs = sorted((broken / "training" / "image_2").glob("*.png"))
    pngs[2].write_bytes(b"not a png")
    with pytest.raises(ValueError, match=rf"{re.escape(str(bins[0]))}: truncated or wrong-shaped point file"):
        augment(broken, tmp_path / "stop", "kitti", ["dense"], progress=False)
    r = augment(broken, tmp_path / "skip", "kitti", ["dense"], on_error="skip", progress=False)["dense"]
    reasons = {s["file"]: s["skipped"] for s in r["skipped"]}
    assert set(reasons) == {f"training/velodyne/{bins[0].name}", f"training/image_2/{pngs[1].name}",
                            f"training/image_2/{pngs[2].name}", f"training/image_2/{pngs[0].name}"}  # fmt: skip
    assert "calibration" in reasons[f"training/image_2/{pngs[1].name}"]
    assert "not a decodable image" in reasons[f"training/image_2/{pngs[2].name}"]
    # the fourth: its scan (needed for depth) is the truncated one


def test_the_command_line_reports_a_full_disk_in_one_line(sets, tmp_path):
    from fog_gym.dataset.writer import FAULT_VARIABLE

    env = {**os.environ, FAULT_VARIABLE: "ENOSPC:5"}
    r = subprocess.run([sys.executable, "-m", "fog_gym.cli", "augment", str(sets["kitti"]), str(tmp_path / "full"),
                        "--format", "kitti", "--fog", "dense"], capture_output=True, text=True, env=env)  # fmt: skip
    lines = [ln.split("\r")[-1] for ln in r.stderr.splitlines() if ln.strip()]
    lines = [ln for ln in lines if not ln.startswith("augment")]  # the progress bar
    assert r.returncode == 1 and len(lines) == 1 and lines[0].startswith("fog-gym augment: ")
    assert "No space left on device" in lines[0]


@pytest.mark.parametrize("kwargs, message", [
    ({"fmt": "waymo"}, "format must be one of"),
    ({"fogs": []}, "at least one fog"),
    ({"sensors": ("radar",)}, "sensors must be a non-empty subset"),
    ({"on_error": "ignore"}, "on_error must be stop or skip"),
    ({"workers": 0}, "workers must be a positive integer"),
    ({"jpeg_quality": 101}, "jpeg_quality"),
    ({"fogs": ["dense", 50.0]}, "distinct names"),
])  # fmt: skip
def test_bad_options_fail_before_any_work(sets, tmp_path, kwargs, message):
    args = {"src": sets["kitti"], "dst": tmp_path / "o", "fmt": "kitti", "fogs": ["dense"], **kwargs}
    with pytest.raises(ValueError, match=message):
        augment(progress=False, **args)
    assert not (tmp_path / "o").exists()


def test_a_fog_bank_from_the_command_line(sets, tmp_path):
    bank = FogBank(40.0, start=20.0, length=60.0, edge=5.0, name="wall")
    from fog_gym.fog.fields import field_json

    (tmp_path / "bank.json").write_text(field_json(bank))
    r = subprocess.run([sys.executable, "-m", "fog_gym.cli", "augment", str(sets["kitti"]), str(tmp_path / "b"),
                        "--format", "kitti", "--fog", str(tmp_path / "bank.json")], capture_output=True, text=True)  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert json.loads((tmp_path / "b" / MANIFEST).read_text())["fog"]["type"] == "FogBank"

"""Recording FogDrive scenes and reading them back through the access class."""

import json

import cv2
import numpy as np
import pytest

import fog_gym
from fog_gym.dataset import CHANNELS, FogDrive, build_index
from fog_gym.encoding import decode_depth
from fog_gym.wrappers import RecordFogDrive

RES = (48, 36)


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    root = tmp_path_factory.mktemp("fogdrive")
    kept = []  # (scene folder, [(obs, info), ...]) as the env returned them
    for town, tod, seed in (("highway", "day", 0), ("roundabout", "night", 1)):
        env = RecordFogDrive(fog_gym.FogDriveEnv(town=town, time_of_day=tod, resolution=RES, episode_seconds=0.3), root)
        obs, info = env.reset(seed=seed)
        frames = [(obs, info)]
        done = False
        while not done:
            obs, _, term, trunc, info = env.step(1)
            frames.append((obs, info))
            done = term or trunc
        kept.append((frames[0][1]["scene_folder"], frames))
        env.close()
    return root, kept


def test_every_sample_has_35_channels_and_files(recorded):
    root, kept = recorded
    ds = FogDrive(root)
    assert len(ds.scene) == 2 and len(ds.sample) == sum(len(f) for _, f in kept)
    assert ds.list_channels() == sorted(CHANNELS)
    for s in ds.sample:
        paths = ds.get_sample_paths(s["token"])
        assert len(paths) == 35 and all(p.exists() for p in paths.values())
    for rec in ds.sample_data:
        assert rec["filename"].startswith("data_root/")
        if rec["fileformat"] == "png":
            assert (rec["width"], rec["height"]) == RES
    assert {sc["name"] for sc in ds.scene} == {"T1_day_scene001", "T3_night_scene001"}


def test_clean_and_fog_files_come_from_one_render(recorded):
    root, kept = recorded
    ds = FogDrive(root)
    folder, frames = kept[0]
    scene = next(sc for sc in ds.scene if folder in sc["extrinsic_config_path"])
    samples = ds.get_samples_for_scene(scene["token"])
    assert [s["timestamp"] for s in samples] == [i * 1e5 for i in range(len(frames))]
    for s, (obs, info) in zip(samples, frames):
        p = ds.get_sample_paths(s["token"])
        clean = cv2.imread(str(p["CAM_FRONT"]))[..., ::-1]
        dense = cv2.imread(str(p["CAM_FRONT_FOG_DENSE"]))[..., ::-1]
        np.testing.assert_array_equal(clean, obs["CAM_FRONT"])
        np.testing.assert_array_equal(dense, obs["CAM_FRONT_FOG_DENSE"])
        assert not np.array_equal(clean, dense)
        depth = decode_depth(cv2.imread(str(p["CAM_FRONT_DEPTH"]))[..., ::-1])
        np.testing.assert_allclose(depth, obs["CAM_FRONT_DEPTH"], atol=1e-3)  # within 1 mm
        assert np.array_equal(cv2.imread(str(p["CAM_FRONT_SEM"]))[..., 2], obs["CAM_FRONT_SEM"])  # tag in red
        lidar = np.load(p["LIDAR_TOP"])
        assert lidar.dtype == np.float32 and lidar.shape[1] == 4
        assert np.load(p["LIDAR_TOP_FOG_DENSE"]).shape == lidar.shape  # N out = N in
        assert np.array_equal(np.load(p["SEM_LIDAR_TOP"]), fog_gym.unpack_points(obs, "SEM_LIDAR_TOP"))
        b2 = json.loads(p["CAM_FRONT_BBOX"].read_text())
        assert b2["bboxes"] == info["boxes_2d"]["CAM_FRONT"]["bboxes"].tolist()
        assert b2["vehicle_ids"] == info["boxes_2d"]["CAM_FRONT"]["vehicle_ids"].tolist()
        b3 = json.loads(p["BBOX_3D"].read_text())
        np.testing.assert_allclose(np.array(b3["bboxes_3d"]).reshape(-1, 8, 3), info["boxes_3d"]["corners"])
    ext = ds.load_extrinsic_config(scene["token"])
    assert sorted(ext) == ["extrinsic_back", "extrinsic_front", "extrinsic_left", "extrinsic_right"]
    np.testing.assert_allclose(ext["extrinsic_front"], frames[0][1]["extrinsics"]["extrinsic_front"])


def test_access_class_methods(recorded):
    root, _ = recorded
    ds = FogDrive(root)
    scene = ds.get_scene_by_name("T3_night_scene001")
    assert ds.get("scene", scene["token"]) is scene and ds.get_idx("scene", scene["token"]) == 1
    samples = ds.get_samples_for_scene(scene["token"])
    assert samples[0]["token"] == scene["first_sample_token"] and samples[-1]["token"] == scene["last_sample_token"]
    assert samples[0]["prev"] == "" and samples[-1]["next"] == "" and samples[1]["prev"] == samples[0]["token"]
    assert len(samples) == scene["nbr_samples"]
    recs = ds.get_sample_data_for_sample(samples[1]["token"], channels=["LIDAR_TOP", "CAM_BACK_SEM"])
    assert [r["channel"] for r in recs] == ["LIDAR_TOP", "CAM_BACK_SEM"]
    assert ds.get_sample_data_path(recs[0]["token"]) == root / recs[0]["filename"]
    rel = ds.get_sample_paths(samples[1]["token"], ["RADAR_FRONT"], absolute=False)
    assert rel["RADAR_FRONT"].startswith("data_root/data_collection_T3_night_run1_")
    assert ds.field2token("sample", "scene_token", scene["token"]) == [s["token"] for s in samples]
    tokens = [r["token"] for t in ("scene", "sample", "sample_data") for r in getattr(ds, t)]
    assert len(set(tokens)) == len(tokens) and all(t[14] == "4" for t in tokens)  # uuid4 format
    with pytest.raises(KeyError, match="no scene named"):
        ds.get_scene_by_name("T9_day_scene001")
    with pytest.raises(ValueError, match="table_name must be one of"):
        ds.get("samples", "x")
    assert [sc["name"] for sc in ds.get_scenes_for_split("train")] == ["T1_day_scene001", "T3_night_scene001"]
    assert ds.get_sample_tokens_for_split("train") == [s["token"] for s in ds.get_samples_for_split("train")]
    assert ds.get_scenes_for_split("val") == [] and len(ds.get_samples_for_split("train")) == len(ds.sample)
    with pytest.raises(ValueError, match="split must be one of"):
        ds.get_scenes_for_split("validation")


def test_index_rebuilds_identically_from_disk(recorded, tmp_path):
    root, _ = recorded
    before = {t: (root / "index" / f"{t}.json").read_bytes() for t in ("scene", "sample", "sample_data", "splits")}
    build_index(root)
    assert {t: (root / "index" / f"{t}.json").read_bytes() for t in before} == before


def test_incomplete_sample_is_left_out(recorded, tmp_path):
    import shutil

    root, kept = recorded
    copy = tmp_path / "copy"
    shutil.copytree(root, copy)
    folder = kept[0][0]
    last = max((copy / "data_root" / folder / "out_3dbbox").iterdir())
    last.unlink()  # as if the process died while writing the last sample
    build_index(copy)
    ds = FogDrive(copy)
    assert len(ds.sample) == len(FogDrive(root).sample) - 1


def test_splits_rules_on_a_generated_set():
    from fog_gym.dataset.splits import check_splits, make_splits

    for towns, per in (([1], 10), ([1, 2, 3, 4, 5, 6], 20)):  # 20 scenes of one town; 240 over six towns
        names = [f"T{t}_{d}_scene{i:03d}" for t in towns for d in ("day", "night") for i in range(1, per + 1)]
        splits = make_splits(names, seed=3)
        r = check_splits(splits, names)
        assert r["duplicate_assignments"] == r["scenes_in_no_split"] == r["scenes_in_split_but_not_in_index"] == []
        assert all(v == 0.5 for v in r["day_share"].values())
        assert abs(r["fractions"]["train"] - 0.7) <= 0.05 and abs(r["fractions"]["test"] - 0.15) <= 0.05
        assert max(r["max_town_share_deviation_points"].values()) <= 2.0 + 1e-9
        assert make_splits(names, seed=3) == splits  # deterministic


def test_generate_resume_validate(tmp_path):
    import hashlib
    import subprocess
    import sys

    from fog_gym.dataset.validate import validate
    from fog_gym.generate import PROGRESS_DIR, check_root, generate, plan_scenes

    root = tmp_path / "gen"
    plan = plan_scenes(4, towns=("merge", "roundabout"), seed=7, resolution=(32, 24), seconds=0.2)
    generate(root, plan, workers=1, progress=False)
    assert validate(root) == []

    def digest(folder):
        return {p.relative_to(root): hashlib.sha256(p.read_bytes()).hexdigest()
                for p in sorted((root / "data_root" / folder).rglob("*")) if p.is_file()}  # fmt: skip

    before = digest(plan[1].folder)
    # a run killed mid-scene: the scene's marker is missing and half its files are gone
    (root / PROGRESS_DIR / f"{plan[1].folder}.json").unlink()
    for p in list((root / "data_root" / plan[1].folder / "lidar").iterdir())[:1]:
        p.unlink()
    for p in (root / "data_root" / plan[1].folder / "out_3dbbox").iterdir():
        p.unlink()
    with pytest.raises(ValueError, match="not empty; pass resume=True"):  # the keyword from Python (--resume in the CLI)
        check_root(root, resume=False)
    generate(root, plan, workers=1, resume=True, progress=False)
    assert digest(plan[1].folder) == before  # regenerated bit for bit from (seed, scene index)
    assert validate(root) == [] and len(FogDrive(root).scene) == 4
    # validate reports problems and the command exits non-zero
    (root / "data_root" / plan[0].folder / "radar" / "000001.npy").unlink()
    problems = validate(root)
    assert any("missing file" in p for p in problems)
    out = subprocess.run([sys.executable, "-m", "fog_gym.cli", "validate", str(root)], capture_output=True, text=True)
    assert out.returncode == 1 and "missing file" in out.stdout


def test_generate_rejects_bad_input_before_rendering(tmp_path):
    from fog_gym.generate import check_root, plan_scenes

    with pytest.raises(ValueError, match="even number"):
        plan_scenes(3)
    with pytest.raises(ValueError, match="town must be one of"):
        plan_scenes(2, towns=("Town01",))
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(ValueError, match="not a folder"):
        check_root(blocker, resume=False)
    plan = plan_scenes(12, seed=1)
    assert sum(p.time_of_day == "day" for p in plan) == 6 and len({p.folder for p in plan}) == 12
    assert plan_scenes(12, seed=1) == plan and plan_scenes(12, seed=2)[0].seed != plan[0].seed


def test_load_sample_decodes_every_channel(recorded):
    from fog_gym.dataset.torch import load_sample

    root, kept = recorded
    ds = FogDrive(root)
    s = ds.sample[1]
    data = load_sample(ds, s["token"])
    assert set(data) == set(CHANNELS)
    assert data["CAM_LEFT"].shape == (36, 48, 3) and data["CAM_LEFT"].dtype == np.uint8
    assert data["CAM_LEFT_DEPTH"].dtype == np.float32 and data["CAM_LEFT_SEM"].dtype == np.uint8
    assert data["SEM_LIDAR_TOP"].shape[1] == 6 and data["BBOX_3D"]["bboxes_3d"].shape[1:] == (8, 3)
    assert data["CAM_FRONT_BBOX"]["bboxes"].shape[1:] == (2, 2)


def test_torch_dataset_and_collate(recorded):
    torch = pytest.importorskip("torch")
    from fog_gym.dataset.torch import FogDriveDataset, collate

    root, _ = recorded
    ds = FogDriveDataset(root, split="train", channels=["CAM_FRONT_FOG_DENSE", "CAM_FRONT_DEPTH", "LIDAR_TOP", "BBOX_3D"])
    assert len(ds) == len(FogDrive(root).sample)
    loader = torch.utils.data.DataLoader(ds, batch_size=3, collate_fn=collate)
    batch = next(iter(loader))
    assert batch["CAM_FRONT_FOG_DENSE"].shape == (3, 3, 36, 48) and batch["CAM_FRONT_DEPTH"].shape == (3, 36, 48)
    assert len(batch["LIDAR_TOP"]) == 3 and batch["LIDAR_TOP"][0].shape[1] == 4  # variable-size clouds stay a list
    assert len(batch["BBOX_3D"]) == 3 and len(batch["sample_token"]) == 3
    with pytest.raises(ValueError, match="channels must be FogDrive channel names"):
        FogDriveDataset(root, channels=["CAM_TOP"])
    with pytest.raises(ValueError, match="split must be one of"):
        FogDriveDataset(root, split="dev")


def test_killed_generation_resumes_to_a_valid_set(tmp_path):
    """A real ``kill -9`` in the middle of a run, then ``--resume``: the set validates, nothing is duplicated, and it
    is byte for byte the uninterrupted run's. While the first run writes, a second writer on the root (``--resume``)
    exits 1 with one line naming the root and the holder; after the kill the lock it left is stale and taken over."""
    import hashlib
    import os
    import re
    import signal
    import socket
    import subprocess
    import sys
    import time

    from fog_gym.dataset.lock import LOCK_FILE, read_holder
    from fog_gym.dataset.validate import validate
    from fog_gym.generate import PROGRESS_DIR, generate, plan_scenes

    root = tmp_path / "killed"
    cmd = [sys.executable, "-m", "fog_gym.cli", "generate", "--root", str(root), "--scenes", "4", "--resolution",
           "24x16", "--seconds", "0.5", "--towns", "merge", "--seed", "5"]  # fmt: skip
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 120
    while time.time() < deadline and not list((root / PROGRESS_DIR).glob("*.json")):
        time.sleep(0.01)
    # frozen at its first finished scene, so that the second writer meets a live holder and the kill finds the run
    # unfinished however fast the machine (a running first writer could finish all four scenes meanwhile)
    os.kill(proc.pid, signal.SIGSTOP)
    second = subprocess.run(cmd + ["--resume"], capture_output=True, text=True)
    proc.kill()
    proc.wait()
    assert second.returncode == 1 and len(second.stderr.strip().splitlines()) == 1, second.stderr
    assert re.fullmatch(rf"fog-gym generate: dataset root {re.escape(str(root))} is being written by pid {proc.pid} on "
                        rf"host {re.escape(socket.gethostname())} since \S+ \(generate\); .+\n", second.stderr), second.stderr
    assert read_holder(root)["pid"] == proc.pid  # the killed run's record stays; its lock went with it
    done_before = len(list((root / PROGRESS_DIR).glob("*.json")))
    assert 1 <= done_before < 4
    out = subprocess.run(cmd + ["--resume"], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert f"took over the stale lock of {root} left by pid {proc.pid}" in out.stderr
    assert not (root / LOCK_FILE).exists()
    assert validate(root) == []
    ds = FogDrive(root)
    assert ds.list_scene_names() == sorted(f"T2_{d}_scene{r:03d}" for r in (1, 2) for d in ("day", "night"))
    assert len(list((root / "data_root").iterdir())) == 4  # no duplicated scene folders
    clean = tmp_path / "clean"
    generate(clean, plan_scenes(4, towns=("merge",), seed=5, resolution=(24, 16), seconds=0.5), progress=False)
    digest = lambda r: {str(p.relative_to(r)): hashlib.sha256(p.read_bytes()).hexdigest()  # noqa: E731
                        for p in sorted(r.rglob("*")) if p.is_file()}  # fmt: skip
    assert digest(root) == digest(clean)
    assert subprocess.run(cmd, capture_output=True, text=True).returncode != 0  # non-empty root without --resume


def test_generated_set_of_20_scenes_meets_the_split_rules(tmp_path):
    from fog_gym.generate import generate, plan_scenes
    from fog_gym.dataset.splits import check_splits

    plan = plan_scenes(20, towns=("roundabout",), seed=2, resolution=(16, 12), seconds=0.1)
    generate(tmp_path / "g", plan, progress=False)
    ds = FogDrive(tmp_path / "g")
    assert len(ds.scene) == 20
    r = check_splits(ds.splits, ds.list_scene_names())
    assert r["duplicate_assignments"] == r["scenes_in_no_split"] == r["scenes_in_split_but_not_in_index"] == []
    assert len(ds.splits["train"]) == 14 and sorted([len(ds.splits["val"]), len(ds.splits["test"])]) == [2, 4]
    assert all(v == 0.5 for v in r["day_share"].values())


@pytest.mark.parametrize("scenes, towns, expected", [
    (2, None, {"highway": 1}),
    (4, None, {"highway": 1, "merge": 1}),
    (12, None, {t: 1 for t in ("highway", "merge", "roundabout", "intersection", "racetrack", "exit")}),
    (14, None, {"highway": 2, **{t: 1 for t in ("merge", "roundabout", "intersection", "racetrack", "exit")}}),
    (6, ("roundabout", "exit"), {"roundabout": 2, "exit": 1}),
])  # fmt: skip
def test_scenes_are_dealt_to_the_towns_as_the_datasets_page_says(scenes, towns, expected):
    """docs/datasets.md: P pairs over T towns in --towns order, ⌊P/T⌋ each and one more for the first P mod T."""
    from collections import Counter

    from fog_gym.generate import plan_scenes

    plan = plan_scenes(scenes, **({"towns": towns} if towns else {}))
    assert Counter(s.town for s in plan if s.time_of_day == "day") == expected
    assert Counter(s.time_of_day for s in plan) == {"day": scenes // 2, "night": scenes // 2}


def test_the_content_digest_changes_with_one_byte_and_not_with_scene_order(tmp_path):
    from fog_gym.dataset.digest import content_digest

    class Tiny:  # the three FogDrive lookups the digest uses, over two scenes of two samples with one file each
        dataroot = tmp_path

        def get_scene_by_name(self, name):
            return {"token": name}

        def get_samples_for_scene(self, token):
            return [{"token": f"{token}-0"}, {"token": f"{token}-mid"}, {"token": f"{token}-1"}]

        def get_sample_paths(self, sample):
            return {"LIDAR_TOP": tmp_path / f"{sample}.bin"}

    for scene in ("a", "b"):
        for i in ("0", "mid", "1"):
            (tmp_path / f"{scene}-{i}.bin").write_bytes(f"{scene}{i}".encode())
    ds = Tiny()
    before = content_digest(ds, ["a", "b"])
    assert before == content_digest(ds, ["b", "a", "b"]) and before.startswith("sha256:")
    (tmp_path / "b-mid.bin").write_bytes(b"changed")  # only the first and last samples are read
    assert content_digest(ds, ["a", "b"]) == before
    (tmp_path / "b-1.bin").write_bytes(b"b2")
    assert content_digest(ds, ["a", "b"]) != before

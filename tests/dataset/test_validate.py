"""``fog-gym validate`` / ``stats`` on broken datasets, the generation manifest, and path safety of the readers."""

import json
import shutil
import subprocess
import sys

import cv2
import numpy as np
import pytest

from fog_gym.dataset import FogDrive
from fog_gym.dataset.access import DatasetError
from fog_gym.dataset.decode import load_channel
from fog_gym.generate import generate, plan_scenes
from fog_gym.dataset.manifest import MANIFEST_FILE, read_manifest
from fog_gym.dataset.validate import stats, validate

RES = (32, 24)


@pytest.fixture(scope="module")
def pristine(tmp_path_factory):
    root = tmp_path_factory.mktemp("valid") / "ds"
    generate(root, plan_scenes(2, towns=("highway",), seed=3, resolution=RES, seconds=0.2), progress=False)
    assert validate(root) == []
    return root


@pytest.fixture
def dataset(pristine, tmp_path):
    root = tmp_path / "ds"
    shutil.copytree(pristine, root)
    return root


def _file(root, channel, sample=1):
    ds = FogDrive(root)
    rec = ds.get_sample_data_for_sample(ds.sample[sample]["token"], [channel])[0]
    return root / rec["filename"], rec["filename"]


def _truncate(path):
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])


def _empty(path):
    path.write_bytes(b"")


def _grey_png(path):
    cv2.imwrite(str(path), np.zeros((RES[1], RES[0]), np.uint8))


def _small_png(path):
    cv2.imwrite(str(path), np.zeros((12, 16, 3), np.uint8))


def _npy_4_columns(path):
    np.save(path, np.zeros((5, 4), np.float32))


def _npy_float64(path):
    np.save(path, np.zeros((5, 4), np.float64))


def _npy_nan(path):
    np.save(path, np.full((2, 4), np.nan, np.float32))


def _json_garbage(path):
    path.write_text("{not json")


def _boxes_3d_wrong_shape(path):
    path.write_text(json.dumps({"bboxes_3d": [[1, 2, 3]], "vehicle_ids": [4]}))


def _boxes_2d_ids_mismatch(path):
    path.write_text(json.dumps({"bboxes": [[[0, 0], [2, 2]]], "vehicle_ids": [4, 5], "vehicle_class": [0]}))


def _boxes_2d_missing_key(path):
    path.write_text(json.dumps({"bboxes": []}))


CORRUPTIONS = [
    ("CAM_FRONT", _truncate, "truncated or corrupt PNG"),
    ("CAM_BACK_FOG_DENSE", _empty, "empty file"),
    ("CAM_LEFT_DEPTH", _truncate, "truncated or corrupt PNG"),
    ("CAM_RIGHT_SEM", _grey_png, "expected an 8-bit RGB PNG"),
    ("CAM_FRONT_FOG_LIGHT", _small_png, "image is 16×12, expected 32×24"),
    ("LIDAR_TOP", _truncate, "truncated or corrupt .npy"),
    ("RADAR_FRONT", _empty, "empty file"),
    ("SEM_LIDAR_TOP", _npy_4_columns, "expected float32 (N, 6)"),
    ("LIDAR_TOP_FOG_DENSE", _npy_float64, "expected float32 (N, 4)"),
    ("LIDAR_TOP_FOG_LIGHT", _npy_nan, "NaN"),
    ("CAM_FRONT_BBOX", _json_garbage, "corrupt JSON"),
    ("CAM_BACK_BBOX", _empty, "empty file"),
    ("CAM_LEFT_BBOX", _boxes_2d_ids_mismatch, "one entry per box"),
    ("CAM_RIGHT_BBOX", _boxes_2d_missing_key, "missing keys"),
    ("BBOX_3D", _boxes_3d_wrong_shape, "wrongly shaped boxes"),
]


@pytest.mark.parametrize("channel, corrupt, message", CORRUPTIONS, ids=[f"{c[0]}-{c[1].__name__}" for c in CORRUPTIONS])
def test_validate_names_each_corrupt_file_and_never_raises(dataset, channel, corrupt, message):
    path, rel = _file(dataset, channel)
    corrupt(path)
    problems = validate(dataset)
    assert problems == [f"{rel}: {problems[0].split(': ', 1)[1]}"]  # exactly one line, naming the file
    assert message in problems[0]


def test_validate_reports_a_missing_file_and_bad_extrinsics(dataset):
    path, rel = _file(dataset, "RADAR_FRONT", 0)
    path.unlink()
    ext = next((dataset / "data_root").glob("*/extrinsic_config/extrinsic_config.json"))
    ext.write_text(json.dumps({"extrinsic_front": [[1, 0], [0, 1]]}))
    problems = validate(dataset)
    assert f"{rel}: missing file" in problems
    assert any("extrinsic_config.json: extrinsic_front is missing or not a finite 4×4 matrix" in p for p in problems)


@pytest.mark.parametrize("table", ["scene", "sample", "sample_data", "splits"])
def test_validate_names_a_corrupt_index_file(dataset, table):
    (dataset / "index" / f"{table}.json").write_text('[{"token": ')
    problems = validate(dataset)
    assert len(problems) == 1 and f"index/{table}.json" in problems[0] and "not valid JSON" in problems[0]


@pytest.mark.parametrize("filename", ["../../outside.npy", "/etc/hostname", "data_root/../../x.png"])
def test_index_entries_outside_the_root_are_refused(dataset, filename):
    table = json.loads((dataset / "index" / "sample_data.json").read_text())
    table[3]["filename"] = filename
    (dataset / "index" / "sample_data.json").write_text(json.dumps(table))
    problems = validate(dataset)
    assert len(problems) == 1 and repr(filename) in problems[0]
    with pytest.raises(DatasetError, match="dataset root"):
        FogDrive(dataset)


def test_a_folder_that_is_not_a_dataset_gets_one_clear_line(tmp_path):
    (tmp_path / "README.md").write_text("hello")
    assert validate(tmp_path) == [f"{tmp_path}: not a FogDrive dataset (no index/ folder)"]
    assert validate(tmp_path / "README.md") == [f"{tmp_path / 'README.md'}: not a folder; a FogDrive dataset root holds data_root/ and index/"]
    assert validate(tmp_path / "nope") == [f"{tmp_path / 'nope'}: no such folder"]


def test_cli_validate_prints_one_line_per_problem_without_traceback_or_libpng_noise(dataset):
    _truncate(_file(dataset, "CAM_FRONT")[0])
    _truncate(_file(dataset, "LIDAR_TOP")[0])
    out = subprocess.run([sys.executable, "-m", "fog_gym.cli", "validate", str(dataset)], capture_output=True, text=True)
    assert out.returncode == 1
    assert out.stdout.splitlines()[-1] == "2 problems" and len(out.stdout.splitlines()) == 3
    assert "Traceback" not in out.stderr and "libpng" not in out.stderr


def test_reader_reports_a_corrupt_file_with_its_path(dataset):
    path, _ = _file(dataset, "LIDAR_TOP")
    _truncate(path)
    with pytest.raises(DatasetError, match=str(path)):
        load_channel("LIDAR_TOP", path)
    png, _ = _file(dataset, "CAM_FRONT")
    _truncate(png)
    with pytest.raises(DatasetError, match="not a decodable PNG"):
        load_channel("CAM_FRONT", png)


def test_generate_writes_a_manifest_and_resume_refuses_other_settings(dataset):
    manifest = read_manifest(dataset)
    assert manifest["resolution"] == list(RES) and manifest["scenes"] == 2 and manifest["seed"] == 3
    assert manifest["towns"] == ["highway"] and manifest["fog_levels"] == {"light": 160.0, "moderate": 100.0, "dense": 50.0}
    assert len(manifest["channels"]) == 35 and manifest["fog_gym_version"]
    with pytest.raises(ValueError, match=r"resolution: \[32, 24\] in the dataset, \[16, 12\] now"):
        generate(dataset, plan_scenes(2, towns=("highway",), seed=3, resolution=(16, 12), seconds=0.2), resume=True,
                 progress=False)  # fmt: skip
    cmd = [sys.executable, "-m", "fog_gym.cli", "generate", "--root", str(dataset), "--scenes", "4", "--resolution",
           "32x24", "--seconds", "0.2", "--towns", "highway", "--seed", "3", "--resume"]  # fmt: skip
    out = subprocess.run(cmd, capture_output=True, text=True)
    assert out.returncode == 1 and out.stderr.startswith("fog-gym generate: --resume with settings that differ")
    assert "scenes: 2 in the dataset, 4 now" in out.stderr


def test_validate_checks_files_against_the_manifest(dataset):
    path = dataset / MANIFEST_FILE
    m = json.loads(path.read_text())
    path.write_text(json.dumps({**m, "resolution": [64, 48], "scenes": 3}))
    problems = validate(dataset)
    assert any("2 scenes, the manifest" in p and "says 3" in p for p in problems)
    assert sum("expected 64×48" in p for p in problems) == 6 * 24  # 6 samples × 24 PNGs


def test_stats_refuses_non_datasets_and_plots_only_where_asked(dataset, tmp_path):
    rows = dict((k, n) for k, n, _ in stats(dataset))
    assert rows["out_rgb"] == 4 * 6 and rows["lidar"] == 6 and rows["out_3dbbox"] == 6
    with pytest.raises(ValueError, match="not a FogDrive dataset"):
        stats(tmp_path)
    out = subprocess.run([sys.executable, "-m", "fog_gym.cli", "stats", str(tmp_path)], capture_output=True, text=True)
    assert out.returncode == 1 and out.stderr.startswith("fog-gym stats: ") and not list(tmp_path.glob("*.png"))
    plot = tmp_path / "figs" / "footprint.png"
    out = subprocess.run([sys.executable, "-m", "fog_gym.cli", "stats", str(dataset), "--plot", str(plot)],
                         capture_output=True, text=True)  # fmt: skip
    assert out.returncode == 0 and plot.exists() and not (dataset / "stats.png").exists()


def test_torch_dataset_refuses_index_entries_outside_the_root(dataset):
    pytest.importorskip("torch")
    from fog_gym.dataset.torch import FogDriveDataset

    table = json.loads((dataset / "index" / "sample_data.json").read_text())
    table[0]["filename"] = "/etc/hostname"
    (dataset / "index" / "sample_data.json").write_text(json.dumps(table))
    with pytest.raises(DatasetError, match="absolute"):
        FogDriveDataset(dataset)

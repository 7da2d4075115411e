"""Parallel sample encoding and the pipelined recorder write exactly what the serial writer writes."""

from __future__ import annotations

import hashlib
from pathlib import Path

import pytest

import fog_gym
from fog_gym.dataset import writer as writer_mod
from fog_gym.dataset.layout import CHANNELS, channel_path, scene_folder_name
from fog_gym.dataset.writer import SceneWriter, complete_samples
from fog_gym.wrappers import RecordFogDrive, FogWrapper

RES = (40, 30)
FOLDER = scene_folder_name(1, "day", 1, "00ab12cd")


@pytest.fixture(scope="module")
def frames():
    env = FogWrapper(fog_gym.FogDriveEnv(resolution=RES, episode_seconds=0.3), ["light", "moderate", "dense"])
    obs, info = env.reset(seed=4)
    out = [(obs, info)]
    for _ in range(2):
        obs, _, _, _, info = env.step(1)
        out.append((obs, info))
    env.close()
    return out


def _digests(root: Path) -> dict[str, str]:
    return {
        str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(root.rglob("*")) if p.is_file() and "index" not in p.parts
    }  # fmt: skip


def test_parallel_writer_writes_the_same_bytes_as_serial(tmp_path, frames):
    for workers, sub in ((1, "serial"), (4, "parallel")):
        w = SceneWriter(tmp_path / sub, FOLDER, workers=workers)
        for i, (obs, info) in enumerate(frames):
            w.write_sample(i, obs, info)
        w.close()
    serial, parallel = _digests(tmp_path / "serial"), _digests(tmp_path / "parallel")
    assert len(serial) == len(frames) * len(CHANNELS)
    assert parallel == serial
    assert complete_samples(tmp_path / "parallel", FOLDER) == len(frames)


def test_bbox_3d_is_written_after_every_other_file(tmp_path, frames, monkeypatch):
    order: list[str] = []
    real = writer_mod._atomic_write

    def recording(path, data):
        real(path, data)
        order.append(Path(path))

    monkeypatch.setattr(writer_mod, "_atomic_write", recording)
    w = SceneWriter(tmp_path, FOLDER, workers=4)
    w.write_sample(0, *frames[0])
    w.close()
    assert len(order) == len(CHANNELS)
    assert order[-1] == tmp_path / channel_path("BBOX_3D", FOLDER, 0)
    assert len(set(order)) == len(CHANNELS)


def test_a_failed_file_leaves_the_sample_incomplete(tmp_path, frames, monkeypatch):
    real = writer_mod.encode_npy

    def failing(array):
        raise OSError("disk full")

    monkeypatch.setattr(writer_mod, "encode_npy", failing)
    w = SceneWriter(tmp_path, FOLDER, workers=3)
    with pytest.raises(OSError, match="disk full"):
        w.write_sample(0, *frames[0])
    w.close()
    monkeypatch.setattr(writer_mod, "encode_npy", real)
    assert complete_samples(tmp_path, FOLDER) == 0


@pytest.mark.parametrize("workers", [0, -1, 1.5, True, "4"])
def test_bad_worker_counts_are_rejected(tmp_path, workers):
    with pytest.raises(ValueError, match="workers must be a positive integer or None"):
        SceneWriter(tmp_path, FOLDER, workers=workers)
    with pytest.raises(ValueError, match="workers must be a positive integer or None"):
        RecordFogDrive(fog_gym.FogDriveEnv(resolution=RES), tmp_path, workers=workers)


def test_pipelined_recorder_matches_serial_recorder(tmp_path):
    for workers, sub in ((1, "serial"), (None, "pipelined")):
        env = RecordFogDrive(fog_gym.FogDriveEnv(resolution=RES, episode_seconds=0.3), tmp_path / sub, workers=workers)
        env.reset(seed=2)
        done = False
        while not done:
            _, _, term, trunc, _ = env.step(1)
            done = term or trunc
        env.reset(seed=3)
        env.step(1)
        env.close()
    serial, pipelined = _digests(tmp_path / "serial"), _digests(tmp_path / "pipelined")
    assert len(serial) > 2 * len(CHANNELS)
    assert pipelined == serial
    index = sorted((tmp_path / "pipelined" / "index").glob("*.json"))
    assert [p.read_bytes() for p in index] == [
        (tmp_path / "serial" / "index" / p.name).read_bytes() for p in index
    ]

"""A data path that survives a full disk or a lost permission: ``generate`` (one process and worker processes),
``RecordFogDrive``, ``export`` and the index writer fail with one line ``<what failed> (<path>): <reason>``, leave no
temporary file, and — once the cause is gone — ``--resume`` completes the set byte for byte as an uninterrupted run.

Faults come from the writer's injection hook (``FOG_GYM_FAIL_WRITES=ENOSPC:<n>``: every write from the n-th fails
half-way, in every process) and, where this process may mount one, from a real tmpfs that fills up and is then grown.
"""

from __future__ import annotations

import hashlib
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from fog_gym.dataset import FogDrive
from fog_gym.dataset.validate import validate
from fog_gym.dataset.writer import FAULT_VARIABLE, WriteError, build_index
from fog_gym.generate import generate, plan_scenes

PLAN = dict(towns=("roundabout",), seed=2, resolution=(32, 24), seconds=0.2)
ARGS = ["--scenes", "2", "--towns", "roundabout", "--seed", "2", "--resolution", "32x24", "--seconds", "0.2"]
LINE = re.compile(r"^fog-gym (generate|export): .+ \(/.+\): (No space left on device|Permission denied)$")


def digests(root: Path) -> dict[str, str]:
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file()}  # fmt: skip


def leftovers(root: Path) -> list[str]:
    """Temporary files anywhere under ``root``."""
    return sorted(str(p) for p in root.rglob("*") if p.name.endswith(".tmp") or p.name == ".write_probe")


def cli(*args: str, env: dict | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "fog_gym.cli", *args], capture_output=True, text=True,
                          env={**os.environ, **(env or {})})  # fmt: skip


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    root = tmp_path_factory.mktemp("clean") / "set"
    generate(root, plan_scenes(2, **PLAN), progress=False)
    return root


def test_a_full_disk_in_generate_is_one_error_and_resume_gives_the_uninterrupted_bytes(uninterrupted, tmp_path,
                                                                                        monkeypatch):  # fmt: skip
    root = tmp_path / "set"
    monkeypatch.setenv(FAULT_VARIABLE, "ENOSPC:150")  # in the second scene
    with pytest.raises(WriteError) as failure:
        generate(root, plan_scenes(2, **PLAN), progress=False)
    assert re.fullmatch(r"cannot write sample \d of scene data_collection_\w+ \(/.+\): No space left on device",
                        str(failure.value))  # fmt: skip
    assert leftovers(root) == []
    monkeypatch.delenv(FAULT_VARIABLE)
    generate(root, plan_scenes(2, **PLAN), resume=True, progress=False)
    assert digests(root) == digests(uninterrupted)


@pytest.mark.parametrize("error", ["ENOSPC", "EACCES"])
def test_cli_generate_with_workers_fails_in_one_line_and_resumes_byte_identical(uninterrupted, tmp_path, error):
    root = tmp_path / "set"
    out = cli("generate", "--root", str(root), "--workers", "2", *ARGS, env={FAULT_VARIABLE: f"{error}:60"})
    assert out.returncode == 1 and "Traceback" not in out.stderr
    assert LINE.match(out.stderr.strip().splitlines()[-1]), out.stderr  # the last line, after the progress bar
    assert sum(line.startswith("fog-gym") for line in out.stderr.splitlines()) == 1
    assert leftovers(root) == []  # both workers cleaned up
    out = cli("generate", "--root", str(root), "--workers", "2", *ARGS, "--resume")
    assert out.returncode == 0, out.stderr
    assert digests(root) == digests(uninterrupted)


def _tmpfs(path: Path, size: str) -> bool:
    path.mkdir(parents=True, exist_ok=True)
    if not hasattr(os, "geteuid") or os.geteuid() != 0 or shutil.which("mount") is None:
        return False
    return subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(path)], capture_output=True).returncode == 0


def test_a_real_tmpfs_fills_then_grows_and_resume_completes_the_set(uninterrupted, tmp_path):
    mnt = tmp_path / "tmpfs"
    if not _tmpfs(mnt, "6m"):  # the set needs 19 MB (LiDAR sweeps dominate)
        pytest.skip("needs root to mount a tmpfs (the injection tests cover the same paths)")
    try:
        out = cli("generate", "--root", str(mnt / "set"), *ARGS)
        assert out.returncode == 1 and "Traceback" not in out.stderr
        assert LINE.match(out.stderr.strip().splitlines()[-1]), out.stderr
        assert leftovers(mnt) == []
        subprocess.run(["mount", "-o", "remount,size=40m", str(mnt)], check=True)  # the cause is removed
        out = cli("generate", "--root", str(mnt / "set"), *ARGS, "--resume")
        assert out.returncode == 0, out.stderr
        assert digests(mnt / "set") == digests(uninterrupted)
    finally:
        subprocess.run(["umount", str(mnt)], capture_output=True)


def test_record_fogdrive_on_a_full_disk_raises_one_error_and_keeps_complete_samples(tmp_path, monkeypatch):
    from fog_gym.envs.fogdrive import FogDriveEnv
    from fog_gym.wrappers import RecordFogDrive

    root = tmp_path / "rec"
    env = RecordFogDrive(FogDriveEnv(resolution=(32, 24), episode_seconds=1.0), root, workers=2)
    env.reset(seed=1)
    monkeypatch.setenv(FAULT_VARIABLE, "ENOSPC:80")  # two samples later
    with pytest.raises(WriteError) as failure:
        for _ in range(10):
            env.step(1)
        env.close()
    assert re.fullmatch(r"cannot write sample \d of scene \w+ \(/.+\): No space left on device", str(failure.value))
    monkeypatch.delenv(FAULT_VARIABLE)
    env.close()  # the index of the complete samples
    assert leftovers(root) == []
    ds = FogDrive(root)
    assert 1 <= len(ds.sample) < 11
    problems = validate(root)
    assert all(p.startswith("splits:") for p in problems)  # one day scene: only the 50/50 rule is unmet


def test_the_index_is_written_all_or_nothing(uninterrupted, tmp_path, monkeypatch):
    root = tmp_path / "set"
    shutil.copytree(uninterrupted, root)
    before = digests(root)
    shutil.rmtree(next(root.glob("data_root/*")))  # the index must change: one scene fewer
    monkeypatch.setenv(FAULT_VARIABLE, "EACCES:2")  # the third of the four index files
    with pytest.raises(WriteError, match=r"^cannot write the index of .+ \(.+\.json\): Permission denied$"):
        build_index(root)
    assert leftovers(root) == []
    after = digests(root)
    assert {k: v for k, v in after.items() if k.startswith("index/")} == {k: v for k, v in before.items()
                                                                            if k.startswith("index/")}  # fmt: skip


def test_an_export_on_a_full_disk_resumes_to_the_uninterrupted_bytes(uninterrupted, tmp_path, monkeypatch):
    from fog_gym.dataset.export import export

    for fmt in ("nuscenes", "kitti", "coco"):
        export(uninterrupted, tmp_path / f"{fmt}-clean", fmt, fog="light", progress=False)
        out = tmp_path / fmt
        monkeypatch.setenv(FAULT_VARIABLE, "ENOSPC:9")
        with pytest.raises(WriteError, match=r"^cannot write the export \(.+\): No space left on device$"):
            export(uninterrupted, out, fmt, fog="light", progress=False)
        assert leftovers(out) == []
        monkeypatch.delenv(FAULT_VARIABLE)
        export(uninterrupted, out, fmt, fog="light", resume=True, progress=False)
        assert digests(out) == digests(tmp_path / f"{fmt}-clean")


def test_cli_export_on_a_full_disk_prints_one_line(uninterrupted, tmp_path):
    out = cli("export", str(uninterrupted), str(tmp_path / "coco"), "--format", "coco", env={FAULT_VARIABLE: "ENOSPC:3"})
    assert out.returncode == 1 and "Traceback" not in out.stderr
    assert LINE.match(out.stderr.strip().splitlines()[-1]), out.stderr
    assert leftovers(tmp_path) == []

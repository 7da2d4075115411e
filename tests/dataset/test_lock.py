"""One writer per dataset root (fog_gym.dataset.lock): real processes hold and contend for the lock; a lock left by
a killed holder is stale and taken over; a root that cannot be written is refused in one line. The whole run of
``generate`` with a kill and a second writer is in tests/dataset/test_dataset.py."""

import os
import shutil
import signal
import subprocess
import sys

import pytest

from fog_gym.dataset.lock import LOCK_FILE, DatasetLock, DatasetLocked, DatasetLockError, describe, read_holder

HOLD = ("import sys, time; from fog_gym.dataset.lock import DatasetLock; "
        "lock = DatasetLock(sys.argv[1], 'generate').acquire(); print('held', flush=True); time.sleep(120)")  # fmt: skip


@pytest.fixture
def holder(tmp_path):
    """A process that holds the lock of tmp_path/root until killed."""
    root = tmp_path / "root"
    proc = subprocess.Popen([sys.executable, "-c", HOLD, str(root)], stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "held"
    yield root, proc
    proc.kill()
    proc.wait()


def test_a_second_process_is_refused_with_the_holders_pid_host_and_start(holder):
    root, proc = holder
    with pytest.raises(DatasetLocked) as refused:
        DatasetLock(root, "export").acquire()
    record = read_holder(root)
    assert refused.value.holder == record and record["pid"] == proc.pid and record["command"] == "generate"
    assert str(refused.value).startswith(f"dataset root {root} is being written by {describe(record)}")
    assert "\n" not in str(refused.value)


def test_the_commands_refuse_a_locked_root_in_one_line_and_exit_1(holder, tmp_path):
    from fog_gym.generate import generate, plan_scenes

    root, proc = holder
    source = tmp_path / "source"
    generate(source, plan_scenes(2, towns=("merge",), seed=1, resolution=(16, 12), seconds=0.1), progress=False)
    for args in (["generate", "--root", str(root), "--scenes", "2", "--resume"],
                 ["export", str(source), str(root), "--format", "coco"]):  # the held root as export's output
        out = subprocess.run([sys.executable, "-m", "fog_gym.cli", *args], capture_output=True, text=True)
        assert out.returncode == 1, out.stderr
        assert out.stderr.count("\n") == 1, out.stderr
        assert out.stderr.startswith(f"fog-gym {args[0]}: dataset root {root} is being written by pid {proc.pid} on host")
    assert sorted(p.name for p in root.iterdir()) == [LOCK_FILE]  # neither wrote anything


def test_the_recorder_holds_its_root_until_close(tmp_path):
    import fog_gym
    from fog_gym.wrappers import RecordFogDrive

    env = RecordFogDrive(fog_gym.FogDriveEnv(resolution=(32, 24), episode_seconds=0.1), tmp_path / "set")
    with pytest.raises(DatasetLocked, match="RecordFogDrive"):
        DatasetLock(tmp_path / "set", "generate").acquire()
    env.close()
    with DatasetLock(tmp_path / "set", "generate") as lock:
        assert lock.stale is None  # released cleanly: no record left


def test_a_killed_holders_lock_is_stale_and_taken_over(holder, capsys):
    root, proc = holder
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert read_holder(root)["pid"] == proc.pid  # the record outlives its process …
    with DatasetLock(root, "generate") as lock:  # … but not its lock
        assert lock.stale["pid"] == proc.pid
        assert read_holder(root)["pid"] == os.getpid()
    assert f"took over the stale lock of {root} left by pid {proc.pid}" in capsys.readouterr().err
    assert not (root / LOCK_FILE).exists()


def test_a_root_that_cannot_be_written_is_refused_in_one_line(tmp_path):
    root = tmp_path / "ro"
    root.mkdir()
    if os.geteuid() != 0:
        root.chmod(0o555)
    elif shutil.which("mount") is None or subprocess.run(["mount", "-t", "tmpfs", "-o", "ro,size=1m", "tmpfs", str(root)],
                                                         capture_output=True).returncode:  # fmt: skip
        pytest.skip("needs a read-only folder: a non-root user, or root allowed to mount a tmpfs")
    try:
        with pytest.raises(DatasetLockError) as refused:
            DatasetLock(root, "generate").acquire()
        assert str(refused.value).startswith(f"cannot lock dataset root {root} for writing: ")
        out = subprocess.run([sys.executable, "-m", "fog_gym.cli", "generate", "--root", str(root), "--scenes", "2"],
                             capture_output=True, text=True)  # fmt: skip
        assert out.returncode == 1 and out.stderr.count("\n") == 1 and "cannot lock dataset root" in out.stderr
        (tmp_path / "file").write_text("x")
        with pytest.raises(DatasetLockError, match="not a folder"):
            DatasetLock(tmp_path / "file", "generate").acquire()
    finally:
        if os.geteuid() == 0:
            subprocess.run(["umount", str(root)], capture_output=True)
        else:
            root.chmod(0o755)

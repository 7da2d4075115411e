"""Serial twins of the parallel kernels (:func:`fog_gym._numba.serial_twin`) give the same bits as the parallel
kernels: an episode observed with every kernel forced parallel equals the one with every kernel forced serial."""

import gymnasium as gym
import numpy as np
import pytest

import fog_gym  # noqa: F401
import fog_gym._numba
from fog_gym.sensors import raycast


def _episode(monkeypatch, below: int, env_id: str, **kwargs) -> list:
    monkeypatch.setattr(fog_gym._numba, "SERIAL_BELOW", below)
    env = gym.make(env_id, **kwargs)
    obs, _ = env.reset(seed=3)
    frames = [obs]
    for a in (1, 3, 1, 0, 4, 1):
        frames.append(env.step(a)[0])
    env.close()
    return frames


@pytest.mark.parametrize("env_id, kwargs", [
    ("FogDriveRL-v0", {"fog": "dense"}),
    ("FogDrive-v0", {"fog": "moderate", "resolution": (96, 64), "cameras": ["CAM_FRONT", "CAM_BACK"]}),
    ("FogDrive-v0", {"fog": "light", "resolution": (48, 32), "cameras": ["CAM_FRONT"], "time_of_day": "night"}),
])  # fmt: skip
def test_serial_and_parallel_kernels_give_identical_frames(monkeypatch, env_id, kwargs):
    parallel = _episode(monkeypatch, 0, env_id, **kwargs)
    serial = _episode(monkeypatch, 10**12, env_id, **kwargs)
    for p, s in zip(parallel, serial):
        assert p.keys() == s.keys()
        for k in p:
            assert np.array_equal(p[k], s[k]), k


def test_serial_twin_is_a_separate_single_thread_kernel():
    assert raycast._cast_serial is not raycast._cast
    assert raycast._cast_serial.py_func.__qualname__ == "_cast_serial"
    assert raycast._cast.targetoptions.get("parallel") and not raycast._cast_serial.targetoptions.get("parallel")

"""``FogCurriculum``: the fog level follows its schedule, switching only at episode boundaries, also in vector envs."""

import math

import gymnasium as gym
import numpy as np
import pytest

from fog_gym.fog.schedules import ContinuousSchedule, StepSchedule, SuccessSchedule
from fog_gym.wrappers import FogCurriculum


def test_curriculum_switches_exactly_at_episode_boundaries():
    env = FogCurriculum(gym.make("FogDriveRL-v0", fog="clear"), StepSchedule(episodes_per_level=2))
    seen = []
    for e in range(8):
        _, info = env.reset(seed=e)
        seen.append(info["fog"]["visibility_m"])
        for _ in range(2):  # the level never changes inside an episode
            _, _, _, _, info = env.step(1)
            assert info["fog"]["visibility_m"] == seen[-1]
    assert seen == [math.inf, math.inf, 160.0, 160.0, 100.0, 100.0, 50.0, 50.0]


def test_curriculum_in_an_async_vector_env():
    def make():
        return FogCurriculum(gym.make("FogDriveRL-v0", fog="clear", episode_seconds=0.4), StepSchedule(episodes_per_level=1))

    envs = gym.vector.AsyncVectorEnv([make, make])
    try:
        _, info = envs.reset(seed=[0, 1])
        levels = [info["fog"]["visibility_m"].tolist()]
        for _ in range(3):  # episodes are 2 steps long; autoreset starts the next one on the following step
            for _ in range(3):
                _, _, term, trunc, info = envs.step(np.array([1, 1]))
            levels.append(info["fog"]["visibility_m"].tolist())
        assert levels == [[math.inf] * 2, [160.0] * 2, [100.0] * 2, [50.0] * 2]
    finally:
        envs.close()


def test_success_and_continuous_schedules():
    s = SuccessSchedule(threshold=0.5, window=2)
    s.record(False)
    s.record(False)
    assert s.level(2) == "clear"
    s.record(True)
    s.record(False)
    assert s.level(4) == 160.0
    c = ContinuousSchedule(start=math.inf, end=50.0, episodes=4)
    v = [c.level(e) for e in range(6)]
    assert v[0] == math.inf and v[4] == pytest.approx(50.0) and v[5] == pytest.approx(50.0)
    assert v[2] == pytest.approx(100.0)  # linear in α: half of α(50 m) is α(100 m)
    with pytest.raises(ValueError):
        StepSchedule(levels=("fog",))
    with pytest.raises(ValueError, match="in-place fog wrapper"):
        FogCurriculum(gym.make("FogDrive-v0", resolution=(8, 6)), StepSchedule())

"""RL preset, fog schedules and the SB3 vector-env curriculum, and the SB3 path (marked slow); the observation and
curriculum wrappers have their own test files, the RL benchmark tests/experiments/test_rl_bench.py."""

import gymnasium as gym
import numpy as np
import pytest

from fog_gym.fog.schedules import MixedSampler, StepSchedule


def test_preset_spaces_match_observations():
    env = gym.make("FogDriveRL-v0", fog="moderate")
    obs, info = env.reset(seed=0)
    assert env.observation_space.contains(obs) and info["fog"]["visibility_m"] == 100.0
    for _ in range(3):
        obs, *_ = env.step(env.action_space.sample())
        assert env.observation_space.contains(obs)
    assert obs["CAM_FRONT"].shape == (3, 64, 64) and obs["LIDAR_BEV"].shape == (2, 64, 64)
    assert obs["LIDAR_BEV"][0].any()  # the road's edge, guard rails and cars are seen


def test_mixed_sampler_is_seeded_and_covers_every_level():
    a = [MixedSampler(seed=4).level(e) for e in range(200)]
    assert a == [MixedSampler(seed=4).level(e) for e in range(200)]
    assert a != [MixedSampler(seed=5).level(e) for e in range(200)]
    assert set(a) == {"clear", 160.0, 100.0, 50.0}


@pytest.mark.slow
def test_sb3_check_env_and_short_ppo_run(tmp_path):
    pytest.importorskip("stable_baselines3")
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_checker import check_env
    from stable_baselines3.common.vec_env import SubprocVecEnv

    from fog_gym.rl.sb3 import VecFogCurriculum

    check_env(gym.make("FogDriveRL-v0"))
    check_env(gym.make("FogDriveRLHazard-v0", fog="dense"))
    # "fog_gym:" makes gym.make import fog_gym in the worker processes (SB3 starts them with forkserver)
    venv = VecFogCurriculum(SubprocVecEnv([lambda: gym.make("fog_gym:FogDriveRL-v0", fog="clear", episode_seconds=2.0)] * 2),
                            StepSchedule(episodes_per_level=1))  # fmt: skip
    model = PPO("MultiInputPolicy", venv, n_steps=32, batch_size=32, n_epochs=1, seed=0)
    model.learn(total_timesteps=128)
    assert venv.episodes >= 2
    assert venv.env_method("get_wrapper_attr", "fog")[0].name != "clear"  # the schedule reached the sub-envs
    model.save(tmp_path / "ppo.zip")
    assert PPO.load(tmp_path / "ppo.zip").observation_space == model.observation_space
    venv.close()


def _short_rl_env(rank: int):
    def make():
        import gymnasium as gym

        import fog_gym  # noqa: F401

        env = gym.make("FogDriveRL-v0", fog="clear", episode_seconds=0.6, camera_size=(16, 16), bev_size=16)
        env.reset(seed=rank)
        return env

    return make


def test_vec_curriculum_applies_each_level_from_the_very_next_episode_in_subproc_envs():
    pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.vec_env import SubprocVecEnv

    from fog_gym.fog.schedules import StepSchedule
    from fog_gym.rl.sb3 import VecFogCurriculum

    schedule = StepSchedule(episodes_per_level=1)  # episode k of the run gets level k: clear, 160, 100, 50, 50, …
    venv = VecFogCurriculum(SubprocVecEnv([_short_rl_env(0), _short_rl_env(1)]), schedule)
    venv.reset()
    expected = {i: venv.levels[i] for i in range(2)}
    assert [expected[0], expected[1]] == ["clear", 160.0]
    seen_new_episode = 0
    for _ in range(16):  # 3 policy steps per episode: several episode boundaries per sub-env
        _, _, dones, infos = venv.step(np.zeros(2, np.int64) + 1)
        for i in range(2):
            if dones[i]:
                expected[i] = venv.levels[i]  # the level chosen at this boundary …
                seen_new_episode += 1
                continue
            vis = infos[i]["fog"]["visibility_m"]  # … is the fog of every step of the next episode
            want = float("inf") if expected[i] == "clear" else float(expected[i])
            assert vis == want, (i, vis, want)
            assert infos[i]["fog_level"] == expected[i]
    assert seen_new_episode >= 6 and venv.episodes == seen_new_episode
    venv.close()

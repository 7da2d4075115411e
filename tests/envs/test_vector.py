"""The native vector env: seeded identity with the single env, autoreset, curricula, SB3, bad arguments."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import fog_gym  # noqa: F401
from fog_gym.envs.vector import FogDriveVectorEnv


def _make_vec(n, **kw):
    return gym.make_vec("FogDriveRLHazard-v0", num_envs=n, vectorization_mode="vector_entry_point", **kw)


def _same_as_single_envs(n, steps, **kw):
    envs = _make_vec(n, **kw)
    singles = [gym.make("FogDriveRLHazard-v0", **kw) for _ in range(n)]
    obs, _ = envs.reset(seed=10)
    for i, s in enumerate(singles):
        o, _ = s.reset(seed=10 + i)
        _assert_obs_equal(obs, i, o)
    rng = np.random.default_rng(0)
    ended = [False] * n
    episodes = 0
    for _ in range(steps):
        a = rng.integers(5, size=n)
        obs, r, term, trunc, _ = envs.step(a)
        for i, s in enumerate(singles):
            if ended[i]:  # NEXT_STEP autoreset: this step reset sub-env i; its single twin resets unseeded
                o, _ = s.reset()
                ri, ti, tri = 0.0, False, False
                episodes += 1
            else:
                o, ri, ti, tri, _ = s.step(int(a[i]))
            ended[i] = ti or tri
            _assert_obs_equal(obs, i, o)
            assert (r[i], term[i], trunc[i]) == (ri, ti, tri)
    return episodes


def _assert_obs_equal(batch, i, single):
    if isinstance(single, dict):
        for k in single:
            np.testing.assert_array_equal(batch[k][i], single[k])
    else:
        np.testing.assert_array_equal(batch[i], single)


def test_each_objects_sub_env_equals_the_single_env_seeded_s_plus_i_for_100_steps():
    assert _same_as_single_envs(3, 100, observation="objects", fog="moderate") > 0  # episodes restarted on the way


def test_each_pixel_sub_env_equals_the_single_env_seeded_s_plus_i():
    _same_as_single_envs(2, 30, fog="dense")


def test_next_step_autoreset_restarts_a_finished_sub_env_with_reward_zero_and_a_fresh_episode():
    envs = _make_vec(2, observation="objects", episode_seconds=0.4)  # 2 steps per episode
    envs.reset(seed=0)
    envs.step(np.ones(2, int))
    _, _, _, trunc, infos = envs.step(np.ones(2, int))
    assert trunc.all()
    _, r, term, trunc, infos = envs.step(np.ones(2, int))
    assert (r == 0).all() and not term.any() and not trunc.any() and (infos["step"] == 0).all()


def test_same_step_autoreset_hands_back_the_final_observation():
    envs = FogDriveVectorEnv("FogDriveRLHazard-v0", 2, autoreset_mode="SameStep", observation="objects",
                             episode_seconds=0.4)  # fmt: skip
    envs.reset(seed=0)
    envs.step(np.ones(2, int))
    obs, _, _, trunc, infos = envs.step(np.ones(2, int))
    assert trunc.all() and infos["_final_obs"].all() and infos["final_obs"][0].shape == obs[0].shape
    assert (infos["step"] == 0).all() and (infos["final_info"]["step"] == 2).all()


def test_episodes_after_autoreset_are_seeded_deterministically():
    runs = []
    for _ in range(2):
        envs = _make_vec(2, observation="objects", episode_seconds=0.6)
        obs, _ = envs.reset(seed=5)
        trace = []
        for k in range(12):
            obs, r, *_ = envs.step(np.full(2, k % 5))
            trace.append((obs.copy(), r.copy()))
        runs.append(trace)
    for (oa, ra), (ob, rb) in zip(*runs):
        np.testing.assert_array_equal(oa, ob)
        np.testing.assert_array_equal(ra, rb)


def test_a_vector_curriculum_sets_each_sub_env_s_next_episode():
    from fog_gym.fog.schedules import StepSchedule
    from fog_gym.wrappers import VectorFogCurriculum

    envs = VectorFogCurriculum(_make_vec(2, observation="objects", episode_seconds=0.2), StepSchedule(episodes_per_level=2))
    envs.reset(seed=0)
    envs.step(np.ones(2, int))  # both episodes end (one step each)
    _, _, _, _, infos = envs.step(np.ones(2, int))  # the NEXT_STEP reset: the new episodes are in light fog
    assert envs.levels == [160.0, 160.0] and (infos["fog"]["visibility_m"] == 160.0).all()


def test_ppo_trains_on_the_vector_env_through_the_sb3_adapter():
    from stable_baselines3 import PPO

    from fog_gym.rl.sb3 import VecFogCurriculum, VectorEnvAdapter
    from fog_gym.fog.schedules import StepSchedule

    venv = VecFogCurriculum(VectorEnvAdapter(_make_vec(4, observation="objects", info_detections=False)),
                            StepSchedule(episodes_per_level=3))  # fmt: skip
    model = PPO("MlpPolicy", venv, n_steps=32, batch_size=64, n_epochs=1, seed=0, device="cpu")
    model.learn(256)
    assert model.num_timesteps >= 256 and venv.episodes >= 1


def test_dqn_trains_on_the_vector_env_and_stores_every_sub_env_s_transitions():
    from stable_baselines3 import DQN

    from fog_gym.rl.sb3 import VectorEnvAdapter

    venv = VectorEnvAdapter(_make_vec(4, observation="objects", info_detections=False))
    model = DQN("MlpPolicy", venv, learning_starts=32, batch_size=16, buffer_size=1000, seed=0, device="cpu")
    model.learn(128)
    buf = model.replay_buffer
    assert model.num_timesteps == 128 and buf.pos == 128 // 4  # one row per vector step, 4 sub-envs per row
    stored = buf.observations[: buf.pos].reshape(-1, *venv.observation_space.shape)
    assert all(venv.observation_space.contains(o) for o in stored)
    assert set(np.unique(buf.actions[: buf.pos])) <= set(range(venv.action_space.n))


@settings(max_examples=10, deadline=None)
@given(st.one_of(st.integers(max_value=0), st.booleans(), st.floats(), st.text(max_size=3)))
def test_bad_num_envs_fail_before_any_world_is_built(n):
    with pytest.raises(ValueError, match="num_envs must be an integer >= 1"):
        FogDriveVectorEnv("FogDriveRLHazard-v0", n)


@pytest.mark.parametrize("kwargs, match", [
    ({"colour": "red"}, r"unknown argument\(s\) \['colour'\]"),
    ({"town": "merge"}, "highway town only"),
    ({"observation": "objects", "camera_size": (32, 32)}, "does not take"),
    ({"sensors": ("lidar",)}, "configure observation='objects'"),
    ({"fog": ["light", "dense"]}, "one level"),
    ({"fog": -5}, "fog visibility must be"),
])  # fmt: skip
def test_bad_arguments_fail_before_any_world_is_built_naming_the_argument(kwargs, match):
    with pytest.raises(ValueError, match=match):
        FogDriveVectorEnv("FogDriveRLHazard-v0", 2, **kwargs)


def test_a_preset_without_a_vector_path_says_so():
    with pytest.raises(ValueError, match="presets with a vector path"):
        FogDriveVectorEnv("FogDrive-v0", 2)
    with pytest.raises(gym.error.Error, match="vector entry point"):
        gym.make_vec("FogDrive-v0", num_envs=2, vectorization_mode="vector_entry_point")


def _rollout(threads, env_id, steps=12, **kw):
    envs = FogDriveVectorEnv(env_id, 3, threads=threads, **kw)
    out = [envs.reset(seed=4)[0]]
    rng = np.random.default_rng(1)
    for _ in range(steps):
        obs, r, term, trunc, infos = envs.step(rng.integers(0, 5, 3))
        out.append((obs, r, term, trunc, infos.get("final_obs")))
    envs.close()
    return out


@pytest.mark.parametrize("env_id, kwargs", [
    ("FogDriveRL-v0", {"fog": "dense", "geometry": "meshes", "episode_seconds": 2.0,
                       "autoreset_mode": gym.vector.AutoresetMode.SAME_STEP}),
    ("FogDriveRL-v0", {"fog": "moderate", "time_of_day": "night", "episode_seconds": 2.0}),
    ("FogDriveRLFogBank-v0", {"episode_seconds": 2.0}),
])  # fmt: skip
def test_worlds_rendered_on_threads_give_the_same_bits_as_one_after_the_other(env_id, kwargs):
    """Night (lights, glow: parallel kernels under the launch lock) and fog banks (the field kernels) included;
    episodes end on the way (autoresets on both paths)."""
    import pickle

    one = _rollout(1, env_id, **kwargs)
    three = _rollout(3, env_id, **kwargs)
    assert any(step[2].any() or step[3].any() for step in one[1:])
    assert pickle.dumps(one) == pickle.dumps(three)


@given(st.one_of(st.integers(max_value=0), st.floats(), st.just(True), st.text(max_size=3)))
@settings(max_examples=20, deadline=None)
def test_bad_thread_counts_fail_before_any_world_is_built(threads):
    with pytest.raises(ValueError, match="threads must be an integer >= 1"):
        FogDriveVectorEnv("FogDriveRLHazard-v0", 2, threads=threads)


def test_the_default_thread_count_is_bounded_by_the_worlds():
    from fog_gym.envs.vector import DEFAULT_THREADS, world_threads

    assert world_threads(None, 1) == 1
    assert 1 <= world_threads(None, 64) <= DEFAULT_THREADS
    assert world_threads(5, 2) == 5  # asked for: kept (extra threads idle)

"""The vector env sharded over worker processes (``shards=K``): the same episodes, infos and sub-env access as one
process, bad arguments refused before a worker starts, a worker's error raised in the main process."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import fog_gym  # noqa: F401
from fog_gym.envs.sharded import ShardedVectorEnv, merge_infos, shard_sizes


def _make(n, shards, **kw):
    return gym.make_vec("FogDriveRLHazard-v0", num_envs=n, vectorization_mode="vector_entry_point", shards=shards, **kw)


def _equal(a, b, path=""):
    """Vector outputs equal key for key (nested info dicts, object arrays of arrays or dicts included)."""
    if isinstance(a, tuple):
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b)):
            _equal(x, y, f"{path}[{i}]")
    elif isinstance(a, dict):
        assert a.keys() == b.keys(), path
        for k in a:
            _equal(a[k], b[k], f"{path}/{k}")
    elif isinstance(a, np.ndarray) and a.dtype == object:
        assert a.shape == b.shape, path
        for x, y in zip(a, b):
            if x is None or y is None:
                assert x is None and y is None, path
            else:
                _equal(x, y, path)
    else:
        np.testing.assert_array_equal(a, b, err_msg=path)


def _valid_final_info(out):
    """A step's outputs with ``final_info`` kept only where ``_final_info`` marks it (elsewhere it is unspecified)."""
    infos = dict(out[4])
    if "final_info" in infos:
        mask = infos["_final_info"]

        def rows(d):
            return {k: rows(v) if isinstance(v, dict) else np.asarray(v)[mask] for k, v in d.items()}

        infos["final_info"] = rows(infos["final_info"])
    return (*out[:4], infos)


@pytest.mark.parametrize("mode", ["NextStep", "SameStep"])
def test_two_shards_step_the_same_episodes_and_infos_as_one_process(mode):
    kw = {"observation": "objects", "fog": "moderate", "episode_seconds": 4.0, "autoreset_mode": mode}
    one, two = _make(5, 1, **kw), _make(5, 2, **kw)
    try:
        _equal(one.reset(seed=7), two.reset(seed=7))
        rng, ended = np.random.default_rng(0), 0
        for _ in range(60):
            a = rng.integers(5, size=5)
            out1, out2 = one.step(a), two.step(a)
            _equal(_valid_final_info(out1), _valid_final_info(out2))
            ended += int((out1[2] | out1[3]).sum())
        assert ended >= 5  # autoresets happened on the way
    finally:
        two.close()


def test_pixel_shards_equal_one_process():
    one, two = _make(3, 1, fog="dense"), _make(3, 3, fog="dense")
    try:
        _equal(one.reset(seed=1)[0], two.reset(seed=1)[0])
        for a in ([1, 3, 0], [4, 1, 1], [2, 2, 2], [1, 0, 4]):
            _equal(one.step(a), two.step(a))
    finally:
        two.close()


def test_fog_and_resets_reach_the_sub_env_they_name():
    envs, one = _make(4, 2, observation="objects"), _make(4, 1, observation="objects")
    try:
        for e in (envs, one):
            e.reset(seed=0)
            e.set_fog(3, "dense")
            e.set_attr("next_fog", ["clear", "light", "moderate", "dense"])
        obs, info = envs.reset_one(3, seed=5)
        single = gym.make("FogDriveRLHazard-v0", observation="objects", fog="dense")
        np.testing.assert_array_equal(obs, single.reset(seed=5)[0])
        assert envs.reset(seed=0)[1]["fog"]["visibility_m"][1:].tolist() == [160.0, 100.0, 50.0]
        assert [str(f) for f in envs.get_attr("fog")] == [str(f) for f in one.reset(seed=0) and one.get_attr("fog")]
    finally:
        envs.close()


def test_ppo_trains_on_shards_through_the_sb3_adapter():
    from stable_baselines3 import PPO

    from fog_gym.rl.sb3 import VectorEnvAdapter

    venv = VectorEnvAdapter(_make(4, 2, observation="objects", info_detections=False, episode_seconds=2.0))
    try:
        model = PPO("MlpPolicy", venv, n_steps=32, batch_size=64, n_epochs=1, seed=0, device="cpu")
        model.learn(256)
        assert model.num_timesteps >= 256 and model.ep_info_buffer is not None
    finally:
        venv.close()


@settings(max_examples=10, deadline=None)
@given(st.one_of(st.integers(max_value=0), st.integers(min_value=5, max_value=99), st.booleans(), st.floats(),
                 st.text(max_size=2)))  # fmt: skip
def test_bad_shards_fail_before_any_worker_starts(shards):
    with pytest.raises(ValueError, match="shards must be an integer"):
        _make(4, shards)


@settings(max_examples=10, deadline=None)
@given(st.one_of(st.integers(max_value=0), st.just(True), st.floats(), st.text(max_size=2)))
def test_bad_thread_counts_fail_before_any_worker_starts(threads):
    with pytest.raises(ValueError, match="threads must be an integer >= 1"):
        ShardedVectorEnv("FogDriveRLHazard-v0", 4, 2, threads=threads)


def test_bad_arguments_fail_in_the_main_process_and_worker_errors_come_back():
    with pytest.raises(ValueError, match=r"unknown argument\(s\) \['colour'\]"):
        ShardedVectorEnv("FogDriveRLHazard-v0", 4, 2, colour="red")
    with pytest.raises(ValueError, match="num_envs must be"):
        ShardedVectorEnv("FogDriveRLHazard-v0", 0, 1)
    import multiprocessing as mp

    before = len(mp.active_children())
    with pytest.raises(ValueError, match="fog visibility must be"):  # checked where the worlds are built
        _make(2, 2, fog=-5)
    assert len(mp.active_children()) == before  # no worker left behind


def test_shard_sizes_cover_every_world_once():
    for n in range(1, 20):
        for k in range(1, n + 1):
            sizes = shard_sizes(n, k)
            assert sum(sizes) == n and max(sizes) - min(sizes) <= 1 and len(sizes) == k


def test_merged_infos_fill_keys_a_shard_lacks():
    a = {"final_obs": np.array([np.zeros(2), None], dtype=object), "_final_obs": np.array([True, False]),
         "fog": {"alpha": np.array([0.1, 0.2])}}  # fmt: skip
    b = {"fog": {"alpha": np.array([0.3])}}
    m = merge_infos([a, b], [2, 1])
    assert m["_final_obs"].tolist() == [True, False, False] and m["final_obs"][2] is None
    assert m["fog"]["alpha"].tolist() == [0.1, 0.2, 0.3]

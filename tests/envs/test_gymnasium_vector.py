"""Gymnasium's vector API in full: every registered env runs under Gymnasium's own ``SyncVectorEnv`` and
``AsyncVectorEnv`` (fixed-shape infos), and the native and sharded vector envs equal ``SyncVectorEnv`` over single
envs — observations, rewards, terminations, truncations and infos with every mask — in each autoreset mode, with
``reset_mask`` and generic ``get_attr`` / ``set_attr`` / ``call``."""

from __future__ import annotations

import time

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import fog_gym  # noqa: F401

CASES = [
    ("FogDrive-v0", {"resolution": (32, 24), "cameras": ["CAM_FRONT"], "fog": ["light", "dense"], "episode_seconds": 0.3}),
    ("FogDriveRL-v0", {"episode_seconds": 1.0}),
    ("FogDriveRLHazard-v0", {"episode_seconds": 1.0}),
    ("FogDriveRL-v0", {"observation": "objects", "episode_seconds": 1.0}),
    ("FogDriveRLHazard-v0", {"observation": "objects", "episode_seconds": 1.0}),
    ("FogDriveRLObjects-v0", {"episode_seconds": 1.0}),
    ("FogDriveRLFogBank-v0", {"episode_seconds": 1.0}),
    ("FogDriveRLFogBank-v0", {"observation": "objects", "episode_seconds": 1.0}),
]  # fmt: skip
IDS = ["FogDrive", "RL-pixels", "Hazard-pixels", "RL-objects", "Hazard-objects", "RLObjects", "FogBank-pixels",
       "FogBank-objects"]


def test_the_cases_cover_every_registered_env_and_observation():
    from fog_gym.envs import ENV_IDS
    from fog_gym.envs.presets import OBSERVATIONS

    assert {c[0] for c in CASES} == set(ENV_IDS)
    for env_id in ("FogDriveRL-v0", "FogDriveRLHazard-v0", "FogDriveRLFogBank-v0"):
        assert {c[1].get("observation", "pixels") for c in CASES if c[0] == env_id} == set(OBSERVATIONS)


def assert_same(a, b, path="infos"):
    """Equal values, recursively: dicts with the same keys, arrays with the same shape, dtype and values (NaN equals
    NaN), object arrays element by element."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and sorted(a) == sorted(b), (path, sorted(a), sorted(b) if isinstance(b, dict) else b)
        for k in a:
            assert_same(a[k], b[k], f"{path}[{k!r}]")
    elif isinstance(a, np.ndarray) and a.dtype == object:
        assert isinstance(b, np.ndarray) and b.dtype == object and a.shape == b.shape, path
        for i, (x, y) in enumerate(zip(a, b)):
            assert_same(x, y, f"{path}[{i}]")
    elif isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray) and a.shape == b.shape and a.dtype == b.dtype, (path, a, b)
        np.testing.assert_array_equal(a, b, err_msg=path)
    else:
        assert type(a) is type(b) and (a == b or (a != a and b != b)), (path, a, b)


@pytest.mark.parametrize("mode", ["sync", "async"])
@pytest.mark.parametrize("env_id, kwargs", CASES, ids=IDS)
def test_every_env_vectorises_with_gymnasiums_own_vectorisers_across_episode_ends(mode, env_id, kwargs):
    envs = gym.make_vec(env_id, num_envs=2, vectorization_mode=mode, **kwargs)
    try:
        obs, infos = envs.reset(seed=0)
        assert envs.observation_space.contains(obs)
        ended = 0
        for _ in range(8):  # past the end of every episode (3 or 5 steps): autoresets happen
            obs, rewards, term, trunc, infos = envs.step(np.ones(2, np.int64))
            ended += int((term | trunc).sum())
            assert envs.observation_space.contains(obs) and rewards.shape == (2,)
        assert ended >= 2
        if "hazards" in infos:
            assert infos["hazards"].shape == (2, 10, 4) and infos["hazard_count"].shape == (2,)
    finally:
        envs.close()


@pytest.mark.parametrize("env_id, kwargs", CASES[3:4] + CASES[1:2], ids=["objects", "pixels"])
def test_async_close_returns_after_a_sub_env_error(env_id, kwargs):
    envs = gym.make_vec(env_id, num_envs=2, vectorization_mode="async", **kwargs)
    envs.reset(seed=0)
    with pytest.raises(ValueError, match="meta-action"):
        envs.step(np.array([1, 9]))
    t0 = time.perf_counter()
    envs.close()
    assert time.perf_counter() - t0 < 10.0


def _run(envs, mode: AutoresetMode, steps: int = 12) -> list:
    """Everything the vector env returns over ``steps`` steps with fixed actions, resets by mask where DISABLED."""
    out = [envs.reset(seed=3)]
    actions = [1, 3, 1, 0, 4, 1, 2, 1, 3, 1, 1, 4]
    ended = np.zeros(envs.num_envs, bool)
    for t in range(steps):
        if mode == AutoresetMode.DISABLED and ended.any():
            out.append(envs.reset(options={"reset_mask": ended.copy()}))
        a = np.array([actions[(t + i) % len(actions)] for i in range(envs.num_envs)])
        step = envs.step(a)
        out.append(step)
        ended = step[2] | step[3]
    return out


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP, AutoresetMode.DISABLED])
@pytest.mark.parametrize("env_id, observation", [("FogDriveRL-v0", "objects"), ("FogDriveRL-v0", "pixels"),
                                                 ("FogDriveRLHazard-v0", "objects"), ("FogDriveRLHazard-v0", "pixels"),
                                                 ("FogDriveRLObjects-v0", "objects")])  # fmt: skip
def test_the_native_vector_env_equals_sync_vector_env_over_single_envs(env_id, observation, mode):
    kwargs = {"observation": observation, "fog": "dense", "episode_seconds": 1.0}
    sync = gym.make_vec(env_id, num_envs=3, vectorization_mode="sync", vector_kwargs={"autoreset_mode": mode}, **kwargs)
    native = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point", autoreset_mode=mode, **kwargs)
    try:
        for got, want in zip(_run(native, mode), _run(sync, mode), strict=True):
            assert len(got) == len(want)
            for g, w in zip(got, want):
                assert_same(g, w, "step")
    finally:
        sync.close()
        native.close()


@pytest.mark.parametrize("observation", ["objects", "pixels"])
def test_a_masked_reset_resets_only_the_masked_sub_envs_as_sync_does(observation):
    kwargs = {"observation": observation, "fog": "light"}
    sync = gym.make_vec("FogDriveRLHazard-v0", num_envs=3, vectorization_mode="sync", **kwargs)
    native = gym.make_vec("FogDriveRLHazard-v0", num_envs=3, vectorization_mode="vector_entry_point", **kwargs)
    mask = np.array([False, True, False])
    for envs in (sync, native):
        envs.reset(seed=1)
        envs.step(np.array([3, 3, 3]))
    a, b = native.reset(seed=9, options={"reset_mask": mask}), sync.reset(seed=9, options={"reset_mask": mask})
    assert_same(a[0], b[0], "obs")
    assert_same(a[1], b[1], "infos")
    assert a[1]["_speed"].tolist() == [False, True, False]  # infos only for the reset sub-env
    for bad, error in ((np.array([True, False]), ValueError), (np.zeros(3, bool), ValueError), ([True] * 3, TypeError)):
        with pytest.raises(error, match="reset_mask"):
            native.reset(options={"reset_mask": bad})
    sync.close()
    native.close()


@pytest.mark.parametrize("shards", [1, 2])
@pytest.mark.parametrize("observation", ["objects", "pixels"])
def test_get_attr_set_attr_and_call_reach_any_attribute_of_the_sub_envs(observation, shards):
    envs = gym.make_vec("FogDriveRL-v0", num_envs=2, vectorization_mode="vector_entry_point", shards=shards,
                        observation=observation)  # fmt: skip
    try:
        envs.reset(seed=0)
        specs = envs.get_attr("spec")
        assert [s.id for s in specs] == ["FogDriveRL-v0"] * 2 and specs[0].kwargs["observation"] == observation
        assert envs.get_attr("render_mode") == (None, None)
        assert all(isinstance(g, np.random.Generator) for g in envs.get_attr("np_random"))
        envs.set_attr("next_fog", ["light", None])
        assert [f.name if f else None for f in envs.get_attr("next_fog")] == ["light", None]
        envs.call("set_fog", "dense")  # one argument for every sub-env, as SyncVectorEnv calls
        _, infos = envs.reset(seed=0)
        assert infos["fog"]["visibility_m"].tolist() == [50.0, 50.0] and infos["fog"]["_alpha"].all()
        assert envs.call("observation_space") == (envs.single_observation_space,) * 2  # an attribute: returned
        with pytest.raises(AttributeError):
            envs.get_attr("no_such_attribute")
    finally:
        envs.close()


@pytest.mark.parametrize("mode", [AutoresetMode.SAME_STEP, AutoresetMode.DISABLED])
def test_two_shards_equal_sync_vector_env_in_every_autoreset_mode(mode):
    kwargs = {"observation": "objects", "fog": "moderate", "episode_seconds": 1.0}
    sync = gym.make_vec("FogDriveRLHazard-v0", num_envs=3, vectorization_mode="sync", vector_kwargs={"autoreset_mode": mode},
                        **kwargs)  # fmt: skip
    sharded = gym.make_vec("FogDriveRLHazard-v0", num_envs=3, vectorization_mode="vector_entry_point", shards=2,
                           autoreset_mode=mode, **kwargs)  # fmt: skip
    try:
        for got, want in zip(_run(sharded, mode), _run(sync, mode), strict=True):
            for g, w in zip(got, want):
                assert_same(g, w, "step")
    finally:
        sync.close()
        sharded.close()


def test_disabled_autoreset_refuses_to_step_an_ended_sub_env():
    envs = gym.make_vec("FogDriveRL-v0", num_envs=2, vectorization_mode="vector_entry_point", observation="objects",
                        episode_seconds=0.4, autoreset_mode=AutoresetMode.DISABLED)  # fmt: skip
    envs.reset(seed=0)
    envs.step(np.ones(2, np.int64))
    envs.step(np.ones(2, np.int64))  # both truncate after 2 steps
    with pytest.raises(RuntimeError, match="reset_mask"):
        envs.step(np.ones(2, np.int64))
    envs.reset(options={"reset_mask": np.array([True, True])})
    envs.step(np.ones(2, np.int64))


def test_the_objects_preset_is_a_flat_box_the_checkers_take_without_a_warning():
    import warnings

    from gymnasium.utils.env_checker import check_env as gym_check
    from stable_baselines3.common.env_checker import check_env as sb3_check

    env = gym.make("FogDriveRLObjects-v0", fog="dense")
    assert env.observation_space.shape == (20,)  # the lanes layout's 4 × 5, row after row
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sb3_check(env.unwrapped)
        gym_check(env.unwrapped, skip_render_check=True)
    assert [str(w.message) for w in caught if "unconventional" in str(w.message) or "shape" in str(w.message)] == []
    flat = gym.make("FogDriveRLHazard-v0", observation="objects", layout="lanes", flat=True)
    lanes = gym.make("FogDriveRLHazard-v0", observation="objects", layout="lanes")
    np.testing.assert_array_equal(flat.reset(seed=4)[0], lanes.reset(seed=4)[0].reshape(-1))

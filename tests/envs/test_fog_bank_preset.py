"""FogDriveRLFogBank-v0: a fog bank on the road ahead, drawn per episode from the reset's seed, in force through the
in-place fog wrapper; the native vector env draws one per sub-env; bad settings fail before any world is built."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import fog_gym  # noqa: F401  (registers the envs)
from fog_gym.fog.banks import BankConfig
from fog_gym.fog.fields import FogBank, field_from_info


def test_each_seed_draws_its_bank_within_the_configured_ranges_and_the_same_seed_the_same_bank():
    env = gym.make("FogDriveRLFogBank-v0")
    banks = [field_from_info(env.reset(seed=s)[1]["fog"]) for s in (0, 1, 2, 0)]
    assert all(isinstance(b, FogBank) for b in banks) and banks[0] == banks[3] and banks[0] != banks[1]
    cfg = BankConfig()
    for b in banks:
        assert cfg.start[0] <= b.start <= cfg.start[1] and cfg.length[0] <= b.length <= cfg.length[1]
        assert cfg.visibility[0] <= b.visibility <= cfg.visibility[1] and cfg.edge[0] <= b.edge <= cfg.edge[1]
        assert b.background == np.inf  # clear air around it
    env.close()


def test_the_bank_starts_beyond_the_sensors_clear_air_reach_so_the_first_frames_are_clear():
    # a bank 140 m or more ahead: the bird's-eye image (up to 56 m ahead) is as in clear air at reset
    bank = gym.make("FogDriveRLFogBank-v0")
    clear = gym.make("FogDriveRLHazard-v0", fog="clear")
    a, b = bank.reset(seed=4)[0], clear.reset(seed=4)[0]
    assert np.array_equal(a["LIDAR_BEV"], b["LIDAR_BEV"])
    assert not np.array_equal(a["CAM_FRONT"], b["CAM_FRONT"])  # the camera sees the wall of fog far ahead
    for env in (bank, clear):
        env.close()


def test_a_dense_bank_around_the_ego_hides_what_lies_past_its_visibility():
    inside = BankConfig(start=(0.0, 0.0), length=(500.0, 500.0), visibility=(20.0, 20.0), edge=(0.0, 0.0))
    env, clear = gym.make("FogDriveRLFogBank-v0", banks=inside), gym.make("FogDriveRLHazard-v0", fog="clear")
    # (the LiDAR sits just past the bank's face at u = 0: everything ahead lies in 20 m fog)
    a, b = env.reset(seed=2)[0], clear.reset(seed=2)[0]
    far = slice(0, 27)  # bird's-eye rows 30–56 m ahead of the LiDAR (row = 56 − x)
    occupied = lambda obs: int((obs["LIDAR_BEV"][0, far] > 0).sum())  # noqa: E731
    assert occupied(b) > 20 and occupied(a) < 0.2 * occupied(b)
    top = lambda obs: obs["CAM_FRONT"][:, :32].astype(float).std(axis=(1, 2)).mean()  # noqa: E731  (the far scene)
    assert top(a) < 0.3 * top(b)  # the airlight everywhere past a few visibilities
    for e in (env, clear):
        e.close()


def test_the_vector_env_draws_a_bank_per_sub_env_as_the_single_env_does():
    vec = gym.make_vec("FogDriveRLFogBank-v0", num_envs=2, vectorization_mode="vector_entry_point")
    _, info = vec.reset(seed=7)
    single = gym.make("FogDriveRLFogBank-v0")
    for i, seed in enumerate((7, 8)):
        assert vec.unwrapped.envs[i].bank == field_from_info(single.reset(seed=seed)[1]["fog"])
    vec.close()
    single.close()


@pytest.mark.parametrize("kwargs, match", [
    ({"fog": "dense"}, "draws a fog bank per episode"),
    ({"banks": (140.0, 340.0)}, "BankConfig"),
])  # fmt: skip
def test_bad_settings_fail_before_any_world_is_built(kwargs, match):
    with pytest.raises(ValueError, match=match):
        gym.make("FogDriveRLFogBank-v0", **kwargs)
    with pytest.raises(ValueError, match=match):
        gym.make_vec("FogDriveRLFogBank-v0", num_envs=2, vectorization_mode="vector_entry_point", **kwargs)


@pytest.mark.parametrize("name, value", [("start", (-1.0, 5.0)), ("visibility", (0.0, 50.0)), ("length", (5.0, 1.0)),
                                         ("edge", (1.0, float("nan"))), ("start", 5.0)])  # fmt: skip
def test_a_bad_bank_range_names_itself(name, value):
    with pytest.raises(ValueError, match=name):
        BankConfig(**{name: value})


def test_the_bank_wrapper_and_the_objects_worlds_refuse_what_they_cannot_use():
    from fog_gym.envs.fogdrive import FogDriveEnv
    from fog_gym.envs.objects import FogDriveObjectsEnv, parse_objects_fog
    from fog_gym.fog.fields import HeightFog
    from fog_gym.wrappers import FogBankEpisodes, FogWrapper

    base = FogDriveEnv(resolution=(32, 24), cameras=["CAM_FRONT"])
    with pytest.raises(ValueError, match="in-place FogWrapper"):
        FogBankEpisodes(base)
    with pytest.raises(ValueError, match="BankConfig"):
        FogBankEpisodes(FogWrapper(base, "dense"), banks={"start": (1.0, 2.0)})
    with pytest.raises(ValueError, match="BankConfig"):
        FogDriveObjectsEnv(banks=(140.0, 340.0))
    five = HeightFog(50.0, 5.0) + HeightFog(80.0, 9.0) + FogBank(50.0, 1.0, 2.0) + FogBank(60.0, 9.0, 2.0) \
        + HeightFog(90.0, 2.0)  # fmt: skip
    with pytest.raises(ValueError, match="at most 4 terms"):
        parse_objects_fog(five)
    base.close()

"""Minari export: lossless round trip, metadata, key selection, bad input, the ``fog-gym minari`` command."""

import os
import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest

import fog_gym
from fog_gym.rl.minari import collect
from tests.helpers import load_module

minari = pytest.importorskip("minari")  # the minari extra is part of the dev extra: never skipped in CI


@pytest.fixture(autouse=True)
def datasets_path(tmp_path, monkeypatch):
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "minari"))
    return tmp_path / "minari"


class Recorder:
    """A policy that cycles through actions and keeps every observation it was shown."""

    def __init__(self, actions=(3, 1, 0, 4, 2)):
        self.actions, self.seen, self.calls = actions, [], 0

    def __call__(self, obs):
        self.seen.append({k: v.copy() for k, v in obs.items()})
        self.calls += 1
        return self.actions[(self.calls - 1) % len(self.actions)]


def test_round_trip_gives_the_recorded_episodes_arrays_and_metadata():
    env = gym.make("FogDriveRL-v0", fog="dense", episode_seconds=1.0)
    policy = Recorder()
    collect(env, policy, episodes=2, dataset_id="fog-gym/test-dense-v0", seed=7, progress=False)
    ds = minari.load_dataset("fog-gym/test-dense-v0")
    assert ds.total_episodes == 2 and ds.total_steps == 10  # 1 s at the preset's 5 Hz
    assert ds.observation_space == env.observation_space and ds.action_space == env.action_space
    meta = ds.storage.metadata
    assert (meta["fog_level"], meta["town"], meta["time_of_day"]) == ("dense", "highway", "day")
    assert meta["fog_gym_version"] == fog_gym.__version__ and meta["jpeg_encoding"] is False
    assert [m["seed"] for m in ds.storage.get_episode_metadata([0, 1])] == [7, 8]
    assert [m["fog_visibility_m"] for m in ds.storage.get_episode_metadata([0, 1])] == [50.0, 50.0]
    episodes = list(ds.iterate_episodes())
    for e, ep in enumerate(episodes):
        seen = policy.seen[5 * e: 5 * e + 5]
        for key in ("CAM_FRONT", "LIDAR_BEV"):
            assert e_obs(ep, key).shape == (6,) + env.observation_space[key].shape
            np.testing.assert_array_equal(e_obs(ep, key)[:5], np.stack([o[key] for o in seen]))  # bit for bit
        np.testing.assert_array_equal(ep.actions, [3, 1, 0, 4, 2])
    # the same seeds replayed give the same last observation (it is stored too)
    obs, _ = env.reset(seed=8)
    for a in [3, 1, 0, 4, 2]:
        obs, *_ = env.step(a)
    np.testing.assert_array_equal(e_obs(episodes[1], "CAM_FRONT")[-1], obs["CAM_FRONT"])


def e_obs(episode, key):
    return np.asarray(episode.observations[key])


def test_keys_select_part_of_a_full_rig_observation():
    env = fog_gym.FogDriveEnv(town="merge", resolution=(16, 12), cameras=["CAM_FRONT"], episode_seconds=0.3)
    ds = collect(env, None, episodes=1, dataset_id="fog-gym/merge-cam-v0", keys=["CAM_FRONT", "RADAR_FRONT"],
                 progress=False)  # fmt: skip
    assert sorted(ds.observation_space.spaces) == ["CAM_FRONT", "RADAR_FRONT"]
    ep = next(iter(ds.iterate_episodes()))
    assert e_obs(ep, "CAM_FRONT").shape == (4, 12, 16, 3) and ds.storage.metadata["fog_level"] == "clear"


@pytest.mark.parametrize("kwargs, error, message", [
    (dict(episodes=0), ValueError, "episodes must be a positive integer"),
    (dict(dataset_id="no version"), ValueError, "dataset_id must look like"),
    (dict(keys=["CAM_BACK"]), ValueError, r"keys must be a non-empty list of \['CAM_FRONT', 'LIDAR_BEV'\]"),
    (dict(keys="CAM_FRONT"), ValueError, "keys must be a list"),
    (dict(policy=42), TypeError, "policy must be None, a callable"),
])  # fmt: skip
def test_bad_arguments_fail_before_the_first_episode(kwargs, error, message):
    env = gym.make("FogDriveRL-v0", episode_seconds=0.4)
    spy = Recorder()
    args = dict(policy=spy, episodes=1, dataset_id="fog-gym/x-v0", progress=False) | kwargs
    with pytest.raises(error, match=message):
        collect(env, **args)
    assert spy.calls == 0 and "fog-gym/x-v0" not in minari.list_local_datasets()


def test_an_existing_dataset_is_kept_unless_overwrite():
    env = gym.make("FogDriveRL-v0", episode_seconds=0.4)
    collect(env, None, episodes=1, dataset_id="fog-gym/keep-v0", progress=False)
    with pytest.raises(FileExistsError, match="exists; pass overwrite=True"):
        collect(env, None, episodes=2, dataset_id="fog-gym/keep-v0", progress=False)
    assert minari.load_dataset("fog-gym/keep-v0").total_episodes == 1
    assert collect(env, None, episodes=2, dataset_id="fog-gym/keep-v0", overwrite=True, progress=False).total_episodes == 2


def test_cli_minari_records_a_random_policy_dataset(datasets_path):
    cmd = [sys.executable, "-m", "fog_gym.cli", "minari", "--dataset-id", "fog-gym/cli-light-v0", "--episodes", "2",
           "--fog", "light", "--episode-seconds", "0.4"]  # fmt: skip
    env = {**os.environ, "MINARI_DATASETS_PATH": str(datasets_path)}
    run = subprocess.run(cmd, capture_output=True, text=True, env=env)
    assert run.returncode == 0, run.stderr
    assert "fog-gym/cli-light-v0: 2 episodes, 4 steps" in run.stdout
    assert minari.load_dataset("fog-gym/cli-light-v0").storage.metadata["fog_level"] == "light"
    again = subprocess.run(cmd, capture_output=True, text=True, env=env)
    assert again.returncode == 1 and again.stderr.startswith("fog-gym minari: Minari dataset 'fog-gym/cli-light-v0' exists")
    bad = subprocess.run(cmd[:6] + ["--fog", "soup"], capture_output=True, text=True, env=env)
    assert bad.returncode == 1 and bad.stderr.startswith("fog-gym minari: fog")


def _example():
    return load_module("examples/bc_minari.py")


class _Scene:
    def __init__(self, ego_xy, others_xy):
        from types import SimpleNamespace

        xy = np.array([ego_xy, *others_xy], float)
        self.ego_id, self.ego_pose = 1, (xy[0, 0], xy[0, 1], 0.0)
        velocities = np.zeros((len(xy), 3))
        velocities[:, 0] = 20.0  # everyone at 20 m/s: a 2 s headway is 40 m
        self.vehicles = SimpleNamespace(ids=np.arange(1, len(xy) + 1), centers=np.c_[xy, np.full(len(xy), 0.75)],
                                        velocities=velocities)  # fmt: skip


@pytest.mark.parametrize("others, action", [
    ([(112.0, 4.0)], 0),                   # blocked, left lane free → LANE_LEFT
    ([(112.0, 4.0), (105.0, 0.0)], 2),     # blocked, left taken, right free → LANE_RIGHT
    ([(112.0, 4.0), (105.0, 0.0), (100.0, 8.0)], 4),  # boxed in → SLOWER
    ([(170.0, 4.0), (100.0, 8.0)], 3),     # 3.5 s headway, right lane taken → FASTER
    ([(150.0, 4.0), (100.0, 8.0)], 1),     # 2.5 s headway, right lane taken → keep lane and speed
    ([], 2),                               # nothing around, a lane to the right → keep right
])  # fmt: skip
def test_rule_driver_of_the_bc_example_overtakes_left_and_keeps_right(others, action):
    from types import SimpleNamespace

    bc = _example()
    env = SimpleNamespace(unwrapped=SimpleNamespace(config=SimpleNamespace(highway_config={"lanes_count": 3})))
    driver = bc.RuleDriver(env)
    driver.base.scene = _Scene((100.0, 4.0), others)  # ego in the middle lane (y = 4 m)
    assert driver(None) == action


def test_bc_example_learns_from_the_dataset_it_loads():
    bc = _example()
    env = gym.make("FogDriveRL-v0", fog="light", episode_seconds=2.0)
    driver = bc.RuleDriver(env)
    seen = []
    collect(env, lambda o: seen.append(driver(o)) or seen[-1], episodes=2, dataset_id="fog-gym/bc-v0", progress=False)
    obs, acts = bc.load_pairs(minari.load_dataset("fog-gym/bc-v0"))
    assert obs["CAM_FRONT"].shape == (20, 3, 64, 64) and acts.tolist() == seen  # every (observation, action) pair
    model, accuracy = bc.train_bc(minari.load_dataset("fog-gym/bc-v0"), epochs=25, progress=False)
    majority = np.bincount(acts).max() / len(acts)
    assert accuracy[-1] >= majority - 1e-6  # at least as good as always predicting the commonest action
    assert bc.bc_policy(model)(env.reset(seed=0)[0]) in range(5)


def test_a_relative_datasets_path_is_made_absolute(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MINARI_DATASETS_PATH", "rel/minari")
    ds = collect(gym.make("FogDriveRL-v0", episode_seconds=0.4), None, episodes=1, dataset_id="fog-gym/rel-v0",
                 progress=False)  # fmt: skip
    assert os.environ["MINARI_DATASETS_PATH"] == str(tmp_path / "rel" / "minari")
    assert ds.total_steps == 2 and (tmp_path / "rel" / "minari" / "fog-gym" / "rel-v0").is_dir()

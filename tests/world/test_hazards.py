"""FogDriveRLHazard-v0: stalled vehicles ahead of the ego (HazardConfig), the forward-looking bird's-eye image and
the speed reward (the scripted drivers and the agent probe: tests/experiments/test_rl_bench.py)."""

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fog_gym.envs.config import FogDriveConfig
from fog_gym.world.hazards import HazardConfig, hazard_rows
from fog_gym.envs.presets import HAZARD_BEV_AHEAD
from fog_gym.world.traffic_world import TrafficWorld

HW = {"lanes_count": 3, "vehicles_count": 10}


@settings(max_examples=60, deadline=None)
@given(st.floats(-50, 300, allow_nan=False), st.floats(-50, 300, allow_nan=False))
def test_hazard_ranges_are_valid_exactly_when_positive_and_ordered(lo, hi):
    if 0 < lo <= hi:
        assert HazardConfig(first=(lo, hi)).first == (lo, hi)
    else:
        with pytest.raises(ValueError, match="first must be"):
            HazardConfig(first=(lo, hi))


@pytest.mark.parametrize("kwargs, match", [({"gap": (10.0,)}, "gap must be"), ({"span": 0.0}, "span must be > 0"),
                                           ({"clearance": -1.0}, "clearance must be >= 0"),
                                           ({"first": (float("nan"), 5.0)}, "finite")])  # fmt: skip
def test_bad_hazard_configs_are_refused(kwargs, match):
    with pytest.raises(ValueError, match=match):
        HazardConfig(**kwargs)


def test_env_and_world_refuse_a_hazards_value_that_is_not_a_config():
    with pytest.raises(ValueError, match="hazards must be a HazardConfig"):
        FogDriveConfig(hazards={"first": (1, 2)})
    with pytest.raises(ValueError, match="hazards must be a HazardConfig"):
        TrafficWorld("highway", hazards=3)


def test_stalled_vehicles_lie_ahead_at_the_configured_spacing_and_stay_put():
    hz = HazardConfig(first=(60.0, 120.0), gap=(70.0, 140.0), span=700.0, clearance=25.0)
    world = TrafficWorld("highway", keyframe_frequency=5, highway_config=HW, hazards=hz)
    world.reset(seed=3)
    h0 = world.hazards_ego()
    ahead = h0[:, 0]
    assert 60.0 <= ahead[0] <= 120.0 and np.all(np.diff(ahead) >= 70.0) and np.all(np.diff(ahead) <= 140.0)
    assert ahead[-1] <= 700.0 and ahead[-1] + 140.0 > 700.0 - 1e-9  # the span is filled
    assert set(np.round(h0[:, 1] - np.round(h0[:, 1] / 4.0) * 4.0, 6)) == {0.0}  # on lane centres (4 m lanes)
    state = world.vehicle_state()
    x, y, _ = world.ego_pose
    # no other vehicle within the clearance of a stalled one in its lane
    for a, r, *_ in h0:
        hx, hy = x + a, y + r
        d = np.hypot(state.centers[:, 0] - hx, state.centers[:, 1] - hy)
        same_lane = np.abs(state.centers[:, 1] - hy) < 2.0
        assert np.sum((d < 25.0) & same_lane) == 1  # itself
    start = world.hazards_ego()[:, :2] + np.array([x, y])
    for _ in range(10):
        world.step(1)
    x1, y1, _ = world.ego_pose
    assert np.allclose(world.hazards_ego()[:, :2] + np.array([x1, y1]), start, atol=1e-9)  # stopped


def test_hazard_placement_is_seeded():
    hz = HazardConfig()
    a, b = (TrafficWorld("highway", highway_config=HW, hazards=hz) for _ in range(2))
    a.reset(seed=11)
    b.reset(seed=11)
    assert np.array_equal(a.hazards_ego(), b.hazards_ego())
    b.reset(seed=12)
    assert not np.array_equal(a.hazards_ego()[:, :2], b.hazards_ego()[:, :2])


def test_hazard_preset_rewards_forward_speed_and_ends_on_a_collision():
    env = gym.make("FogDriveRLHazard-v0")
    obs, info = env.reset(seed=2_000_000)  # a stalled vehicle lies in the ego's lane (checked below)
    assert env.observation_space.contains(obs)
    h = info["hazards"]  # a fixed (capacity, 4) array: the first hazard_count rows are the stalled vehicles, zeros after
    assert h.shape == (HazardConfig().capacity, 4) and (h[info["hazard_count"]:] == 0).all()
    real = hazard_rows(info)
    assert len(real) == info["hazard_count"] >= 1 and (real[:, 2] > 0).all() and np.any(np.abs(real[:, 1]) < 0.5)
    rewards, infos = [], []
    for _ in range(100):
        obs, r, term, trunc, info = env.step(1)  # idle: hold the lane at 25 m/s
        rewards.append(r)
        infos.append(info)
        if term or trunc:
            break
    assert term and info["crashed"]
    assert rewards[0] == pytest.approx(infos[0]["speed"] / 30.0)  # forward speed / 30 (straight road)
    assert rewards[-1] == pytest.approx(infos[-1]["speed"] / 30.0 - 1.0)  # the collision costs 1


def test_fogdriverl_keeps_its_meaning():
    env = gym.make("FogDriveRL-v0")
    _, info = env.reset(seed=0)
    assert "hazards" not in info and env.unwrapped.config.hazards is None
    _, r, *_ = env.step(1)
    assert 0.0 <= r <= 1.0  # highway-env's normalised reward


def test_forward_bird_eye_image_puts_a_point_where_documented():
    from fog_gym.wrappers import LidarBEV

    class Points(gym.Env):
        observation_space = gym.spaces.Dict({"LIDAR_TOP": gym.spaces.Box(-1e3, 1e3, (4, 4), np.float32)})
        action_space = gym.spaces.Discrete(1)

        def reset(self, *, seed=None, options=None):
            # one point 45.2 m ahead, 3.7 m left, 1.5 m above the road (the sensor is 2 m up)
            return {"LIDAR_TOP": np.array([[45.2, -3.7, -0.5, 1.0]], np.float32)}, {}

    env = LidarBEV(Points(), size=64, metres=64.0, ahead=HAZARD_BEV_AHEAD)
    obs, _ = env.reset()
    rows, cols = np.nonzero(obs["LIDAR_BEV"][0])
    assert (rows.tolist(), cols.tolist()) == ([int(np.floor(32 + 24 - 45.2))], [int(np.floor(-3.7 + 32))])  # (10, 28)
    with pytest.raises(ValueError, match="ahead must be"):
        LidarBEV(Points(), metres=64.0, ahead=32.0)


def test_close_hazards_never_clear_each_other_away():
    hz = HazardConfig(first=(30.0, 30.0), gap=(10.0, 10.0), span=100.0, clearance=25.0)
    world = TrafficWorld("highway", highway_config=HW, hazards=hz)
    world.reset(seed=5)
    h = world.hazards_ego()
    assert np.allclose(h[:, 0] - h[0, 0], np.arange(8) * 10.0)  # 30, 40, …, 100 m ahead
    state = world.vehicle_state()
    stalled = np.linalg.norm(state.velocities, axis=1) == 0.0
    assert stalled.sum() == len(h) == 8  # every placed vehicle is on the road


def test_fogdriverl_reward_is_highway_envs_normalised_as_documented():
    env = gym.make("FogDriveRL-v0")
    env.reset(seed=1)
    for _ in range(6):
        _, r, term, _, info = env.step(4)  # slower: down to 20 m/s
        assert not term
        parts = info["rewards"]
        # (−1·collision + 0.1·right lane + 0.4·speed over 20–30 m/s) mapped from [−1, 0.5] to [0, 1]
        assert r == pytest.approx((1.0 + 0.1 * parts["right_lane_reward"] + 0.4 * parts["high_speed_reward"]) / 1.5)
    assert info["speed"] == pytest.approx(20.0, abs=1.0) and 0.66 <= r <= 0.74  # surviving at 20 m/s earns ≈ 0.7

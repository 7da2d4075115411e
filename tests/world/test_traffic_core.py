"""The traffic core reproduces highway-env's own path exactly (trajectories, rewards, flags, random draws)."""

from __future__ import annotations

import gymnasium as gym
import highway_env  # noqa: F401  (registers the envs)
import numpy as np
import pytest

from fog_gym.world.traffic import accelerate, is_accelerated
from fog_gym.world.towns import check_traffic_mode
from tests.world.traffic_identity import PLAIN_SCENARIOS, compare_plain, compare_town

SCENARIOS = list(PLAIN_SCENARIOS)
run_pair = compare_plain
run_towns = compare_town


@pytest.mark.parametrize(("env_id", "config"), SCENARIOS, ids=[s[0] for s in SCENARIOS])
def test_accelerated_env_matches_highway_env_step_for_step(env_id, config):
    run_pair(env_id, config, seed=3, steps=15)


@pytest.mark.slow
@pytest.mark.parametrize(("env_id", "config"), SCENARIOS, ids=[s[0] for s in SCENARIOS])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_accelerated_env_matches_highway_env_over_300_steps(env_id, config, seed):
    run_pair(env_id, config, seed=seed, steps=300)


def test_accelerate_is_per_instance_and_idempotent():
    from highway_env.road.road import Road

    plain = gym.make("highway-fast-v0")
    fast = accelerate(gym.make("highway-fast-v0"))
    plain.reset(seed=0)
    fast.reset(seed=0)
    assert is_accelerated(fast) and not is_accelerated(plain)
    assert "neighbour_vehicles" in vars(fast.unwrapped.road)
    assert "neighbour_vehicles" not in vars(plain.unwrapped.road)
    assert Road.neighbour_vehicles.__module__ == "highway_env.road.road"
    assert accelerate(fast) is fast  # no-op the second time
    fast.reset(seed=1)  # re-installed on the new road
    assert "neighbour_vehicles" in vars(fast.unwrapped.road)


def test_accelerate_rejects_other_envs():
    with pytest.raises(TypeError, match="highway-env environment"):
        accelerate(gym.make("CartPole-v1"))
    with pytest.raises(TypeError, match="highway-env environment"):
        accelerate(gym.make("parking-v0"))
    with pytest.raises(TypeError):
        accelerate(object())


def test_unknown_traffic_mode_names_the_allowed_values():
    with pytest.raises(ValueError, match=r"traffic must be one of \('fast', 'reference', 'native'\)"):
        check_traffic_mode("numba")
    with pytest.raises(ValueError):
        check_traffic_mode(None)


@pytest.mark.parametrize("town", ["highway", "merge", "roundabout", "intersection", "exit", "racetrack"])
def test_fogdrive_towns_match_reference_traffic(town):
    from fog_gym.world.towns import TOWNS

    if town not in TOWNS:
        pytest.skip(f"{town} is not a fog-gym town")
    run_towns(town, seed=5, steps=12)


@pytest.mark.slow
@pytest.mark.parametrize("town", ["highway", "merge", "roundabout", "intersection", "exit", "racetrack"])
@pytest.mark.parametrize("seed", [0, 1])
def test_fogdrive_towns_match_reference_traffic_over_300_steps(town, seed):
    from fog_gym.world.towns import TOWNS

    if town not in TOWNS:
        pytest.skip(f"{town} is not a fog-gym town")
    run_towns(town, seed=seed, steps=300)


def test_fogdrive_env_rejects_unknown_traffic_before_building():
    from fog_gym.envs.config import FogDriveConfig
    from fog_gym.envs.fogdrive import FogDriveEnv

    with pytest.raises(ValueError, match="traffic must be one of"):
        FogDriveEnv(traffic="numba")
    with pytest.raises(ValueError, match="traffic must be one of"):
        FogDriveConfig(traffic="compiled")
    assert FogDriveConfig().traffic == "fast"


def test_straight_lane_projection_matches_highway_env_to_the_rounding_of_its_dot_product():
    """highway-env's ``np.dot`` on two-vectors is BLAS's ddot, whose last bit depends on the CPU kernel OpenBLAS picks
    (with FMA on AVX-512 machines, without elsewhere); the core's written-out sum agrees to a few ulps everywhere and
    bit for bit where BLAS does not fuse. The env-level identity (1e-9 m, identical decisions) is checked below."""
    from highway_env.road.lane import StraightLane

    from fog_gym.world.traffic.core import straight_lane_projection

    rng = np.random.default_rng(7)
    lane = StraightLane(rng.uniform(-50, 50, 2), rng.uniform(100, 300, 2), width=4.0)
    pos = rng.uniform(-100, 350, (2000, 2))
    pos[:50] = lane.start + np.outer(rng.uniform(-6, lane.length + 6, 50), lane.direction)  # near both ends
    s, on = straight_lane_projection(pos, lane.start, lane.direction, lane.direction_lateral, lane.width,
                                     lane.length, lane.VEHICLE_LENGTH)  # fmt: skip
    ref = [lane.local_coordinates(p) for p in pos]
    np.testing.assert_allclose(s, [r[0] for r in ref], rtol=1e-13, atol=1e-12)
    np.testing.assert_array_equal(on, [lane.on_lane(p, *r, margin=1) for p, r in zip(pos, ref)])
    assert on.any() and not on.all()


def test_fast_neighbour_search_matches_highway_env_for_every_vehicle_and_lane():
    from highway_env.road.road import Road

    from fog_gym.world.traffic.core import lane_cache

    env = accelerate(gym.make("highway-v0", config={"vehicles_count": 40}))
    env.reset(seed=11)
    road = env.unwrapped.road
    road._fog_lane_cache = lane_cache(road)  # as inside Road.act
    queries = 0
    for v in road.vehicles:
        for lane_index in road.network.all_side_lanes(v.lane_index):
            assert road.neighbour_vehicles(v, lane_index) == Road.neighbour_vehicles(road, v, lane_index)
            queries += 1
    road._fog_lane_cache = None
    assert queries == 4 * len(road.vehicles)

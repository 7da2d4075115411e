"""The native array traffic core against highway-env's own path, and its batching."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fog_gym.envs.presets import HAZARD_TRAFFIC, RL_TRAFFIC
from fog_gym.world.hazards import HazardConfig
from fog_gym.world.traffic import kernels as K
from fog_gym.world.traffic.native import NativeTraffic
from tests.world.traffic_identity import compare_native

PRESETS = {"FogDriveRL-v0": (RL_TRAFFIC, None), "FogDriveRLHazard-v0": (HAZARD_TRAFFIC, HazardConfig())}


@pytest.mark.parametrize("preset", sorted(PRESETS))
def test_native_traffic_matches_highway_env_step_for_step(preset):
    config, hazards = PRESETS[preset]
    compare_native(config, seed=3, steps=60, hazards=hazards)


@pytest.mark.slow
@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("preset", sorted(PRESETS))
def test_native_traffic_matches_highway_env_for_300_steps(preset, seed):
    config, hazards = PRESETS[preset]
    assert compare_native(config, seed=seed, steps=300, hazards=hazards) > 0  # episodes end and restart too


def test_native_traffic_matches_highway_env_on_a_wider_road_with_other_target_speeds():
    config = {"lanes_count": 4, "vehicles_count": 15, "vehicles_density": 1.5, "ego_spacing": 1.0,
              "action": {"type": "DiscreteMetaAction", "target_speeds": [10.0, 15.0, 20.0, 25.0, 30.0]}}  # fmt: skip
    compare_native(config, seed=11, steps=40, keyframe_frequency=10)


def test_worlds_stepped_together_equal_worlds_stepped_alone():
    together = NativeTraffic(3, RL_TRAFFIC, None, 20, 5)
    alone = [NativeTraffic(1, RL_TRAFFIC, None, 20, 5) for _ in range(3)]
    for w in range(3):
        together.reset(w, 100 + w)
        alone[w].reset(0, 100 + w)
    rng = np.random.default_rng(0)
    for _ in range(30):
        actions = rng.integers(5, size=3)
        together.step(actions)
        for w in range(3):
            alone[w].step(actions[w : w + 1])
    for w in range(3):
        n = together.counts[w]
        np.testing.assert_array_equal(together.floats[w, :n], alone[w].floats[0, :n])
        np.testing.assert_array_equal(together.ints[w, :n], alone[w].ints[0, :n])


def test_an_inactive_world_does_not_move():
    t = NativeTraffic(2, RL_TRAFFIC, None, 20, 5)
    t.reset(0, 1)
    t.reset(1, 2)
    before = t.floats[1].copy()
    t.step(np.array([3, 3]), active=np.array([True, False]))
    np.testing.assert_array_equal(t.floats[1], before)
    assert t.ticks.tolist() == [4, 0]


def test_stalled_vehicles_stay_put_and_clear_their_surroundings():
    t = NativeTraffic(1, HAZARD_TRAFFIC, HazardConfig(), 20, 5)
    t.reset(0, 5)
    slots = t.hazard_slots[0]
    assert len(slots) >= 1 and (t.ints[0, slots, K.IKIND] == K.STALLED).all()
    xy = t.floats[0, slots][:, [K.FX, K.FY]].copy()
    t.step(np.array([1]))
    np.testing.assert_array_equal(t.floats[0, slots][:, [K.FX, K.FY]], xy)
    ahead = t.hazards_ego(0)[:, 0]
    assert ahead[0] >= 60.0 - 25.0 * 0.2 - 1e-9 and np.all(np.diff(ahead) > 0)  # first 60–120 m ahead, ordered


@settings(max_examples=20, deadline=None)
@given(st.one_of(st.integers(max_value=0), st.booleans(), st.floats(), st.text()))
def test_bad_world_counts_are_refused(n):
    with pytest.raises(ValueError, match="num_worlds must be an integer >= 1"):
        NativeTraffic(n)


@pytest.mark.parametrize("config, match", [
    ({"action": {"type": "ContinuousAction"}}, "DiscreteMetaAction"),
    ({"manual_control": True}, "does not support 'manual_control'"),
    ({"other_vehicles_type": "highway_env.vehicle.behavior.LinearVehicle"}, "IDMVehicle"),
])  # fmt: skip
def test_settings_the_native_core_cannot_reproduce_are_refused(config, match):
    with pytest.raises(ValueError, match=match):
        NativeTraffic(1, config)


def test_actions_outside_the_meta_actions_are_refused():
    t = NativeTraffic(1, RL_TRAFFIC)
    t.reset(0, 0)
    with pytest.raises(ValueError, match="meta-actions 0..4"):
        t.step(np.array([7]))

"""fog_gym.world.traffic.vehicles restates highway-env's per-vehicle hot paths bit for bit."""

from __future__ import annotations

import copy
import types

import gymnasium as gym
import highway_env  # noqa: F401  (registers the envs)
import numpy as np
import pytest

from fog_gym.world.traffic import accelerate
from fog_gym.world.traffic.vehicles import RoadFast, act_eligible, step_kind


def _road(env_id: str, seed: int = 0):
    env = gym.make(env_id)
    env.reset(seed=seed)
    return env, env.unwrapped.road


@pytest.mark.parametrize("env_id", ["highway-fast-v0", "merge-v0", "roundabout-v0", "intersection-v0", "racetrack-v0"])
def test_batched_closest_lane_equals_highway_env_for_every_lane_kind(env_id):
    env, road = _road(env_id)
    lanes = road.network.lanes_list()
    rng = np.random.default_rng(3)
    probes = []
    for _ in range(400):  # points on, beside, before and after random lanes, with random headings
        lane = lanes[rng.integers(len(lanes))]
        s = rng.uniform(-10, lane.length + 10)
        probes.append(types.SimpleNamespace(position=lane.position(s, rng.normal(0, 3)),
                                            heading=float(lane.heading_at(s) + rng.normal(0, 0.6))))  # fmt: skip
    RoadFast(road).update_lanes(probes)
    for p in probes:
        assert p.lane_index == road.network.get_closest_lane_index(p.position, p.heading)
        assert p.lane is road.network.get_lane(p.lane_index)
    env.close()


def test_kinematic_step_equals_vehicle_step_including_crash_impact_and_speed_limits():
    env, road = _road("highway-fast-v0", seed=4)
    rng = np.random.default_rng(5)
    fast = RoadFast(road)
    checked = 0
    for v in road.vehicles:
        for case in range(4):
            a, b = copy.deepcopy(v), copy.deepcopy(v)
            action = {"steering": float(rng.uniform(-0.5, 0.5)), "acceleration": float(rng.uniform(-6, 6))}
            for w in (a, b):
                w.action = dict(action)
                if case == 1:
                    w.crashed = True
                if case == 2:
                    w.impact = np.array([0.3, -0.2])
                if case == 3:
                    w.speed = 45.0  # above MAX_SPEED: acceleration is limited
            kind = step_kind(b, b.road)
            assert kind is not None
            a.step(0.05)
            fast.kinematic_step(b, 0.05, kind)
            fast.update_lanes([b])
            assert a.position.tolist() == b.position.tolist()
            assert (a.heading, a.speed, a.crashed, a.lane_index) == (b.heading, b.speed, b.crashed, b.lane_index)
            assert a.action == b.action
            if case == 2:
                assert a.impact is None and b.impact is None and b.crashed
            checked += 1
    assert checked == 4 * len(road.vehicles)
    env.close()


def test_vehicles_with_their_own_methods_keep_them():
    env = accelerate(gym.make("highway-fast-v0"))
    env.reset(seed=0)
    road = env.unwrapped.road
    ego, idm = road.vehicles[0], road.vehicles[1]
    assert not act_eligible(ego) and act_eligible(idm)  # the ego is an MDPVehicle: its own act
    calls = []
    idm.act = lambda action=None: calls.append("act")  # an instance-level override
    idm.step = lambda dt: calls.append("step")
    assert not act_eligible(idm) and step_kind(idm, road) is None
    position = idm.position.copy()
    env.step(1)
    assert calls.count("act") == calls.count("step") > 0
    assert idm.position.tolist() == position.tolist()  # its own (no-op) step ran, not the inlined one
    env.close()


@pytest.mark.parametrize("env_id", ["highway-v0", "roundabout-v0", "merge-v0"])
def test_batched_idm_controls_equal_the_scalar_restatement_of_idm_act(env_id):
    from fog_gym.world.traffic.core import lane_cache

    env = accelerate(gym.make(env_id))
    env.reset(seed=2)
    road = env.unwrapped.road
    rng = np.random.default_rng(2)
    for v in road.vehicles[1:]:  # varied states: lane changes under way, speeds off target
        v.speed = float(v.speed + rng.normal(0, 3))
        if rng.random() < 0.3:
            sides = road.network.side_lanes(v.lane_index)
            if sides:
                v.target_lane_index = sides[0]
    fast = road._fog_fast
    road._fog_lane_cache = lane_cache(road)
    fast.xy = {}
    idm = [v for v in road.vehicles if act_eligible(v) and not v.crashed]
    assert len(idm) >= 4 and any(v.lane_index != v.target_lane_index for v in idm)
    scalar = []
    for v in idm:
        fast.idm_control(v, road.neighbour_vehicles)
        scalar.append(dict(v.action))
    fast.idm_controls(idm, road.neighbour_vehicles)
    road._fog_lane_cache = None
    assert [v.action for v in idm] == scalar
    env.close()


def test_pairs_found_clearly_apart_have_no_collision_in_highway_env():
    from highway_env.vehicle.kinematics import Vehicle

    from fog_gym.world.traffic.core import clearly_apart

    rng = np.random.default_rng(9)
    vehicles = []
    for _ in range(3000):  # pairs of rectangles of random size and pose, from overlapping to a few metres apart
        a = Vehicle(None, rng.uniform(-1, 1, 2) + 1000.0, heading=float(rng.uniform(-np.pi, np.pi)),
                    speed=float(rng.uniform(-5, 40)))  # fmt: skip
        b = Vehicle(None, a.position + rng.normal(0, 4, 2), heading=float(a.heading + rng.normal(0, 0.5)),
                    speed=float(rng.uniform(0, 40)))  # fmt: skip
        for v in (a, b):
            v.LENGTH, v.WIDTH = float(rng.uniform(3, 12)), float(rng.uniform(1.6, 2.6))
            v.diagonal = float(np.hypot(v.LENGTH, v.WIDTH))
        vehicles += [a, b]
    i = np.arange(0, len(vehicles), 2)
    apart = clearly_apart(vehicles, i, i + 1, 0.05)
    outcomes = [vehicles[k]._is_colliding(vehicles[k + 1], 0.05)[:2] for k in i.tolist()]
    assert all(out == (False, False) for out, skip in zip(outcomes, apart) if skip)
    assert apart.sum() > 1000 and sum(any(out) for out in outcomes) > 300  # both kinds of pair are common

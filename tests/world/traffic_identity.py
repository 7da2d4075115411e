"""Step a reference and an accelerated traffic path side by side and assert they agree (tests, benchmark).

It sits above both the traffic core and :class:`~fog_gym.world.traffic_world.TrafficWorld`, which it compares.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from fog_gym.world.traffic.core import accelerate, is_accelerated

#: Plain highway-env scenarios ``accelerate`` supports, with the config used for the identity checks.
PLAIN_SCENARIOS: tuple[tuple[str, dict[str, Any]], ...] = (
    ("highway-v0", {"vehicles_count": 30}),
    ("highway-fast-v0", {}),
    ("merge-v0", {}),
    ("roundabout-v0", {}),
    ("intersection-v0", {}),
    ("racetrack-v0", {}),
    ("exit-v0", {}),
)


def _state(env: Any) -> np.ndarray:
    road = env.unwrapped.road
    return np.array([[*v.position, v.heading, v.speed] for v in road.vehicles], dtype=np.float64).reshape(-1, 4)


def compare_plain(env_id: str, config: dict[str, Any], seed: int, steps: int, atol: float = 1e-9) -> int:
    """``gym.make(env_id)`` against ``accelerate(gym.make(env_id))`` with seeded random actions.

    Asserts every vehicle's position, heading and speed agree within ``atol`` and rewards, ``crashed``,
    ``terminated`` and ``truncated`` are identical after every step. Returns the number of episodes ended.
    """
    import gymnasium as gym
    import highway_env  # noqa: F401

    ref = gym.make(env_id, config=dict(config))
    fast = accelerate(gym.make(env_id, config=dict(config)))
    assert is_accelerated(fast) and not is_accelerated(ref)
    ref.reset(seed=seed)
    fast.reset(seed=seed)
    ref.action_space.seed(seed)
    ended = 0
    for k in range(steps):
        action = ref.action_space.sample()
        _, r_ref, term_ref, trunc_ref, info_ref = ref.step(action)
        _, r_fast, term_fast, trunc_fast, info_fast = fast.step(action)
        where = f"{env_id} seed {seed} step {k}"
        a, b = _state(ref), _state(fast)
        assert a.shape == b.shape, f"{where}: vehicle count differs"
        np.testing.assert_allclose(b, a, rtol=0, atol=atol, err_msg=where)
        assert r_fast == r_ref, where
        assert (term_fast, trunc_fast) == (term_ref, trunc_ref), where
        assert info_fast["crashed"] == info_ref["crashed"], where
        if term_ref or trunc_ref:
            ended += 1
            ref.reset(seed=seed + 1000 + k)
            fast.reset(seed=seed + 1000 + k)
    ref.close()
    fast.close()
    return ended


def compare_town(town: str, seed: int, steps: int, atol: float = 1e-9) -> int:
    """A fog-gym town's ``TrafficWorld`` with ``traffic="reference"`` against ``traffic="fast"``.

    Same checks as :func:`compare_plain` on ids, centres, yaws, velocities, rewards and termination.
    """
    from fog_gym.world.traffic_world import TrafficWorld

    ref, fast = TrafficWorld(town, traffic="reference"), TrafficWorld(town, traffic="fast")
    assert fast.accelerated and not ref.accelerated
    ref.reset(seed=seed)
    fast.reset(seed=seed)
    ref.action_space.seed(seed)
    ended = 0
    for k in range(steps):
        action = ref.action_space.sample()
        r_ref, t_ref, _ = ref.step(action)
        r_fast, t_fast, _ = fast.step(action)
        where = f"{town} seed {seed} step {k}"
        a, b = ref.vehicle_state(), fast.vehicle_state()
        np.testing.assert_array_equal(b.ids, a.ids, err_msg=where)
        np.testing.assert_allclose(b.centers, a.centers, rtol=0, atol=atol, err_msg=where)
        np.testing.assert_allclose(b.yaws, a.yaws, rtol=0, atol=atol, err_msg=where)
        np.testing.assert_allclose(b.velocities, a.velocities, rtol=0, atol=atol, err_msg=where)
        assert (r_fast, t_fast) == (r_ref, t_ref), where
        assert ref.ego_crashed == fast.ego_crashed, where
        if t_ref:
            ended += 1
            ref.reset(seed=seed + k + 1)
            fast.reset(seed=seed + k + 1)
    return ended


def compare_native(overrides: dict[str, Any], seed: int, steps: int, hazards: Any = None, keyframe_frequency: int = 5,
                   atol: float = 1e-9) -> int:  # fmt: skip
    """The highway town's ``TrafficWorld`` on highway-env's own path (``traffic="reference"``) against the native
    array core (:class:`~fog_gym.world.traffic.native.NativeTraffic`), with seeded random meta-actions.

    After every step: ids, classes, sizes and colours equal; every vehicle's position, heading and speed within
    ``atol``; every vehicle's lane, target lane and crash flag, the ego's termination identical; the reward within
    ``atol``. An ended episode restarts both on a new seed. Returns the number of episodes ended.
    """
    from fog_gym.world.traffic import kernels as K
    from fog_gym.world.traffic.native import NativeTraffic
    from fog_gym.world.traffic_world import TrafficWorld

    ref = TrafficWorld("highway", 20, keyframe_frequency, highway_config=dict(overrides), traffic="reference",
                       hazards=hazards)  # fmt: skip
    nat = NativeTraffic(1, overrides, hazards, 20, keyframe_frequency)
    rng = np.random.default_rng(seed)
    episode_seed = seed
    ref.reset(seed=episode_seed)
    nat.reset(0, episode_seed)
    ended = 0
    for k in range(steps + 1):
        where = f"seed {episode_seed} step {k}"
        a = ref.vehicle_state()
        ids, classes, centers, sizes, yaws, vel, colors = nat.vehicle_arrays(0)
        np.testing.assert_array_equal(ids, a.ids, err_msg=where)
        np.testing.assert_array_equal(classes, a.classes, err_msg=where)
        np.testing.assert_array_equal(sizes, a.sizes, err_msg=where)
        np.testing.assert_array_equal(colors, a.colors, err_msg=where)
        np.testing.assert_allclose(centers, a.centers, rtol=0, atol=atol, err_msg=where)
        np.testing.assert_allclose(yaws, a.yaws, rtol=0, atol=atol, err_msg=where)
        np.testing.assert_allclose(vel, a.velocities, rtol=0, atol=atol, err_msg=where)
        vs = ref.vehicles()
        n = len(vs)
        lanes = [v.lane_index[2] for v in vs]
        targets = [getattr(v, "target_lane_index", v.lane_index)[2] for v in vs]
        crashed = [bool(v.crashed) for v in vs]
        assert nat.ints[0, :n, K.ILANE].tolist() == lanes, where
        kinds = nat.ints[0, :n, K.IKIND]
        assert [t for t, kd in zip(nat.ints[0, :n, K.ITLANE].tolist(), kinds) if kd != K.STALLED] == \
            [t for t, kd in zip(targets, kinds) if kd != K.STALLED], where  # fmt: skip
        assert nat.ints[0, :n, K.ICRASH].astype(bool).tolist() == crashed, where
        if k == steps:
            break
        action = int(rng.integers(5))
        r_ref, t_ref, _ = ref.step(action)
        nat.step(np.array([action]))
        assert abs(nat.reward(0) - r_ref) <= atol, where
        assert nat.ego_crashed(0) == ref.ego_crashed, where
        if t_ref:
            ended += 1
            episode_seed = seed * 1000 + k + 1
            ref.reset(seed=episode_seed)
            nat.reset(0, episode_seed)
    return ended

"""The native traffic core: highway-env's ``HighwayEnv`` (straight parallel lanes) for N worlds as arrays.

:class:`NativeTraffic` holds the state of ``num_worlds`` worlds as (worlds × vehicles) arrays and steps all of
them in one numba call (:mod:`fog_gym.world.traffic.kernels`): no highway-env object and no Python per vehicle
on the step path. A reset spawns the vehicles as ``HighwayEnv._create_vehicles`` does, drawing from a Generator
seeded as highway-env seeds its own with the same calls in the same order, so a seed means what it means in
highway-env; fog-gym's vehicle classes, sizes and colours (:mod:`fog_gym.world.traffic_world`) and the stalled
vehicles (:mod:`fog_gym.world.hazards`) are drawn from their own named streams as :class:`TrafficWorld` does.

Columns of ``floats[w, k]``: x, y, heading, speed, target speed, IDM lane-change timer, IDM exponent δ, length,
width, diagonal, impact x, impact y, steering, acceleration; of ``ints[w, k]``: kind (0 ego, 1 IDM vehicle,
2 stalled vehicle), lane, target lane, crashed, impact pending, has a target speed, speed index (ego).
Slot 0 is the ego; slots follow highway-env's ``road.vehicles`` order. fog-gym ids, classes, heights and colours
are in ``ids``, ``classes``, ``heights``, ``colors``.

Supported: the ``highway`` town with ``DiscreteMetaAction`` (any target speeds), any lane and vehicle count, IDM
traffic, the fog-gym IDM profile, hazards. Anything else raises ``ValueError`` naming the setting.

Example:
    >>> t = NativeTraffic(2, {"lanes_count": 3, "vehicles_count": 5})
    >>> t.reset(0, seed=7); t.reset(1, seed=8)
    >>> t.step(np.array([1, 3]))
    >>> t.counts.tolist(), bool(t.floats[1, 0, 3] > t.floats[0, 0, 3])  # world 1's ego accelerates (FASTER)
    ([6, 6], True)
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from fog_gym._numba import launch
from fog_gym.seeds import stream
from fog_gym.world.fleet import EGO_COLOR, EGO_SIZE, draw_vehicle
from fog_gym.world.hazards import HazardConfig
from fog_gym.world.towns import IDM_PROFILES, TOWN_SPECS, highway_env_config
from fog_gym.world.traffic import kernels as K

#: highway-env config keys the native core reproduces (others must keep HighwayEnv's defaults).
SUPPORTED_KEYS = frozenset((
    "lanes_count", "vehicles_count", "vehicles_density", "ego_spacing", "initial_lane_id", "controlled_vehicles",
    "action", "simulation_frequency", "policy_frequency", "duration", "offroad_terminal", "collision_reward",
    "right_lane_reward", "high_speed_reward", "lane_change_reward", "reward_speed_range", "normalize_reward",
    "offscreen_rendering", "observation", "other_vehicles_type", "show_trajectories",
))  # fmt: skip
_DEFAULT_TARGET_SPEEDS = np.linspace(20, 30, 3)  # MDPVehicle.DEFAULT_TARGET_SPEEDS


def highway_config(overrides: Mapping[str, Any] | None = None, simulation_frequency: int = 20,
                   keyframe_frequency: int = 10) -> dict[str, Any]:  # fmt: skip
    """The ``highway`` town's full highway-env config (HighwayEnv's defaults, fog-gym's town settings, overrides),
    checked for what the native core supports; ``ValueError`` names an unsupported setting."""
    from highway_env.envs.highway_env import HighwayEnv

    config = HighwayEnv.default_config()
    config.update(highway_env_config("highway", simulation_frequency, keyframe_frequency, dict(overrides or {})))
    for key in dict(overrides or {}):
        if key not in SUPPORTED_KEYS:
            raise ValueError(f"highway_config: the native traffic core does not support {key!r} "
                             f"(supported: {sorted(SUPPORTED_KEYS)}); use traffic='fast'")  # fmt: skip
    action = config["action"]
    if action.get("type") != "DiscreteMetaAction" or set(action) - {"type", "target_speeds"}:
        raise ValueError(f"highway_config['action'] must be DiscreteMetaAction (optionally with target_speeds) for the "
                         f"native traffic core, got {action!r}")  # fmt: skip
    if config["controlled_vehicles"] != 1:
        raise ValueError(f"the native traffic core drives one controlled vehicle, got {config['controlled_vehicles']}")
    if config["other_vehicles_type"] != "highway_env.vehicle.behavior.IDMVehicle":
        raise ValueError(f"the native traffic core drives IDMVehicle traffic, got {config['other_vehicles_type']!r}")
    if config["simulation_frequency"] % config["policy_frequency"]:
        raise ValueError("simulation_frequency must be a multiple of policy_frequency")
    return config


class NativeTraffic:
    """``num_worlds`` highway worlds stepped together; see the module docstring for the state layout.

    ``config`` overrides the highway town's highway-env config (:func:`highway_config`); ``hazards`` places
    stalled vehicles at each reset (:class:`~fog_gym.world.hazards.HazardConfig`). :meth:`reset` one world,
    :meth:`step` all active ones.
    """

    def __init__(self, num_worlds: int, config: Mapping[str, Any] | None = None, hazards: HazardConfig | None = None,
                 simulation_frequency: int = 20, keyframe_frequency: int = 10) -> None:  # fmt: skip
        if isinstance(num_worlds, bool) or not isinstance(num_worlds, (int, np.integer)) or num_worlds < 1:
            raise ValueError(f"num_worlds must be an integer >= 1, got {num_worlds!r}")
        if hazards is not None and not isinstance(hazards, HazardConfig):
            raise ValueError(f"hazards must be a HazardConfig or None, got {type(hazards).__name__}")
        self.config = highway_config(config, simulation_frequency, keyframe_frequency)
        self.hazards = hazards
        c = self.config
        self.lanes = int(c["lanes_count"])
        self.frames = int(c["simulation_frequency"] // c["policy_frequency"])
        self.dt = 1 / c["simulation_frequency"]
        speeds = c["action"].get("target_speeds")
        self.target_speeds = np.array(speeds, np.float64) if speeds is not None else _DEFAULT_TARGET_SPEEDS.copy()
        profile = IDM_PROFILES[TOWN_SPECS["highway"].idm]
        self.d0, self.cam, self.cmin = profile["DISTANCE_WANTED"], profile["COMFORT_ACC_MAX"], profile["COMFORT_ACC_MIN"]
        self.capacity = int(c["vehicles_count"]) + 1 + self._max_hazards()
        w, v = int(num_worlds), self.capacity
        self.num_worlds = w
        self.floats = np.zeros((w, v, K.N_FLOAT))
        self.ints = np.zeros((w, v, K.N_INT), np.int64)
        self.counts = np.zeros(w, np.int64)
        self.ids = np.zeros((w, v), np.int32)
        self.classes = np.zeros((w, v), np.int8)
        self.heights = np.zeros((w, v))
        self.colors = np.zeros((w, v, 3))
        self.hazard_slots: list[np.ndarray] = [np.zeros(0, np.int64) for _ in range(w)]
        self.ticks = np.zeros(w, np.int64)
        self.start_position = np.zeros((w, 2))

    def _max_hazards(self) -> int:
        hz = self.hazards
        return 0 if hz is None else hz.capacity

    @property
    def action_count(self) -> int:
        return 5

    # -- reset ----------------------------------------------------------------------------------------
    def reset(self, w: int, seed: int | None) -> None:
        """Spawn world ``w`` as ``HighwayEnv.reset(seed=seed)`` followed by fog-gym's classes and hazards."""
        from gymnasium.utils import seeding

        rng = seeding.np_random(seed)[0]
        c = self.config
        lanes = self.lanes
        xs: list[float] = []
        ys: list[float] = []
        rows = []  # (kind, x, y, speed, target speed, timer, delta)

        def create_random(speed: float | None, spacing: float, lane_id: int | None) -> tuple[float, float, float]:
            # _from and _to: choices among one road, which draw nothing; choice(lanes) is integers(0, lanes)
            _id = lane_id if lane_id is not None else rng.integers(0, lanes)
            if speed is None:
                speed = rng.uniform(0.7 * K.SPEED_LIMIT, 0.8 * K.SPEED_LIMIT)
            default_spacing = 12 + 1.0 * speed
            offset = spacing * default_spacing * np.exp(-5 / 40 * lanes)
            x0 = np.max(xs) if xs else 3 * offset
            x0 += offset * rng.uniform(0.9, 1.1)
            return float(x0), float(_id * K.LANE_WIDTH), speed

        x, y, sp = create_random(25.0, c["ego_spacing"], c["initial_lane_id"])
        xs.append(x)
        ys.append(y)
        ts = self.target_speeds
        idx = int(K.speed_to_index(sp, ts, len(ts)))
        rows.append((K.EGO, x, y, float(sp), float(ts[idx]), 0.0, 4.0, idx))
        for _ in range(int(c["vehicles_count"])):
            x, y, sp = create_random(None, 1 / c["vehicles_density"], None)
            timer = (np.sum(np.array([x, y])) * np.pi) % K.LANE_CHANGE_DELAY
            delta = rng.uniform(low=3.5, high=4.5)
            xs.append(x)
            ys.append(y)
            rows.append((K.IDM, x, y, float(sp), float(sp), float(timer), float(delta), 0))
        self._load(w, rows, seed)

    def _load(self, w: int, rows: list, seed: int | None) -> None:
        f, it = self.floats[w], self.ints[w]
        f[:] = 0.0
        it[:] = 0
        world = stream(seed, "world")
        n = 0
        for kind, x, y, sp, ts, timer, delta, idx in rows:
            f[n, K.FX], f[n, K.FY], f[n, K.FH], f[n, K.FS], f[n, K.FTS] = x, y, 0.0, sp, ts
            f[n, K.FTIMER], f[n, K.FDELTA] = timer, delta
            lane = K.closest_lane(x, y, 0.0, self.lanes)
            it[n, K.IKIND], it[n, K.ILANE], it[n, K.ITLANE], it[n, K.IHASTS] = kind, lane, lane, 1
            it[n, K.ISPEEDIDX] = idx
            n += 1
        self.counts[w] = n
        self.ids[w, 0], self.classes[w, 0] = 1, 0
        self._size(w, 0, *EGO_SIZE)
        self.colors[w, 0] = EGO_COLOR
        hazard_slots: list[int] = []
        if self.hazards is not None:
            hazard_slots = self._place_hazards(w, stream(seed, "hazards"))
        next_id = 2
        for k in range(1, self.counts[w]):
            next_id = self._assign(w, k, world, next_id)
        self.hazard_slots[w] = np.array(hazard_slots, np.int64)
        self.ticks[w] = 0
        self.start_position[w] = f[0, K.FX], f[0, K.FY]

    def _size(self, w: int, k: int, length: float, width: float, height: float) -> None:
        f = self.floats[w]
        f[k, K.FLEN], f[k, K.FWID], f[k, K.FDIAG] = length, width, math.hypot(length, width)
        self.heights[w, k] = height

    def _assign(self, w: int, k: int, rng: np.random.Generator, next_id: int) -> int:
        """fog-gym's class, size and colour of vehicle ``k`` (as ``TrafficWorld`` draws them, in road order)."""
        cls, size, color = draw_vehicle(rng)
        self.ids[w, k], self.classes[w, k] = next_id, cls
        self._size(w, k, *size)
        self.colors[w, k] = color
        return next_id + 1

    def _place_hazards(self, w: int, rng: np.random.Generator) -> list[int]:
        """:func:`fog_gym.world.hazards.place_hazards` on the arrays: remove traffic near each stalled vehicle,
        append it (speed 0, heading 0, class-default size until :meth:`_assign`)."""
        hz, f, it = self.hazards, self.floats[w], self.ints[w]
        ego_s = f[0, K.FX]  # lane.local_coordinates(ego.position)[0] on a straight lane of direction (1, 0)
        placed: list[int] = []
        d = float(rng.uniform(*hz.first))
        while d <= hz.span:
            lane = int(rng.integers(self.lanes))
            s = ego_s + d
            if s > K.LANE_LENGTH:
                break
            n = int(self.counts[w])
            keep = [k for k in range(n) if k == 0 or k in placed or not (
                abs(f[k, K.FX] - s) < hz.clearance and abs(f[k, K.FY] - lane * K.LANE_WIDTH) < K.LANE_WIDTH)]  # fmt: skip
            placed = [keep.index(k) for k in placed]
            f[: len(keep)] = f[keep]
            it[: len(keep)] = it[keep]
            n = len(keep)
            f[n] = 0.0
            it[n] = 0
            f[n, K.FX], f[n, K.FY] = s, lane * K.LANE_WIDTH
            f[n, K.FLEN], f[n, K.FWID], f[n, K.FDIAG] = 5.0, 2.0, math.sqrt(5.0**2 + 2.0**2)
            it[n, K.IKIND] = K.STALLED
            it[n, K.ILANE] = it[n, K.ITLANE] = K.closest_lane(s, lane * K.LANE_WIDTH, 0.0, self.lanes)
            placed.append(n)
            self.counts[w] = n + 1
            d += float(rng.uniform(*hz.gap))
        return placed

    # -- step -----------------------------------------------------------------------------------------
    def step(self, actions: np.ndarray, active: np.ndarray | None = None) -> None:
        """Advance every active world by one policy step with its ego's meta-action (0 lane left, 1 idle, 2 lane
        right, 3 faster, 4 slower)."""
        actions = np.ascontiguousarray(actions, np.int64).reshape(self.num_worlds)
        if actions.min(initial=0) < 0 or actions.max(initial=0) > 4:
            raise ValueError(f"actions must be meta-actions 0..4, got {actions.tolist()}")
        act = np.ones(self.num_worlds, np.bool_) if active is None else np.ascontiguousarray(active, np.bool_)
        launch(K.step_worlds)(act, self.floats, self.ints, self.counts, actions, self.frames, self.dt, self.lanes,
                      self.target_speeds, len(self.target_speeds), self.d0, self.cam, self.cmin)  # fmt: skip
        self.ticks[act] += self.frames

    # -- views ----------------------------------------------------------------------------------------
    def rewards(self, w: int) -> dict[str, float]:
        """highway-env's reward terms of world ``w``'s ego: collision, right lane, high speed, on road."""
        out = np.zeros(6)
        out[0], out[1] = self.config["reward_speed_range"]
        K.highway_rewards(self.floats[w], self.ints[w], self.lanes, out)
        return {"collision_reward": out[2], "right_lane_reward": out[3], "high_speed_reward": out[4],
                "on_road_reward": out[5]}  # fmt: skip

    def reward(self, w: int, rewards: dict[str, float] | None = None) -> float:
        """``HighwayEnv._reward`` of world ``w`` (weights and normalisation from the config); ``rewards``: its
        :meth:`rewards`, when the caller has them already."""
        c = self.config
        rewards = self.rewards(w) if rewards is None else rewards
        reward = sum(c.get(name, 0) * r for name, r in rewards.items())
        if c["normalize_reward"]:
            lo, hi = c["collision_reward"], c["high_speed_reward"] + c["right_lane_reward"]
            reward = 0 + (reward - lo) * (1 - 0) / (hi - lo)
        return float(reward * rewards["on_road_reward"])

    def ego_crashed(self, w: int) -> bool:
        return bool(self.ints[w, 0, K.ICRASH])

    def vehicle_arrays(self, w: int) -> tuple[np.ndarray, ...]:
        """(ids, classes, centres (N, 3), sizes (N, 3), yaws, velocities (N, 3), colours) of world ``w``, ego first."""
        n = int(self.counts[w])
        f = self.floats[w, :n]
        heading, speed = f[:, K.FH], f[:, K.FS]
        sizes = np.stack((f[:, K.FLEN], f[:, K.FWID], self.heights[w, :n]), axis=1)
        centers = np.stack((f[:, K.FX], f[:, K.FY], sizes[:, 2] / 2), axis=1)
        vel = np.stack((speed * np.cos(heading), speed * np.sin(heading), np.zeros(n)), axis=1)
        return (self.ids[w, :n].copy(), self.classes[w, :n].copy(), centers, sizes, heading.copy(), vel,
                self.colors[w, :n].copy())  # fmt: skip

    def hazards_ego(self, w: int) -> np.ndarray:
        """World ``w``'s stalled vehicles as :meth:`TrafficWorld.hazards_ego`: (K, 4) ahead, right, length, width."""
        slots = self.hazard_slots[w]
        if not len(slots):
            return np.zeros((0, 4))
        f = self.floats[w]
        d = f[slots][:, [K.FX, K.FY]] - f[0, [K.FX, K.FY]]
        c, s = math.cos(f[0, K.FH]), math.sin(f[0, K.FH])
        return np.c_[d[:, 0] * c + d[:, 1] * s, -d[:, 0] * s + d[:, 1] * c, f[slots][:, [K.FLEN, K.FWID]]]


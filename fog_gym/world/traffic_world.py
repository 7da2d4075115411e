"""The traffic world: a highway-env scenario whose vehicles carry FogDrive classes, sizes and stable ids.

highway-env drives the traffic (IDM/MOBIL on its road networks). This module adds what it lacks for 3D
sensing — per-vehicle class, height, colour and an id that is stable for the episode — keeps
highway-env's collision geometry equal to the rendered box, and steps the scenario without computing
highway-env's own observation (its Kinematics observation alone costs ≈6 ms).

Example:
    >>> world = TrafficWorld("roundabout", simulation_frequency=20, keyframe_frequency=10)
    >>> world.reset(seed=0)
    >>> state = world.vehicle_state()
    >>> int(state.ids[0]), int(state.classes[0])  # the ego is id 1, a passenger car
    (1, 0)
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from fog_gym.world.hazards import HazardConfig, place_hazards
from fog_gym.world.scenery import LaneGeometry
from fog_gym.world.towns import IDM_PROFILES, TOWN_SPECS, TOWNS, apply_idm_profile, check_traffic_mode, highway_env_config
from fog_gym.world.traffic.core import accelerate, is_accelerated
from fog_gym.seeds import stream
from fog_gym.world.fleet import EGO_COLOR, EGO_ID, EGO_SIZE, VehicleState, draw_vehicle


class TrafficWorld:
    """One highway-env scenario with FogDrive vehicle classes and stable ids.

    ``highway_config`` overrides highway-env config keys (``action``, ``vehicles_count``, …). ``traffic="fast"``
    steps it through :mod:`fog_gym.world.traffic` (identical trajectories); ``"reference"`` through highway-env alone.

    The world's surface — what the env, wrappers, audit and benchmarks use — is :meth:`reset`, :meth:`step`,
    :meth:`vehicle_state`, :meth:`lane_geometry`, :attr:`ego_pose`, :attr:`ego_speed`, :attr:`ego_crashed`,
    :attr:`tick`, :attr:`time`, :attr:`vehicle_count`, :attr:`accelerated`, :attr:`idm_profile`, :meth:`hazards_ego`,
    ``hazards``, ``action_space``,
    ``town``, ``spec``, ``traffic`` and ``start_position``. ``hw`` (the highway-env environment) is for this module
    and :mod:`fog_gym.world.traffic` only (``tests/test_world.py`` checks that nothing else reads it).
    """

    def __init__(
        self,
        town: str,
        simulation_frequency: int = 20,
        keyframe_frequency: int = 10,
        episode_seconds: float = 20.0,
        highway_config: dict[str, Any] | None = None,
        traffic: str = "fast",
        hazards: HazardConfig | None = None,
    ) -> None:
        import highway_env.envs as hw_envs  # noqa: F401  (registers highway-env and its vehicle classes)

        if town not in TOWN_SPECS:
            raise ValueError(f"town must be one of {TOWNS}, got {town!r}")
        self.traffic = check_traffic_mode(traffic)
        if hazards is not None and not isinstance(hazards, HazardConfig):
            raise ValueError(f"hazards must be a HazardConfig or None, got {type(hazards).__name__}")
        self.hazards = hazards
        self._hazard_vehicles: list[Any] = []  # the episode's stalled vehicles (highway-env objects)
        self.town = town
        self.spec = TOWN_SPECS[town]
        self.idm_profile: dict[str, float] = dict(IDM_PROFILES[self.spec.idm])
        config = highway_env_config(town, simulation_frequency, keyframe_frequency, highway_config)
        self.episode_seconds = float(episode_seconds)
        self._apply_idm_profile()
        self.hw = getattr(hw_envs, self.spec.env_class)(config=config)
        if traffic == "fast":
            accelerate(self.hw)
        self.action_space = self.hw.action_space
        self._rng = np.random.default_rng(0)
        self._next_id = EGO_ID + 1

    # -- highway-env plumbing -------------------------------------------------------------------------
    def _apply_idm_profile(self) -> None:
        apply_idm_profile(self.town)

    def _skip_observation(self) -> None:
        # FogDrive-v0 never uses highway-env's observation: make it free on the hot path.
        self.hw.observation_type.observe = lambda: None

    def reset(self, seed: int | None = None) -> None:
        """Reset the scenario; ``seed`` determines traffic, classes, sizes and colours."""
        self._apply_idm_profile()
        self.hw.observation_type.observe = lambda: None  # reset also observes once; define_spaces replaces it
        self.hw.reset(seed=seed)
        self._skip_observation()
        self.action_space = self.hw.action_space
        self._rng = stream(seed, "world")
        self._next_id = EGO_ID + 1
        ego = self.hw.vehicle
        self._assign(ego, is_ego=True)
        self._hazard_vehicles = ([] if self.hazards is None else
                                 place_hazards(self.hw.road, ego, self.hazards, stream(seed, "hazards")))
        self._register_new()
        self.start_position = np.array(ego.position, dtype=np.float64)

    def step(self, action: Any) -> tuple[float, bool, dict]:
        """Advance one keyframe (``simulation_frequency / keyframe_frequency`` sub-steps)."""
        self._apply_idm_profile()
        _, reward, terminated, _, info = self.hw.step(action)
        self._register_new()
        terminated = bool(terminated) or bool(self.hw.vehicle.crashed)
        return float(reward), terminated, info

    # -- vehicles -------------------------------------------------------------------------------------
    def _assign(self, v: Any, is_ego: bool = False) -> None:
        if is_ego:
            vid, cls, (length, width, height), color = EGO_ID, 0, EGO_SIZE, EGO_COLOR
        else:
            vid = self._next_id
            self._next_id += 1
            cls, (length, width, height), color = draw_vehicle(self._rng)
        v._fog_id = vid
        v._fog_class = cls
        v._fog_height = height
        v._fog_color = color
        # highway-env's collision geometry equals the rendered box (maintainer's recipe, #490)
        v.LENGTH, v.WIDTH = length, width
        v.diagonal = math.hypot(length, width)

    def hazards_ego(self) -> np.ndarray:
        """The stalled vehicles in placement order (nearest first at the reset), (K, 4): their centres' offsets from
        the ego's centre in its frame (metres ahead, metres to the right, CARLA convention), length and width;
        (0, 4) without hazards."""
        if not self._hazard_vehicles:
            return np.zeros((0, 4))
        ego = self.hw.vehicle
        vs = self._hazard_vehicles
        d = np.array([v.position for v in vs], np.float64) - np.asarray(ego.position, np.float64)
        c, s = math.cos(ego.heading), math.sin(ego.heading)
        size = np.array([(v.LENGTH, v.WIDTH) for v in vs], np.float64)
        return np.c_[d[:, 0] * c + d[:, 1] * s, -d[:, 0] * s + d[:, 1] * c, size]

    def _register_new(self) -> None:
        for v in self.hw.road.vehicles:
            if not hasattr(v, "_fog_id"):
                self._assign(v)

    def vehicles(self) -> list[Any]:
        """highway-env vehicles, ego first."""
        ego = self.hw.vehicle
        return [ego] + [v for v in self.hw.road.vehicles if v is not ego]

    def vehicle_state(self) -> VehicleState:
        vs = self.vehicles()
        n = len(vs)
        ids = np.fromiter((v._fog_id for v in vs), np.int32, n)
        classes = np.fromiter((v._fog_class for v in vs), np.int8, n)
        xy = np.array([v.position for v in vs], dtype=np.float64).reshape(n, 2)
        heading = np.fromiter((v.heading for v in vs), np.float64, n)
        speed = np.fromiter((v.speed for v in vs), np.float64, n)
        sizes = np.array([(v.LENGTH, v.WIDTH, v._fog_height) for v in vs], dtype=np.float64).reshape(n, 3)
        centers = np.c_[xy, sizes[:, 2] / 2]
        vel = np.c_[speed * np.cos(heading), speed * np.sin(heading), np.zeros(n)]
        colors = np.array([v._fog_color for v in vs], dtype=np.float64).reshape(n, 3)
        return VehicleState(ids, classes, centers, sizes, heading, vel, colors)

    @property
    def ego_pose(self) -> tuple[float, float, float]:
        """(x, y, yaw) of the ego origin: the ground point under its centre, and its heading."""
        v = self.hw.vehicle
        return float(v.position[0]), float(v.position[1]), float(v.heading)

    @property
    def time(self) -> float:
        """Simulated seconds since the reset."""
        return float(self.hw.time)

    @property
    def tick(self) -> int:
        """Simulation sub-steps since the reset (``simulation_frequency`` per second)."""
        return int(self.hw.steps)

    @property
    def ego_speed(self) -> float:
        """The ego's speed [m/s]."""
        return float(self.hw.vehicle.speed)

    @property
    def ego_crashed(self) -> bool:
        """Whether the ego has collided in this episode."""
        return bool(self.hw.vehicle.crashed)

    @property
    def vehicle_count(self) -> int:
        """Vehicles on the road, the ego included."""
        return len(self.hw.road.vehicles)

    @property
    def accelerated(self) -> bool:
        """Whether the traffic steps through :mod:`fog_gym.world.traffic`'s core."""
        return is_accelerated(self.hw)

    # -- road geometry --------------------------------------------------------------------------------
    def lane_geometry(self, center: np.ndarray, radius: float, step: float = 1.0) -> list[LaneGeometry]:
        """Every lane sampled every ``step`` metres, restricted to a square of half-size ``radius`` around ``center``."""
        lanes = []
        for lane in self.hw.road.network.lanes_list():
            length = float(lane.length)
            coarse = np.linspace(0.0, length, max(2, int(length // 20.0) + 2))
            cp = np.array([lane.position(s, 0.0) for s in coarse])
            near = np.all(np.abs(cp - center) <= radius + 25.0, axis=1)
            if not near.any():
                continue
            idx = np.flatnonzero(near)
            s0 = coarse[max(idx[0] - 1, 0)]
            s1 = coarse[min(idx[-1] + 1, len(coarse) - 1)]
            s = np.linspace(s0, s1, max(2, int(np.ceil((s1 - s0) / step)) + 1))
            if type(lane).__name__ == "StraightLane":  # vectorised: start + s·direction + r·lateral
                width = np.full(len(s), float(lane.width_at(0.0)))
                c = lane.start[None, :] + s[:, None] * lane.direction[None, :]
                lat = lane.direction_lateral[None, :] * (width[:, None] / 2)
                left, right = c - lat, c + lat
            else:
                width = np.array([lane.width_at(x) for x in s])
                c = np.array([lane.position(x, 0.0) for x in s])
                left = np.array([lane.position(x, -w / 2) for x, w in zip(s, width)])
                right = np.array([lane.position(x, w / 2) for x, w in zip(s, width)])
            lanes.append(LaneGeometry(s, c, left, right, tuple(int(t) for t in lane.line_types)))
        return lanes

    def close(self) -> None:
        self.hw.close()


class NativeTrafficWorld:
    """The highway town on the native array core (:class:`~fog_gym.world.traffic.native.NativeTraffic`), with
    :class:`TrafficWorld`'s surface: same seeds, trajectories (≤ 1e-9 m), rewards, classes, ids and hazards.

    ``core`` and ``index``: a world of a shared core (a vector env steps all its worlds in one call, then each
    sub-env's :meth:`step` finds its world already stepped with its action); by default the world owns a core of
    one world and steps it itself. ``vehicles()`` (highway-env objects) does not exist here.
    """

    traffic = "native"

    def __init__(self, town: str = "highway", simulation_frequency: int = 20, keyframe_frequency: int = 10,
                 episode_seconds: float = 20.0, highway_config: dict[str, Any] | None = None,
                 hazards: HazardConfig | None = None, core: Any = None, index: int = 0) -> None:  # fmt: skip
        from gymnasium import spaces

        from fog_gym.world.traffic.native import NativeTraffic

        if town != "highway":
            raise ValueError(f"traffic='native' drives the highway town only (straight lanes), got town {town!r}; "
                             "use traffic='fast'")  # fmt: skip
        self.town = town
        self.spec = TOWN_SPECS[town]
        self.idm_profile = dict(IDM_PROFILES[self.spec.idm])
        self.episode_seconds = float(episode_seconds)
        self.core = core if core is not None else NativeTraffic(1, highway_config, hazards, simulation_frequency,
                                                                keyframe_frequency)  # fmt: skip
        self.index = int(index)
        self.hazards = self.core.hazards
        self.simulation_frequency = int(self.core.config["simulation_frequency"])
        self.action_space = spaces.Discrete(5)
        self.start_position = np.zeros(2)
        self._pending: int | None = None  # the action a shared core already stepped this world with

    def reset(self, seed: int | None = None) -> None:
        self.core.reset(self.index, seed)
        self.start_position = self.core.start_position[self.index].copy()
        self._pending = None

    def pre_stepped(self, action: int) -> None:
        """Tell the world its core already advanced it with ``action`` (a vector env's batched step)."""
        self._pending = int(action)

    def step(self, action: Any) -> tuple[float, bool, dict]:
        a = int(action)
        if not self.action_space.contains(a):
            raise ValueError(f"action must be a meta-action 0..4, got {action!r}")
        if self._pending is None:
            actions = np.ones(self.core.num_worlds, np.int64)
            actions[self.index] = a
            active = np.zeros(self.core.num_worlds, bool)
            active[self.index] = True
            self.core.step(actions, active)
        elif self._pending != a:
            raise RuntimeError(f"world {self.index} was stepped with action {self._pending}, not {a}")
        self._pending = None
        w = self.index
        rewards = self.core.rewards(w)
        info = {"speed": self.ego_speed, "crashed": self.ego_crashed, "action": a, "rewards": rewards}
        return self.core.reward(w, rewards), self.ego_crashed, info

    def vehicle_state(self) -> VehicleState:
        return VehicleState(*self.core.vehicle_arrays(self.index))

    def hazards_ego(self) -> np.ndarray:
        return self.core.hazards_ego(self.index)

    @property
    def ego_pose(self) -> tuple[float, float, float]:
        f = self.core.floats[self.index, 0]
        return float(f[0]), float(f[1]), float(f[2])

    @property
    def time(self) -> float:
        return float(self.core.ticks[self.index] / self.simulation_frequency)

    @property
    def tick(self) -> int:
        return int(self.core.ticks[self.index])

    @property
    def ego_speed(self) -> float:
        return float(self.core.floats[self.index, 0, 3])

    @property
    def ego_crashed(self) -> bool:
        return self.core.ego_crashed(self.index)

    @property
    def vehicle_count(self) -> int:
        return int(self.core.counts[self.index])

    @property
    def accelerated(self) -> bool:
        return True

    def lane_geometry(self, center: np.ndarray, radius: float, step: float = 1.0) -> list[LaneGeometry]:
        """The straight lanes (0, 4 i) → (10 000, 4 i) sampled every ``step`` metres near ``center``."""
        from fog_gym.world.traffic import kernels as K

        x0 = max(0.0, float(center[0]) - radius - 25.0)
        x1 = min(K.LANE_LENGTH, float(center[0]) + radius + 25.0)
        lanes = []
        for i in range(self.core.lanes):
            y = i * K.LANE_WIDTH
            if abs(y - float(center[1])) > radius + 25.0 or x1 <= x0:
                continue
            line_types = (3 if i == 0 else 1, 3 if i == self.core.lanes - 1 else 0)  # highway-env's straight_road_network
            s = np.linspace(x0, x1, max(2, int(np.ceil((x1 - x0) / step)) + 1))
            c = np.c_[s, np.full(len(s), y)]
            half = np.array([0.0, K.LANE_WIDTH / 2])
            lanes.append(LaneGeometry(s, c, c - half, c + half, line_types))
        return lanes

    def close(self) -> None:
        pass


def make_world(town: str, simulation_frequency: int = 20, keyframe_frequency: int = 10, episode_seconds: float = 20.0,
               highway_config: dict[str, Any] | None = None, traffic: str = "fast",
               hazards: HazardConfig | None = None) -> TrafficWorld | NativeTrafficWorld:  # fmt: skip
    """The world of a town on the traffic core ``traffic`` ("fast", "reference": highway-env's objects; "native": the
    array core, highway town only)."""
    check_traffic_mode(traffic)
    if traffic == "native":
        return NativeTrafficWorld(town, simulation_frequency, keyframe_frequency, episode_seconds, highway_config,
                                  hazards)  # fmt: skip
    return TrafficWorld(town, simulation_frequency, keyframe_frequency, episode_seconds, highway_config, traffic, hazards)

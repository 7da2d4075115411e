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

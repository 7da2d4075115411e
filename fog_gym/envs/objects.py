"""The RL presets with the perceived-objects observation: N worlds in arrays (:class:`ObjectWorlds`), one as a
Gymnasium env (:class:`FogDriveObjectsEnv`), N as a vector env (:class:`fog_gym.envs.vector.FogDriveVectorEnv`).

A world is the preset's highway traffic on the native core (:mod:`fog_gym.world.traffic.native`), its fog level and
its episode's seeds; an observation is what the fogged sensors detect (:mod:`fog_gym.perception.objects`). Seeds
follow ``FogDriveEnv``: ``reset(seed=s)`` seeds the world's generator, the episode seed is its first draw, the
traffic, hazards, vehicle classes, lighting and every detection draw derive from it; an unseeded reset continues
the generator. Fog changes with :meth:`FogDriveObjectsEnv.set_fog` from the next reset, as the fog wrapper's.

Example:
    >>> import gymnasium as gym, fog_gym
    >>> env = gym.make("FogDriveRLHazard-v0", observation="objects", fog="dense")
    >>> obs, info = env.reset(seed=0)
    >>> obs.shape, obs.dtype, sorted(info["detections"])
    ((8, 9), dtype('float32'), ['camera', 'fused', 'lidar', 'radar'])
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding

from fog_gym._numba import launch
from fog_gym.envs import batched as B
from fog_gym.fog.banks import BankConfig, bank_rng
from fog_gym.fog.fields import along_axis, field_info
from fog_gym.fog.lidar import BETA_PER_MOR, GAMMA, soft_response_table
from fog_gym.fog.lidar_field import FIELD_COARSE, FIELD_STEP, field_pulse_weights, peak_extinction
from fog_gym.fog.physics import FogField, FogLevel, parse_fog
from fog_gym.perception import objects as PO
from fog_gym.seeds import stream
from fog_gym.channels.packing import pad_rows
from fog_gym.world.hazards import HazardConfig, hazard_info
from fog_gym.world.scene import Lighting, town_static_world
from fog_gym.world.scenery import SURFACE_RGB
from fog_gym.world.traffic import kernels as K
from fog_gym.world.traffic.native import NativeTraffic
from fog_gym.world.traffic_world import NativeTrafficWorld

SKY_HORIZON = np.array([205.0, 218.0, 232.0])  # the day sky's horizon colour (Lighting.for_time_of_day)
#: The most packed rows a world's fog field may have (a bank over ground fog over homogeneous fog is three).
MAX_FIELD_ROWS = 4


def parse_objects_fog(fog: Any) -> FogField:
    """A fog level or field for the perceived objects (:func:`~fog_gym.fog.physics.parse_fog`), with at most
    :data:`MAX_FIELD_ROWS` packed rows; bad values fail here, naming the problem."""
    level = parse_fog(fog)
    if not level.is_homogeneous and len(level.pack(0.0)) > MAX_FIELD_ROWS:
        raise ValueError(f"fog: the perceived objects take fields of at most {MAX_FIELD_ROWS} terms, got {level!r}")
    return level


def _luma(rgb: np.ndarray) -> np.ndarray:
    return 0.2126 * rgb[..., 0] + 0.7152 * rgb[..., 1] + 0.0722 * rgb[..., 2]


class ObjectWorlds:
    """``num_worlds`` worlds of an RL preset with the perceived-objects observation, stepped together.

    ``highway_config`` and ``hazards`` define the traffic (the preset's), ``fog`` the initial level of every world,
    ``episode_seconds`` the truncation, ``objects`` the detection rig (:class:`~fog_gym.perception.objects.ObjectsConfig`).
    """

    def __init__(self, num_worlds: int, highway_config: Mapping[str, Any], hazards: HazardConfig | None, fog: Any,
                 objects: PO.ObjectsConfig, episode_seconds: float = 20.0, keyframe_frequency: int = 5,
                 simulation_frequency: int = 20, surface_resolution: float = 0.1, banks: Any = None) -> None:  # fmt: skip
        if banks is not None and not isinstance(banks, BankConfig):
            raise ValueError(f"banks must be a fog_gym.fog.banks.BankConfig, got {banks!r}")
        first = parse_objects_fog(fog)
        self.core = NativeTraffic(num_worlds, highway_config, hazards, simulation_frequency, keyframe_frequency)
        self.n = num_worlds
        self.objects = objects
        self.keyframe_frequency = keyframe_frequency
        self.episode_steps = int(round(episode_seconds * keyframe_frequency))
        self.levels: list[FogField] = [first] * num_worlds
        self.pending: list[FogField | None] = [None] * num_worlds
        #: A fog bank per episode (FogDriveRLFogBank-v0): each world draws its own from its reset's seed.
        self.banks = banks
        self._bank_rngs: list[np.random.Generator | None] = [None] * num_worlds
        self.np_random = [seeding.np_random(None)[0] for _ in range(num_worlds)]
        self.episode_seed = np.zeros(num_worlds, np.int64)
        self.keys = np.zeros(num_worlds, np.uint64)
        self.steps = np.zeros(num_worlds, np.int64)
        self.suns = np.zeros((num_worlds, 3))
        self.shades = np.zeros((num_worlds, 3))
        v = self.core.capacity
        self.present = np.zeros((num_worlds, v, 4), np.bool_)
        self.pos = np.zeros((num_worlds, v, 4, 2))
        self.vel = np.zeros((num_worlds, v, 4, 2))
        self.prev_present = np.zeros((num_worlds, v, 4), np.bool_)
        self.prev_pos = np.zeros((num_worlds, v, 4, 2))
        self.prev_vel = np.zeros((num_worlds, v, 4, 2))
        self.obs = np.zeros((num_worlds, *objects.shape), np.float32)
        self.alphas = np.zeros(num_worlds)
        self.beta_ratios = np.zeros(num_worlds)
        self.tables_i = np.zeros((num_worlds, 101))
        self.tables_r = np.zeros((num_worlds, 101))
        # fog fields (a world with rows > 0): packed terms, the field frame (the ego at reset) and the peak extinction
        self.fterms = np.zeros((num_worlds, MAX_FIELD_ROWS, 8))
        self.frows = np.zeros(num_worlds, np.int64)
        self.fframes = np.zeros((num_worlds, 3))
        self.fbeta = np.zeros(num_worlds)
        self.fdrift = np.zeros(num_worlds, np.bool_)  # a drifting bank: its terms are packed anew every step
        self._pulse = (np.zeros((1, 1)), np.zeros(1), np.zeros((1, 1)), np.zeros(1))  # (the weights, with a field)
        static = town_static_world(NativeTrafficWorld("highway", core=self.core), "highway",
                                   self.core.lanes, surface_resolution, 1050.0)  # fmt: skip
        s = static.surface
        self._grid = np.ascontiguousarray(s.grid, np.uint8)
        self._ground = (float(s.origin[0]), float(s.origin[1]), float(s.resolution))
        self._surf_luma = _luma(SURFACE_RGB)
        o = objects
        self._elev = o.lidar_elevations()
        az = np.arange(o.lidar_beams) * (2.0 * np.pi / o.lidar_beams) - np.pi
        self._az_cos, self._az_sin = np.cos(az), np.sin(az)
        self._drop = np.array([0.45, 0.8, 0.4])  # CARLA's LiDAR drop-off defaults (LidarConfig)
        self._cam = np.array([o.camera_pose[0], o.camera_pose[1], o.camera_focal, o.camera_size[0], o.camera_size[1],
                              o.camera_range])  # fmt: skip
        self._rad = np.array([o.radar_pose[0], o.radar_pose[1], o.radar_range, math.radians(o.radar_fov[0]),
                              math.radians(o.radar_fov[1]), o.radar_rays])  # fmt: skip
        self._rules = np.array([o.min_points, o.min_pixels, o.min_contrast, PO.LAYOUTS.index(o.layout), o.max_rays,
                                float(o.lidar_returns == "last")],
                               np.float64)  # fmt: skip
        self._mask = o.sensor_mask
        self._fog_infos: list[dict[str, Any]] = [{}] * num_worlds
        self._fog_batch: dict[str, Any] | None = None  # the fog infos of every world, batched (until a level changes)
        for w in range(num_worlds):
            self._set_level(w, self.levels[w])
        hz = self.core.hazards
        self._hazard_slots = np.full((num_worlds, 0 if hz is None else hz.capacity), -1, np.int64)
        cfg = self.core.config
        self._reward_args = (float(cfg["reward_speed_range"][0]), float(cfg["reward_speed_range"][1]),
                             np.array([float(cfg.get(k, 0)) for k in B.REWARD_TERMS]), bool(cfg["normalize_reward"]),
                             float(cfg["collision_reward"]), float(cfg["high_speed_reward"] + cfg["right_lane_reward"]))  # fmt: skip

    # -- fog ------------------------------------------------------------------------------------------
    def _set_level(self, w: int, level: FogField) -> None:
        self.levels[w] = level
        self._fog_infos[w] = level.info() if isinstance(level, FogLevel) else field_info(level)
        self._fog_batch = None
        self.frows[w] = 0
        self.fdrift[w] = False
        if not level.is_homogeneous:  # a fog field: closed-form τ on every ray, the soft return beam by beam
            terms = level.pack(0.0)
            self.fterms[w, : len(terms)] = terms
            self.frows[w] = len(terms)
            self.fdrift[w] = any(getattr(t, "velocity", 0.0) for t in getattr(level, "terms", (level,)))
            self.fbeta[w] = peak_extinction(terms)
            if self._pulse[0].shape[0] == 1:
                self._pulse = (*field_pulse_weights(), *field_pulse_weights(FIELD_STEP * FIELD_COARSE))
            self.alphas[w], self.beta_ratios[w] = 0.0, 0.0
            self.tables_i[w] = self.tables_r[w] = 0.0
            return
        if not isinstance(level, FogLevel):  # (a sum of homogeneous terms)
            level = parse_fog(level.visibility_m)
        self.alphas[w] = level.alpha
        if level.is_clear:
            self.beta_ratios[w] = 0.0
            self.tables_i[w] = 0.0
            self.tables_r[w] = 0.0
        else:
            ti, tr = soft_response_table(level.alpha)
            self.tables_i[w], self.tables_r[w] = ti, tr
            self.beta_ratios[w] = BETA_PER_MOR / level.visibility_m / (GAMMA / math.pi)

    def observation(self, w: int | slice = slice(None)) -> np.ndarray:
        """A copy of world ``w``'s observation (or every world's), in the config's :attr:`observation_shape`."""
        obs = self.obs[w]
        lead = obs.shape[: obs.ndim - 2]
        return obs.reshape(*lead, *self.objects.observation_shape).copy()

    def set_fog(self, w: int, fog: Any) -> None:
        """World ``w``'s fog (a level or a fog field) from its next reset on."""
        self.pending[w] = parse_objects_fog(fog)

    # -- episodes -------------------------------------------------------------------------------------
    def reset(self, w: int, seed: int | None = None) -> None:
        """Start a new episode in world ``w`` (seeded, or continuing its generator)."""
        self.reset_many([w], [seed])

    def reset_many(self, worlds: list[int], seeds: list[int | None], perceive: bool = True) -> None:
        """Start new episodes in several worlds, perceived in one call (``perceive=False``: by the caller's next
        :meth:`step`, with ``also=`` these worlds)."""
        active = np.zeros(self.n, bool)
        for w, seed in zip(worlds, seeds):
            if seed is not None:
                self.np_random[w] = seeding.np_random(seed)[0]
            if self.banks is not None:  # the episode's bank, from the reset's seed (as FogBankEpisodes draws it)
                if seed is not None or self._bank_rngs[w] is None:
                    self._bank_rngs[w] = bank_rng(seed)
                self.pending[w] = self.banks.draw(self._bank_rngs[w])
            if self.pending[w] is not None:
                self._set_level(w, self.pending[w])
                self.pending[w] = None
            world_seed = int(self.np_random[w].integers(0, 2**31 - 1))
            self.episode_seed[w] = world_seed
            self.core.reset(w, world_seed)
            if self._hazard_slots.shape[1]:
                slots = self.core.hazard_slots[w][: self._hazard_slots.shape[1]]
                self._hazard_slots[w] = -1
                self._hazard_slots[w, : len(slots)] = slots
            ego = self.core.floats[w, 0]
            self.fframes[w] = ego[K.FX], ego[K.FY], ego[K.FH]  # the field frame: the ego (and its LiDAR) at reset
            light = Lighting.for_time_of_day("day", stream(world_seed, "scenery"))
            self.suns[w] = light.sun_dir
            self.shades[w] = light.ambient, light.sun_intensity, light.ground_shade
            self.keys[w] = np.random.SeedSequence([world_seed, 0x0B5]).generate_state(1, np.uint64)[0]
            self.steps[w] = 0
            self.prev_present[w] = False
            active[w] = True
        if perceive:
            self._perceive(active)

    def step(self, actions: np.ndarray, active: np.ndarray, also: np.ndarray | None = None) -> None:
        """Step the ``active`` worlds and perceive them (with ``also``: worlds just reset without perceiving, in the
        same call)."""
        self.core.step(actions, active)
        self.steps[active] += 1
        for w in np.flatnonzero(active & self.fdrift):  # a drifting bank moves with the episode's time
            self.fterms[w, : self.frows[w]] = self.levels[w].pack(self.steps[w] / self.keyframe_frequency)
        self._perceive(active if also is None else active | also)

    def _perceive(self, active: np.ndarray) -> None:
        c = self.core
        launch(PO.perceive_worlds)(active, c.floats, c.counts, c.classes, c.colors, c.heights, self.keys, c.ticks,
                           self.alphas, self.beta_ratios, self.tables_i, self.tables_r, self.suns, self.shades,
                           float(_luma(SKY_HORIZON)), self._grid, *self._ground, self._surf_luma, self._elev,
                           self._az_cos, self._az_sin, self.objects.lidar_range, self.objects.lidar_height, self._drop,
                           self._cam, self._rad, self._mask, self._rules, 1.0 / self.keyframe_frequency, c.lanes,
                           self.present, self.pos, self.vel, self.prev_present, self.prev_pos, self.prev_vel,
                           self.obs, self.fterms, self.frows, self.fframes, self.fbeta, *self._pulse)  # fmt: skip

    # -- every world at once (fog_gym.envs.batched) --------------------------------------------------------
    def rewards(self, active: np.ndarray) -> np.ndarray:
        """:meth:`NativeTraffic.reward` of every active world (0 elsewhere)."""
        c = self.core
        return B.batch_rewards(c.floats, c.ints, c.lanes, *self._reward_args, active, np.zeros(self.n))

    def terminations(self) -> np.ndarray:
        return self.core.ints[:, 0, K.ICRASH] != 0

    def truncations(self) -> np.ndarray:
        return (self.steps >= self.episode_steps) & ~self.terminations()

    def batched_infos(self, mask: np.ndarray, detections: bool = True) -> dict[str, Any]:
        """The infos Gymnasium's ``_add_info`` builds from :meth:`info` of each world in ``mask`` (in world order),
        assembled from arrays over all worlds (see :mod:`fog_gym.envs.batched`)."""
        c = self.core
        out: dict[str, Any] = {}
        B.put(out, "speed", c.floats[:, 0, K.FS], mask, np.float64)
        B.put(out, "crashed", self.terminations(), mask, np.bool_)
        if mask.all():  # the fog's descriptions change only at resets: batched once per change
            if self._fog_batch is None:
                self._fog_batch = B.add_infos({}, {w: {"fog": self._fog_infos[w]} for w in range(self.n)}, self.n)
            out.update(B.copy_infos(self._fog_batch))
        else:
            out.update(B.add_infos({}, {w: {"fog": self._fog_infos[w]} for w in np.flatnonzero(mask)}, self.n))
        B.put(out, "step", self.steps, mask, np.int64)
        fields = np.flatnonzero(mask & (self.frows > 0))
        if len(fields):  # where each ego stands in its fog field
            u = np.zeros(self.n)
            for w in fields:
                u[w] = along_axis(self.fframes[w], c.floats[w, 0, K.FX], c.floats[w, 0, K.FY])
            B.put(out, "fog_u", u, mask & (self.frows > 0), np.float64)
        if c.hazards is not None:
            rows = np.zeros((self.n, c.hazards.capacity, 4))
            counts = B.batch_hazards(c.floats, self._hazard_slots, rows)
            B.put(out, "hazards", rows, mask, np.float64)
            B.put(out, "hazard_count", counts, mask, np.int64)
        if detections:
            det: dict[str, Any] = {}
            cap = c.capacity
            for s, name in ((PO.CAM, "camera"), (PO.LID, "lidar"), (PO.RAD, "radar"), (PO.FUSED, "fused")):
                if name != "fused" and name not in self.objects.sensors:
                    continue
                count, ids = np.zeros(self.n, np.int64), np.empty((self.n, cap), np.int64)
                pos, true, dist = np.empty((self.n, cap, 2)), np.empty((self.n, cap, 2)), np.empty((self.n, cap))
                B.batch_detections(c.floats, c.counts, c.ids, self.present, self.pos, s, count, ids, pos, true, dist)
                one: dict[str, Any] = {}
                for key, arr, dtype in (("count", count, np.int64), ("vehicle_ids", ids, np.int64),
                                        ("position", pos, np.float64), ("true_position", true, np.float64),
                                        ("distance", dist, np.float64)):  # fmt: skip
                    B.put(one, key, arr, mask, dtype)
                det[name], det[f"_{name}"] = one, mask.copy()
            out["detections"], out["_detections"] = det, mask.copy()
        return out

    # -- per-world results ----------------------------------------------------------------------------
    def terminated(self, w: int) -> bool:
        return self.core.ego_crashed(w)

    def truncated(self, w: int) -> bool:
        return bool(self.steps[w] >= self.episode_steps) and not self.terminated(w)

    def info(self, w: int, detections: bool = True) -> dict[str, Any]:
        c = self.core
        level = self.levels[w]
        info: dict[str, Any] = {"speed": float(c.floats[w, 0, K.FS]), "crashed": c.ego_crashed(w),
                                "fog": level.info() if isinstance(level, FogLevel) else field_info(level),
                                "step": int(self.steps[w])}  # fmt: skip
        if self.frows[w] > 0:  # where the ego stands in its fog field: the distance along the field's axis [m]
            info["fog_u"] = along_axis(self.fframes[w], c.floats[w, 0, K.FX], c.floats[w, 0, K.FY])
        if c.hazards is not None:
            info.update(hazard_info(c.hazards_ego(w), c.hazards))
        if detections:
            info["detections"] = self.detections(w)
        return info

    def detections(self, w: int) -> dict[str, dict[str, np.ndarray]]:
        """Per sensor of the rig and ``"fused"``: ``count`` (vehicles detected), then one row per detected vehicle in
        fixed arrays of the world's vehicle capacity (rows after ``count``: id −1, zeros): ``vehicle_ids``, ``position``
        (reported x, y, ego frame), ``true_position`` (their true centres, ego frame) and ``distance`` (true, from the
        ego's centre) [m]."""
        c = self.core
        n = int(c.counts[w])
        f = c.floats[w, :n]
        ex, ey, eh = f[0, K.FX], f[0, K.FY], f[0, K.FH]
        d = f[:, [K.FX, K.FY]] - (ex, ey)
        cs, sn = math.cos(eh), math.sin(eh)
        true = np.c_[d[:, 0] * cs + d[:, 1] * sn, -d[:, 0] * sn + d[:, 1] * cs]
        out = {}
        for s, name in ((PO.CAM, "camera"), (PO.LID, "lidar"), (PO.RAD, "radar"), (PO.FUSED, "fused")):
            if name != "fused" and name not in self.objects.sensors:
                continue
            slots = np.flatnonzero(self.present[w, :n, s])
            cap = c.capacity
            out[name] = {"count": len(slots), "vehicle_ids": pad_rows(c.ids[w, slots].astype(np.int64), cap, -1),
                         "position": pad_rows(self.pos[w, slots, s], cap), "true_position": pad_rows(true[slots], cap),
                         "distance": pad_rows(np.hypot(true[slots, 0], true[slots, 1]), cap)}  # fmt: skip
        return out


class FogDriveObjectsEnv(gym.Env):
    """One world of :class:`ObjectWorlds` as a Gymnasium env (what ``gym.make(<RL preset>, observation="objects")``
    returns). Observation: ``Box(-1, 1, (max_objects, 6 + len(sensors)), float32)`` (``layout="lanes"``: ``(4, 5)``);
    actions, reward, termination and truncation as the preset's; ``info``: speed, crashed, fog, step, hazards and
    hazard_count (hazard preset), fog_u (in a fog field: the ego's distance along the field's axis), detections
    (unless ``info_detections=False``: the fastest training loop).

    ``worlds`` and ``index`` make it a view of world ``index`` of a shared :class:`ObjectWorlds` (the native vector
    env's sub-envs, for ``get_attr`` / ``set_attr`` / ``call``); it then reads the world's state and draws on its
    generator, and the vector env steps all worlds at once."""

    metadata = {"render_modes": [], "render_fps": 5}

    def __init__(self, highway_config: Mapping[str, Any] | None = None, hazards: HazardConfig | None = None,
                 fog: Any = "clear", objects: PO.ObjectsConfig | None = None, episode_seconds: float = 20.0,
                 info_detections: bool = True, worlds: ObjectWorlds | None = None, index: int = 0,
                 banks: Any = None) -> None:  # fmt: skip
        if not isinstance(info_detections, bool):
            raise ValueError(f"info_detections must be True or False, got {info_detections!r}")
        if worlds is None:
            self.objects = objects if objects is not None else PO.ObjectsConfig()
            worlds = ObjectWorlds(1, highway_config or {}, hazards, fog, self.objects, episode_seconds, banks=banks)
        self.objects = worlds.objects
        self.worlds, self.index = worlds, int(index)
        self.info_detections = info_detections
        self.observation_space = spaces.Box(-1.0, 1.0, self.objects.observation_shape, np.float32)
        self.action_space = spaces.Discrete(5)
        self._started = False

    @property
    def np_random(self) -> np.random.Generator:
        """The world's generator (its reset draws the episode seed from it)."""
        return self.worlds.np_random[self.index]

    @np_random.setter
    def np_random(self, value: np.random.Generator) -> None:
        self.worlds.np_random[self.index] = value

    @property
    def episode_seed(self) -> int:
        return int(self.worlds.episode_seed[self.index])

    @property
    def fog(self) -> FogLevel:
        return self.worlds.levels[self.index]

    def set_fog(self, fog: Any) -> None:
        """Change the fog from the next ``reset`` on (curricula)."""
        self.worlds.set_fog(self.index, fog)

    @property
    def next_fog(self) -> FogLevel | None:
        return self.worlds.pending[self.index]

    @next_fog.setter
    def next_fog(self, fog: Any) -> None:
        if fog is not None:
            self.set_fog(fog)

    def info(self) -> dict[str, Any]:
        """The world's current ``info`` (what ``reset`` and ``step`` return)."""
        return self.worlds.info(self.index, self.info_detections)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        self.worlds.reset(self.index, seed)
        if seed is not None:
            self._np_random_seed = int(seed)
        self._np_random = self.worlds.np_random[self.index]  # Gymnasium's own field names the world's generator
        self._started = True
        return self.worlds.observation(self.index), self.info()

    def step(self, action: Any):
        if not self._started:
            raise RuntimeError("call reset() before step()")
        a = int(action)
        if not self.action_space.contains(a):
            raise ValueError(f"action must be a meta-action 0..4, got {action!r}")
        actions = np.zeros(self.worlds.n, np.int64)
        actions[self.index] = a
        active = np.zeros(self.worlds.n, bool)
        active[self.index] = True
        self.worlds.step(actions, active)
        w, i = self.worlds, self.index
        return w.observation(i), w.core.reward(i), w.terminated(i), w.truncated(i), self.info()

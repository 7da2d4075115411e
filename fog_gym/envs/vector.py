"""The native vector env of the RL presets: ``gym.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point")``.

:class:`FogDriveVectorEnv` steps all N worlds in one process, the traffic of all of them in one numba call on a
shared :class:`~fog_gym.world.traffic.native.NativeTraffic`:

* ``observation="objects"``: everything batched (:class:`~fog_gym.envs.objects.ObjectWorlds`: traffic, detection and
  fusion in one call per step; no Python per world except the resets and ``info``);
* ``observation="pixels"``: the traffic batched, then each world's own env (the preset's ``FogDriveEnv`` and its
  wrappers, on a view of the shared traffic) renders its camera, LiDAR, fog and bird's-eye image.

**Seeded identity**: ``reset(seed=s)`` gives sub-env i exactly the episode of ``gym.make(id, **kwargs)`` reset with
``seed=s + i`` (a list of seeds: one per sub-env); a later reset without a seed continues each sub-env's own
generator, as a single env's does. **Autoreset** (``autoreset_mode``): Gymnasium's ``NEXT_STEP`` by default — a
sub-env that terminates or truncates is reset by the next ``step``, whose action for it is ignored and whose reward
is 0 — or ``SAME_STEP`` (the reset happens inside the step that ended the episode; the last observation and info
are in ``infos["final_obs"]`` and ``infos["final_info"]``, as SB3 expects). ``set_fog`` per sub-env, reachable with
``call("set_fog", [...])``-style lists or ``set_attr("next_fog", [...])`` (:class:`~fog_gym.wrappers.VectorFogCurriculum`).

Example:
    >>> import gymnasium as gym, fog_gym
    >>> envs = gym.make_vec("FogDriveRLHazard-v0", num_envs=4, vectorization_mode="vector_entry_point",
    ...                     observation="objects", fog="dense")
    >>> obs, infos = envs.reset(seed=0)
    >>> obs.shape, envs.action_space
    ((4, 8, 9), MultiDiscrete([5 5 5 5]))
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space

from fog_gym.envs.presets import (HAZARD_BEV_AHEAD, HAZARD_TRAFFIC, OBJECT_ARGS, RL_TRAFFIC, check_observation,
                                  make_fogdrive_rl, objects_config)  # fmt: skip
from fog_gym.fog.physics import parse_fog
from fog_gym.world.hazards import HazardConfig

#: Env ids with a native vector path → (traffic, hazards by default, bird's-eye look-ahead).
VECTOR_PRESETS: dict[str, tuple[dict, bool, float]] = {
    "FogDriveRL-v0": (RL_TRAFFIC, False, 0.0),
    "FogDriveRLHazard-v0": (HAZARD_TRAFFIC, True, HAZARD_BEV_AHEAD),
}
#: Keyword arguments the vector env accepts besides the presets' own (``make_fogdrive_rl``'s).
PRESET_ARGS = ("fog", "town", "camera_size", "grayscale", "bev_size", "frame_stack", "highway_config", "bev_ahead",
               "observation", "hazards", "episode_seconds", "traffic", "static_world", "time_of_day", *OBJECT_ARGS)  # fmt: skip


def check_vector_arguments(env_id: str, num_envs: Any, autoreset_mode: Any, kwargs: dict) -> AutoresetMode:
    """``ValueError`` naming the argument unless the vector env can be built from these (before any world is); returns
    the autoreset mode."""
    if env_id not in VECTOR_PRESETS:
        raise ValueError(f"env_id must be one of {sorted(VECTOR_PRESETS)} (the presets with a vector path), got {env_id!r}")
    if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
        raise ValueError(f"num_envs must be an integer >= 1, got {num_envs!r}")
    unknown = sorted(set(kwargs) - set(PRESET_ARGS))
    if unknown:
        raise ValueError(f"unknown argument(s) {unknown} for {env_id}; allowed: {sorted(PRESET_ARGS)}")
    try:
        mode = AutoresetMode(autoreset_mode)
    except ValueError:
        mode = None
    if mode not in (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP):
        raise ValueError(f"autoreset_mode must be NEXT_STEP or SAME_STEP, got {autoreset_mode!r}")
    if kwargs.get("town", "highway") != "highway":
        raise ValueError(f"town: the native vector path runs the highway town only, got {kwargs['town']!r}")
    return mode


def sub_env_seeds(seed: Any, num_envs: int) -> list[int | None]:
    """Each sub-env's seed for ``reset(seed=seed)``: ``seed + i`` for an int, None for None, or one of a list.

    >>> sub_env_seeds(5, 3), sub_env_seeds(None, 2)
    ([5, 6, 7], [None, None])
    """
    if seed is None:
        return [None] * num_envs
    if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
        return [int(seed) + i for i in range(num_envs)]
    seeds = list(seed)
    if len(seeds) != num_envs:
        raise ValueError(f"seed must be an int, None or {num_envs} seeds, got {len(seeds)}")
    return seeds


class FogDriveVectorEnv(gym.vector.VectorEnv):
    """N worlds of an RL preset stepped in one process (see the module docstring)."""

    def __init__(self, env_id: str, num_envs: int, autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
                 info_detections: bool = True, **kwargs: Any) -> None:  # fmt: skip
        mode = check_vector_arguments(env_id, num_envs, autoreset_mode, kwargs)
        self.env_id = env_id
        self.num_envs = int(num_envs)
        self.metadata = {"autoreset_mode": mode, "render_modes": []}
        self.info_detections = bool(info_detections)
        traffic, with_hazards, bev_ahead = VECTOR_PRESETS[env_id]
        observation = check_observation(kwargs.pop("observation", "pixels"))
        self.observation = observation
        highway_config = {**traffic, **(kwargs.pop("highway_config", None) or {})}
        hazards = kwargs.pop("hazards", None)
        if with_hazards and hazards is None:
            hazards = HazardConfig()
        fog = kwargs.pop("fog", "clear")
        if isinstance(fog, (list, tuple)):
            raise ValueError("fog: the RL presets take one level (in place), not a paired list")
        parse_fog(fog)
        if observation == "objects":
            from fog_gym.envs.objects import ObjectWorlds

            objects = objects_config(kwargs)
            episode_seconds = kwargs.pop("episode_seconds", 20.0)
            kwargs.pop("traffic", None)
            kwargs.pop("town", None)
            if kwargs:
                raise ValueError(f"observation='objects' does not take {sorted(kwargs)}")
            self.worlds = ObjectWorlds(self.num_envs, highway_config, hazards, fog, objects, episode_seconds)
            m, nf = self.worlds.obs.shape[1:]
            self.single_observation_space = gym.spaces.Box(-1.0, 1.0, (m, nf), np.float32)
            self.core = self.worlds.core
            self.envs: list[gym.Env] = []
        else:
            from fog_gym.world.traffic.native import NativeTraffic
            from fog_gym.world.traffic_world import NativeTrafficWorld

            leftover = [k for k in OBJECT_ARGS if k in kwargs]
            if leftover:
                raise ValueError(f"{leftover} configure observation='objects'; this env has observation='pixels'")
            if kwargs.get("traffic", "native") != "native":
                raise ValueError(f"traffic: the native vector path needs traffic='native', got {kwargs['traffic']!r}")
            kwargs.pop("traffic", None)
            self.core = NativeTraffic(self.num_envs, highway_config, hazards, 20, 5)
            kwargs.setdefault("bev_ahead", bev_ahead)
            self.envs = []
            for i in range(self.num_envs):
                world = NativeTrafficWorld("highway", core=self.core, index=i,
                                           episode_seconds=kwargs.get("episode_seconds", 20.0))  # fmt: skip
                self.envs.append(make_fogdrive_rl(fog=fog, highway_config=highway_config, hazards=hazards, world=world,
                                                  **kwargs))  # fmt: skip
            self.single_observation_space = self.envs[0].observation_space
        self.single_action_space = gym.spaces.Discrete(5)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self._ended = np.zeros(self.num_envs, bool)
        self._started = False

    # -- Gymnasium VectorEnv API ----------------------------------------------------------------------
    def reset(self, *, seed: int | Sequence[int | None] | None = None, options: dict[str, Any] | None = None):
        seeds = self._seeds(seed)
        self._ended[:] = False
        self._started = True
        if self.observation == "objects":
            self.worlds.reset_many(list(range(self.num_envs)), seeds)
            infos = self._infos(np.ones(self.num_envs, bool))
            return self.worlds.obs.copy(), infos
        obs, infos = [], self._ragged()
        for i, env in enumerate(self.envs):
            o, info = env.reset(seed=seeds[i])
            obs.append(o)
            infos = self._add_info(infos, info, i)
        return self._batch(obs), infos

    def step(self, actions: Any):
        if not self._started:
            raise RuntimeError("call reset() before step()")
        actions = np.asarray(actions, np.int64).reshape(self.num_envs)
        if actions.min() < 0 or actions.max() > 4:
            raise ValueError(f"actions must be meta-actions 0..4, got {actions.tolist()}")
        next_step = self.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
        resetting = self._ended.copy() if next_step else np.zeros(self.num_envs, bool)
        stepping = ~resetting
        if self.observation == "objects":
            return self._step_objects(actions, resetting, stepping, next_step)
        return self._step_pixels(actions, resetting, stepping, next_step)

    def _step_objects(self, actions, resetting, stepping, next_step):
        w = self.worlds
        if resetting.any():
            w.reset_many(list(np.flatnonzero(resetting)), [None] * int(resetting.sum()))
        w.step(actions, stepping)
        rewards = np.zeros(self.num_envs)
        terminated = np.zeros(self.num_envs, bool)
        truncated = np.zeros(self.num_envs, bool)
        for i in np.flatnonzero(stepping):
            rewards[i] = w.core.reward(i)
            terminated[i] = w.terminated(i)
            truncated[i] = w.truncated(i)
        done = terminated | truncated
        infos = self._infos(np.ones(self.num_envs, bool))
        obs = w.obs.copy()
        if not next_step and done.any():
            ended = list(np.flatnonzero(done))
            infos["final_obs"] = np.full(self.num_envs, None, dtype=object)
            infos["final_info"] = {k: v.copy() if isinstance(v, np.ndarray) else v for k, v in infos.items()
                                   if k != "final_obs"}  # fmt: skip
            infos["_final_obs"] = infos["_final_info"] = done.copy()
            for i in ended:
                infos["final_obs"][i] = obs[i].copy()
            w.reset_many(ended, [None] * len(ended))
            obs = w.obs.copy()
            fresh = self._infos(done)
            for k, v in fresh.items():
                if isinstance(v, np.ndarray) and k in infos and infos[k].shape == v.shape:
                    infos[k][done] = v[done]
        self._ended = done if next_step else np.zeros(self.num_envs, bool)
        return obs, rewards, terminated, truncated, infos

    def _step_pixels(self, actions, resetting, stepping, next_step):
        self.core.step(actions, stepping)
        obs, infos = [], self._ragged()
        rewards = np.zeros(self.num_envs)
        terminated = np.zeros(self.num_envs, bool)
        truncated = np.zeros(self.num_envs, bool)
        final_obs, final_info = {}, {}
        for i, env in enumerate(self.envs):
            if resetting[i]:
                o, info = env.reset()
            else:
                env.unwrapped.world.pre_stepped(int(actions[i]))
                o, rewards[i], terminated[i], truncated[i], info = env.step(int(actions[i]))
                if not next_step and (terminated[i] or truncated[i]):
                    final_obs[i], final_info[i] = o, info
                    o, info = env.reset()
            obs.append(o)
            infos = self._add_info(infos, info, i)
        if final_obs:
            infos["final_obs"] = np.full(self.num_envs, None, dtype=object)
            infos["_final_obs"] = np.zeros(self.num_envs, bool)
            fi: dict = self._ragged()
            for i, o in final_obs.items():
                infos["final_obs"][i] = o
                infos["_final_obs"][i] = True
                fi = self._add_info(fi, final_info[i], i)
            infos["final_info"], infos["_final_info"] = fi, infos["_final_obs"].copy()
        self._ended = (terminated | truncated) if next_step else np.zeros(self.num_envs, bool)
        return self._batch(obs), rewards, terminated, truncated, infos

    # -- sub-env access (curricula) -------------------------------------------------------------------
    def set_fog(self, index: int, fog: Any) -> None:
        """Sub-env ``index``'s fog from its next reset on."""
        if self.observation == "objects":
            self.worlds.set_fog(index, fog)
        else:
            self.envs[index].get_wrapper_attr("set_fog")(fog)

    def set_attr(self, name: str, values: Any) -> None:
        values = list(values) if isinstance(values, (list, tuple)) else [values] * self.num_envs
        if len(values) != self.num_envs:
            raise ValueError(f"set_attr needs {self.num_envs} values, got {len(values)}")
        if name != "next_fog":
            raise AttributeError(f"{name!r}: the vector env's sub-envs take 'next_fog' only")
        for i, v in enumerate(values):
            if v is not None:
                self.set_fog(i, v)

    def call(self, name: str, *args: Any, **kwargs: Any) -> tuple:
        if name != "set_fog":
            raise AttributeError(f"{name!r}: the vector env's sub-envs answer 'set_fog' only")
        levels = args[0] if args else kwargs["fog"]
        levels = list(levels) if isinstance(levels, (list, tuple)) else [levels] * self.num_envs
        for i, lv in enumerate(levels):
            self.set_fog(i, lv)
        return tuple(None for _ in range(self.num_envs))

    def get_attr(self, name: str) -> tuple:
        if name == "fog":
            if self.observation == "objects":
                return tuple(self.worlds.levels)
            return tuple(env.get_wrapper_attr("fog") for env in self.envs)
        raise AttributeError(f"{name!r} is not an attribute the vector env's sub-envs share")

    def reset_one(self, index: int, seed: int | None = None) -> tuple[Any, dict]:
        """Reset sub-env ``index`` alone (an SB3 curriculum's re-reset); its next step continues normally."""
        self._ended[index] = False
        if self.observation == "objects":
            self.worlds.reset(index, seed)
            return self.worlds.obs[index].copy(), self.worlds.info(index, self.info_detections)
        return self.envs[index].reset(seed=seed)

    def close_extras(self, **kwargs: Any) -> None:
        for env in self.envs:
            env.close()

    # -- helpers --------------------------------------------------------------------------------------
    def _seeds(self, seed: Any) -> list[int | None]:
        return sub_env_seeds(seed, self.num_envs)

    def _ragged(self) -> dict[str, Any]:
        """Info keys whose arrays differ in shape between sub-envs, as object arrays (Gymnasium's convention)."""
        return {"hazards": np.full(self.num_envs, None, dtype=object)} if self.core.hazards is not None else {}

    def _batch(self, obs: list) -> Any:
        if isinstance(self.single_observation_space, gym.spaces.Dict):
            return {k: np.stack([o[k] for o in obs]) for k in self.single_observation_space.spaces}
        return np.stack(obs)

    def _infos(self, mask: np.ndarray) -> dict[str, Any]:
        w = self.worlds
        c = w.core
        infos: dict[str, Any] = {
            "speed": c.floats[:, 0, 3].copy(), "crashed": c.ints[:, 0, 3].astype(bool),
            "step": w.steps.copy(), "fog": {"visibility_m": np.array([lv.visibility_m for lv in w.levels]),
                                            "alpha": w.alphas.copy()},
        }  # fmt: skip
        for k in ("speed", "crashed", "step"):
            infos[f"_{k}"] = mask.copy()
        infos["_fog"] = mask.copy()
        if c.hazards is not None:
            infos["hazards"] = np.array([c.hazards_ego(i) for i in range(self.num_envs)] + [None], dtype=object)[:-1]
            infos["_hazards"] = mask.copy()
        if self.info_detections:
            infos["detections"] = np.array([w.detections(i) for i in range(self.num_envs)] + [None], dtype=object)[:-1]
            infos["_detections"] = mask.copy()
        return infos

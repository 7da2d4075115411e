"""The native vector env of the RL presets: ``gym.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point")``.

:class:`FogDriveVectorEnv` steps all N worlds in one process, the traffic of all of them in one numba call on a
shared :class:`~fog_gym.world.traffic.native.NativeTraffic`:

* ``observation="objects"``: everything batched (:class:`~fog_gym.envs.objects.ObjectWorlds`: traffic, detection and
  fusion in one call per step, the resets' perception in the same call; rewards, terminations and every info entry as
  arrays over all worlds, the Gymnasium-shaped infos assembled from them, :mod:`fog_gym.envs.batched`; no Python per
  world but the resets and, in ``SAME_STEP`` mode, an ended world's final info);
* ``observation="pixels"``: the traffic batched, then each world's own env (the preset's ``FogDriveEnv`` and its
  wrappers, on a view of the shared traffic) renders its camera, LiDAR, fog and bird's-eye image. The worlds' Python
  runs in the calling thread, each world's step a coroutine, and their kernels (ray cast, camera set-up and raster,
  fogs, bird's-eye image) in rounds on ``threads`` threads (default: 2, or fewer cores or worlds): every world runs
  to its next kernel, then the round's kernels of all worlds run in parallel (:mod:`fog_gym._rounds`), so no thread
  waits for another's Python. The worlds share nothing they write, so the result is the same bits for any ``threads``
  (tested); ``threads=1`` renders them one after the other, each kernel where it is called.

**Seeded identity**: ``reset(seed=s)`` gives sub-env i exactly the episode of ``gym.make(id, **kwargs)`` reset with
``seed=s + i`` (a list of seeds: one per sub-env); a later reset without a seed continues each sub-env's own
generator, as a single env's does. **Gymnasium's contract**, as ``SyncVectorEnv`` over single envs keeps it (tested
differentially): ``autoreset_mode`` ``NEXT_STEP`` (default: a sub-env that ended is reset by the next ``step``, whose
action for it is ignored and whose reward is 0), ``SAME_STEP`` (reset inside the ending step; ``infos["final_obs"]``
and ``infos["final_info"]``, as SB3 expects) or ``DISABLED`` (reset ended sub-envs yourself with
``reset(options={"reset_mask": mask})``); infos with ``_key`` masks at every level; ``get_attr`` / ``set_attr`` /
``call`` on any attribute or method of the sub-envs (``set_attr("next_fog", [...])`` per sub-env:
:class:`~fog_gym.wrappers.VectorFogCurriculum`).

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

from fog_gym._numba import worker_crew
from fog_gym._rounds import run_rounds
from fog_gym.envs.presets import (HAZARD_BEV_AHEAD, HAZARD_TRAFFIC, OBJECT_ARGS, OBJECTS_PRESET, RL_TRAFFIC,
                                  check_banks, check_observation, make_fogdrive_rl, objects_config)  # fmt: skip
from fog_gym.envs.objects import parse_objects_fog
from fog_gym.fog.physics import parse_fog
from fog_gym.world.hazards import HazardConfig

#: Env ids with a native vector path → (traffic, hazards by default, bird's-eye look-ahead).
VECTOR_PRESETS: dict[str, tuple[dict, bool, float]] = {
    "FogDriveRL-v0": (RL_TRAFFIC, False, 0.0),
    "FogDriveRLHazard-v0": (HAZARD_TRAFFIC, True, HAZARD_BEV_AHEAD),
    "FogDriveRLObjects-v0": (HAZARD_TRAFFIC, True, HAZARD_BEV_AHEAD),
    "FogDriveRLFogBank-v0": (HAZARD_TRAFFIC, True, HAZARD_BEV_AHEAD),
}
#: Env ids whose own arguments the vector env applies first (the caller's override them).
PRESET_DEFAULTS: dict[str, dict[str, Any]] = {"FogDriveRLObjects-v0": OBJECTS_PRESET}
#: Keyword arguments the vector env accepts besides the presets' own (``make_fogdrive_rl``'s).
PRESET_ARGS = ("fog", "town", "camera_size", "grayscale", "bev_size", "frame_stack", "highway_config", "bev_ahead",
               "observation", "hazards", "episode_seconds", "traffic", "static_world", "time_of_day", "geometry",
               "banks", *OBJECT_ARGS)  # fmt: skip


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
    if mode is None:
        raise ValueError(f"autoreset_mode must be NEXT_STEP, SAME_STEP or DISABLED, got {autoreset_mode!r}")
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
    """N worlds of an RL preset stepped in one process (see the module docstring).

    It is Gymnasium's ``SyncVectorEnv`` over N single envs of the preset, made fast: the traffic (and, for perceived
    objects, the detection) of every world runs in one numba call, and everything else follows ``SyncVectorEnv``
    step by step — the same observations, rewards, terminations, truncations and infos (built by the same
    ``_add_info``, so the same ``_key`` masks, ``final_obs`` and ``final_info``) in every autoreset mode, ``reset``
    with ``options={"reset_mask": mask}``, and ``get_attr`` / ``set_attr`` / ``call`` on the sub-envs (``envs``:
    the preset's wrapped envs for pixels, :class:`~fog_gym.envs.objects.FogDriveObjectsEnv` views of the shared
    worlds for perceived objects)."""

    def __init__(self, env_id: str, num_envs: int, autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
                 info_detections: bool = True, threads: int | None = None, **kwargs: Any) -> None:  # fmt: skip
        spec_kwargs = dict(kwargs)  # what the caller passed, as gym.make records it in each sub-env's spec
        kwargs = {**PRESET_DEFAULTS.get(env_id, {}), **kwargs}
        mode = check_vector_arguments(env_id, num_envs, autoreset_mode, kwargs)
        if not isinstance(info_detections, bool):
            raise ValueError(f"info_detections must be True or False, got {info_detections!r}")
        self.threads = world_threads(threads, int(num_envs))
        self._pool: Any = None
        self.env_id = env_id
        self.num_envs = int(num_envs)
        self.metadata = {"autoreset_mode": mode, "render_modes": []}
        self.render_mode = None
        self.info_detections = info_detections
        traffic, with_hazards, bev_ahead = VECTOR_PRESETS[env_id]
        observation = check_observation(kwargs.pop("observation", "pixels"))
        self.observation = observation
        highway_config = {**traffic, **(kwargs.pop("highway_config", None) or {})}
        hazards = kwargs.pop("hazards", None)
        if with_hazards and hazards is None:
            hazards = HazardConfig()
        banks = kwargs.pop("banks", None)
        if env_id == "FogDriveRLFogBank-v0":  # a bank per episode and world (drawn as the single env draws it)
            banks, kwargs["fog"] = check_banks(banks, kwargs)
        elif banks is not None:
            raise ValueError(f"banks configures FogDriveRLFogBank-v0, not {env_id}")
        fog = kwargs.pop("fog", "clear")
        if isinstance(fog, (list, tuple)):
            raise ValueError("fog: the RL presets take one level (in place), not a paired list")
        parse_objects_fog(fog) if observation == "objects" else parse_fog(fog)
        if observation == "objects":
            from fog_gym.envs.objects import FogDriveObjectsEnv, ObjectWorlds

            objects = objects_config(kwargs)
            episode_seconds = kwargs.pop("episode_seconds", 20.0)
            kwargs.pop("traffic", None)
            kwargs.pop("town", None)
            if kwargs:
                raise ValueError(f"observation='objects' does not take {sorted(kwargs)}")
            self.worlds = ObjectWorlds(self.num_envs, highway_config, hazards, fog, objects, episode_seconds, banks=banks)
            self.core = self.worlds.core
            self.envs: list[gym.Env] = [FogDriveObjectsEnv(worlds=self.worlds, index=i, info_detections=info_detections)
                                        for i in range(self.num_envs)]  # fmt: skip
            spec_kwargs["info_detections"] = info_detections
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
                env = make_fogdrive_rl(fog=fog, highway_config=highway_config, hazards=hazards, world=world, **kwargs)
                if banks is not None:
                    from fog_gym.wrappers import FogBankEpisodes

                    env = FogBankEpisodes(env, banks)
                self.envs.append(env)
        sub_spec = _sub_env_spec(env_id, spec_kwargs)
        for env in self.envs:
            env.unwrapped.spec = sub_spec
        self.single_observation_space = self.envs[0].observation_space
        self.single_action_space = gym.spaces.Discrete(5)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self._obs: list[Any] = [None] * self.num_envs  # the pixel path's latest observation per sub-env
        self._autoreset = np.zeros(self.num_envs, bool)  # SyncVectorEnv's _autoreset_envs
        self._started = False

    # -- Gymnasium VectorEnv API ----------------------------------------------------------------------
    def reset(self, *, seed: int | Sequence[int | None] | None = None, options: dict[str, Any] | None = None):
        seeds = self._seeds(seed)
        options = dict(options) if options is not None else None
        mask = reset_mask(options, self.num_envs)
        which = list(np.flatnonzero(mask))
        self._autoreset[mask] = False
        if not self._started and not mask.all():
            raise RuntimeError("the first reset resets every sub-env (no reset_mask)")
        self._started = True
        infos: dict[str, Any] = {}
        if self.observation == "objects":
            self.worlds.reset_many(which, [seeds[i] for i in which])
            for i in which:
                self.envs[i]._started = True
            return self.worlds.observation(), self.worlds.batched_infos(mask, self.info_detections)
        results = self._map(lambda i: self.envs[i].reset(seed=seeds[i], options=options), which)
        for i, (self._obs[i], info) in zip(which, results):
            infos = self._add_info(infos, info, i)
        return self._batch(self._obs), infos

    def step(self, actions: Any):
        if not self._started:
            raise RuntimeError("call reset() before step()")
        actions = np.asarray(actions, np.int64).reshape(self.num_envs)
        if actions.min() < 0 or actions.max() > 4:
            raise ValueError(f"actions must be meta-actions 0..4, got {actions.tolist()}")
        mode = self.metadata["autoreset_mode"]
        if mode == AutoresetMode.DISABLED and self._autoreset.any():
            raise RuntimeError(f"sub-envs {np.flatnonzero(self._autoreset).tolist()} ended: with autoreset_mode "
                               "DISABLED reset them first, reset(options={'reset_mask': mask})")  # fmt: skip
        resetting = self._autoreset.copy() if mode == AutoresetMode.NEXT_STEP else np.zeros(self.num_envs, bool)
        stepping = ~resetting
        rewards = np.zeros(self.num_envs)
        terminated = np.zeros(self.num_envs, bool)
        truncated = np.zeros(self.num_envs, bool)
        same_step = mode == AutoresetMode.SAME_STEP
        if self.observation == "objects":
            infos = self._step_objects(actions, resetting, stepping, same_step, rewards, terminated, truncated)
            obs = self.worlds.observation()
        else:
            infos = self._step_pixels(actions, resetting, same_step, rewards, terminated, truncated)
            obs = self._batch(self._obs)
        self._autoreset = terminated | truncated
        return obs, rewards, terminated, truncated, infos

    def _step_objects(self, actions, resetting, stepping, same_step, rewards, terminated, truncated) -> dict:
        w = self.worlds
        if resetting.any():  # their traffic now, their perception with the stepped worlds' (one kernel call)
            w.reset_many(list(np.flatnonzero(resetting)), [None] * int(resetting.sum()), perceive=False)
        w.step(actions, stepping, also=resetting)
        rewards[:] = w.rewards(stepping)
        terminated[:] = w.terminations() & stepping
        truncated[:] = w.truncations() & stepping
        ended = np.flatnonzero((terminated | truncated) & same_step)
        finals = {i: (w.observation(i), self.envs[i].info()) for i in ended}
        if len(ended):
            w.reset_many(list(ended), [None] * len(ended))
        infos = w.batched_infos(np.ones(self.num_envs, bool), self.info_detections)
        for i in ended:  # SAME_STEP: the ended worlds' last observation and info (Gymnasium's own merge)
            infos = self._add_info(infos, {"final_obs": finals[i][0], "final_info": finals[i][1]}, i)
        return infos

    def _step_pixels(self, actions, resetting, same_step, rewards, terminated, truncated) -> dict:
        self.core.step(actions, ~resetting)

        def world(i: int) -> tuple:
            """World ``i``'s part of the step (on a worker thread): its reset, or its step and, in SAME_STEP mode when
            it ended, its final observation and info before the reset."""
            env = self.envs[i]
            if resetting[i]:
                return env.reset(), None
            env.unwrapped.world.pre_stepped(int(actions[i]))
            out = env.step(int(actions[i]))
            if same_step and (out[2] or out[3]):
                return out, env.reset()
            return out, None

        infos: dict[str, Any] = {}
        for i, (out, after) in enumerate(self._map(world, range(self.num_envs))):
            if resetting[i]:
                self._obs[i], info = out
            else:
                self._obs[i], rewards[i], terminated[i], truncated[i], info = out
                if after is not None:
                    infos = self._add_info(infos, {"final_obs": self._obs[i], "final_info": info}, i)
                    self._obs[i], info = after
            infos = self._add_info(infos, info, i)
        return infos

    def _map(self, f: Any, worlds: Any) -> list:
        """``f(i)`` for each of ``worlds``, in order: with several threads, each world's ``f`` a coroutine in this
        thread and their kernels in rounds on the threads (:func:`fog_gym._rounds.run_rounds`)."""
        worlds = list(worlds)
        if self.threads == 1 or len(worlds) < 2:
            return [f(i) for i in worlds]
        if self._pool is None:
            self._pool = worker_crew(self.threads)
        return run_rounds([lambda i=i: f(i) for i in worlds], self._pool)

    # -- sub-env access (as SyncVectorEnv) ------------------------------------------------------------
    def get_attr(self, name: str) -> tuple[Any, ...]:
        """Each sub-env's attribute ``name`` (through its wrappers)."""
        return tuple(env.get_wrapper_attr(name) for env in self.envs)

    def set_attr(self, name: str, values: Any) -> None:
        """Set ``name`` on every sub-env: one value for all, or a list of ``num_envs`` values."""
        if not isinstance(values, (list, tuple)):
            values = [values] * self.num_envs
        if len(values) != self.num_envs:
            raise ValueError(f"values must be a list of num_envs={self.num_envs} values, got {len(values)}")
        for env, value in zip(self.envs, values):
            env.set_wrapper_attr(name, value)

    def call(self, name: str, *args: Any, **kwargs: Any) -> tuple[Any, ...]:
        """Call each sub-env's method ``name`` with the same arguments (an attribute that is not callable is
        returned as it is)."""
        out = []
        for env in self.envs:
            f = env.get_wrapper_attr(name)
            out.append(f(*args, **kwargs) if callable(f) else f)
        return tuple(out)

    def set_fog(self, index: int, fog: Any) -> None:
        """Sub-env ``index``'s fog from its next reset on."""
        self.envs[index].get_wrapper_attr("set_fog")(fog)

    def reset_one(self, index: int, seed: int | None = None) -> tuple[Any, dict]:
        """Reset sub-env ``index`` alone (an SB3 curriculum's re-reset); its next step continues normally."""
        self._autoreset[index] = False
        obs, info = self.envs[index].reset(seed=seed)
        if self.observation != "objects":
            self._obs[index] = obs
        return obs, info

    def close_extras(self, **kwargs: Any) -> None:
        if self._pool is not None:
            self._pool.close()
            self._pool = None
        for env in self.envs:
            env.close()

    # -- helpers --------------------------------------------------------------------------------------
    def _seeds(self, seed: Any) -> list[int | None]:
        return sub_env_seeds(seed, self.num_envs)

    def _batch(self, obs: list) -> Any:
        if isinstance(self.single_observation_space, gym.spaces.Dict):
            return {k: np.stack([o[k] for o in obs]) for k in self.single_observation_space.spaces}
        return np.stack(obs)


#: Kernel threads of the pixel path by default (at most; fewer with fewer cores or worlds): the worlds' Python runs in
#: one thread, their kernels in rounds on these (measured on two cores only: docs/performance.md).
DEFAULT_THREADS = 2


def world_threads(threads: Any, num_envs: int) -> int:
    """The pixel path's kernel threads: ``threads`` (an int >= 1) or, for None, :data:`DEFAULT_THREADS` bounded by the
    cores and the worlds.

    >>> world_threads(1, 8), world_threads(None, 1), world_threads(3, 8)
    (1, 1, 3)
    """
    if threads is None:
        import os

        cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
        return max(1, min(DEFAULT_THREADS, cores, num_envs))
    if isinstance(threads, bool) or not isinstance(threads, (int, np.integer)) or threads < 1:
        raise ValueError(f"threads must be an integer >= 1 or None, got {threads!r}")
    return int(threads)


def reset_mask(options: dict[str, Any] | None, num_envs: int) -> np.ndarray:
    """The sub-envs ``reset`` resets: ``options["reset_mask"]`` (popped; checked as ``SyncVectorEnv`` checks it) or
    all of them."""
    if options is None or "reset_mask" not in options:
        return np.ones(num_envs, bool)
    mask = options.pop("reset_mask")
    if not isinstance(mask, np.ndarray):
        raise TypeError(f"`options['reset_mask']` must be a numpy array, got {type(mask)}")
    if mask.shape != (num_envs,):
        raise ValueError(f"`options['reset_mask']` must have shape `({num_envs},)`, got {mask.shape}")
    if mask.dtype != np.bool_:
        raise TypeError(f"`options['reset_mask']` must have `dtype=np.bool_`, got {mask.dtype}")
    if not mask.any():
        raise ValueError(f"`options['reset_mask']` must contain a boolean array with at least one True value, got "
                         f"reset_mask={mask}")  # fmt: skip
    return mask.copy()


def _sub_env_spec(env_id: str, kwargs: dict[str, Any]) -> Any:
    """The spec ``gym.make(env_id, **kwargs)`` gives its env (the sub-envs report it through ``get_attr("spec")``)."""
    import copy

    spec = copy.deepcopy(gym.spec(env_id))
    spec.kwargs = {**spec.kwargs, **copy.deepcopy(kwargs)}
    return spec

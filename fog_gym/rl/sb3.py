"""Stable-Baselines3 glue (needs the ``rl`` extra): the SB3 adapter of the fog curriculum.

SB3 vector envs reset a finished sub-env inside ``step`` — in the worker process, before any callback or wrapper
in the main process sees the ``done``. A level chosen from that episode's outcome can therefore only reach the
sub-env after its new episode has begun. :class:`VecFogCurriculum` closes that gap: when sub-env ``i`` finishes an
episode it reports the outcome to the :class:`~fog_gym.fog.curriculum.Curriculum`, sets the next level with
``set_fog`` and resets sub-env ``i`` once more, so the episode the agent plays next is in the new fog. The
auto-reset's episode had no step and is dropped; the terminal observation stays in ``infos[i]``. Cost: one extra
reset per episode (about 3 % of an episode of FogDriveRL-v0).

(The earlier SB3 callback ``curriculum_callback``, which applied a level one episode late, is gone: this wrapper
replaces it.)

Example (sketch):
    >>> # venv = VecFogCurriculum(SubprocVecEnv([make_env] * 8), StepSchedule(episodes_per_level=50))
    >>> # model = PPO("MultiInputPolicy", VecMonitor(venv)).learn(100_000)
"""

from __future__ import annotations

from typing import Any

import numpy as np
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper

from fog_gym.fog.curriculum import Curriculum
from fog_gym.fog.schedules import FogSchedule


class VecFogCurriculum(VecEnvWrapper):
    """Drive one fog ``schedule`` over the episodes of all sub-envs (counted in the order they finish); the level
    chosen when an episode ends applies to that sub-env's very next episode.

    The sub-envs must have an in-place fog wrapper (``gym.make("FogDriveRL-v0", fog=...)``). ``infos[i]["fog_level"]``
    carries the level of the episode that sub-env ``i`` is playing, ``curriculum`` the bookkeeping (``episodes``:
    the number finished so far) and ``levels`` the level each sub-env is on.
    """

    def __init__(self, venv: VecEnv, schedule: FogSchedule | Curriculum) -> None:
        super().__init__(venv)
        self.curriculum = schedule if isinstance(schedule, Curriculum) else Curriculum(schedule)
        self.levels: list[Any] = []

    @property
    def schedule(self) -> FogSchedule:
        return self.curriculum.schedule

    @property
    def episodes(self) -> int:
        """Episodes finished so far."""
        return self.curriculum.finished

    def reset(self) -> Any:
        self.levels = [self.curriculum.next_level() for _ in range(self.num_envs)]
        for i, level in enumerate(self.levels):
            self.venv.env_method("set_fog", level, indices=[i])
        return self.venv.reset()

    def step_wait(self):
        obs, rewards, dones, infos = self.venv.step_wait()
        for i in np.flatnonzero(dones):
            self.curriculum.finish(not infos[i].get("crashed", False))
            level = self.levels[i] = self.curriculum.next_level()
            self.venv.env_method("set_fog", level, indices=[i])
            new_obs, _ = self.venv.env_method("reset", indices=[i])[0]
            _put(obs, i, new_obs)
        for i, info in enumerate(infos):
            info["fog_level"] = self.levels[i]
        return obs, rewards, dones, infos


def _put(batch: Any, i: int, single: Any) -> None:
    """Write one sub-env's observation into the batched observation (arrays or a dict of arrays)."""
    if isinstance(batch, dict):
        for key in batch:
            batch[key][i] = single[key]
    else:
        batch[i] = single


class VectorEnvAdapter(VecEnv):
    """fog-gym's native vector env (:class:`~fog_gym.envs.vector.FogDriveVectorEnv`, or ``gym.make_vec(...,
    vectorization_mode="vector_entry_point")``) as an SB3 ``VecEnv``, so PPO, DQN and SB3's wrappers train on it.

    It switches the vector env to Gymnasium's ``SAME_STEP`` autoreset, which is SB3's: a finished sub-env's ``step``
    returns the first observation of its next episode, the last one in ``infos[i]["terminal_observation"]`` and
    ``infos[i]["TimeLimit.truncated"]`` when the time limit (not a crash) ended it. ``seed(s)`` seeds the next reset
    (sub-env i gets ``s + i``); ``env_method("set_fog", level, indices=[i])`` and ``env_method("reset",
    indices=[i])`` reach one sub-env (what :class:`VecFogCurriculum` uses).

    >>> import gymnasium as gym, fog_gym
    >>> venv = VectorEnvAdapter(gym.make_vec("FogDriveRLHazard-v0", num_envs=2, vectorization_mode="vector_entry_point",
    ...                                      observation="objects", info_detections=False))
    >>> _ = venv.seed(0)
    >>> venv.reset().shape
    (2, 8, 9)
    """

    def __init__(self, venv: Any) -> None:
        from gymnasium.vector import AutoresetMode

        base = getattr(venv, "unwrapped", venv)
        if not (hasattr(base, "reset_one") and hasattr(base, "set_fog")):
            raise ValueError(f"venv must be fog-gym's native vector env, got {type(venv).__name__}")
        base.metadata = {**base.metadata, "autoreset_mode": AutoresetMode.SAME_STEP}
        self.venv = base
        self.render_mode = None
        super().__init__(base.num_envs, base.single_observation_space, base.single_action_space)
        self._actions: np.ndarray | None = None

    def reset(self) -> Any:
        seeds = self._seeds if any(s is not None for s in self._seeds) else None
        obs, _ = self.venv.reset(seed=seeds)
        self._reset_seeds()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions)

    def step_wait(self):
        obs, rewards, terminated, truncated, infos = self.venv.step(self._actions)
        dones = terminated | truncated
        out = [{} for _ in range(self.num_envs)]
        for i in range(self.num_envs):
            out[i]["crashed"] = bool(infos["crashed"][i]) if "crashed" in infos else False
            if "speed" in infos:
                out[i]["speed"] = float(infos["speed"][i])
            if dones[i]:
                out[i]["terminal_observation"] = infos["final_obs"][i]
                out[i]["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
                final = infos.get("final_info", {})
                if "crashed" in final:
                    out[i]["crashed"] = bool(final["crashed"][i])
        return obs, rewards.astype(np.float32), dones, out

    def close(self) -> None:
        self.venv.close()

    def get_attr(self, attr_name: str, indices: Any = None) -> list[Any]:
        if attr_name == "render_mode":
            return [None for _ in self._get_indices(indices)]
        values = self.venv.get_attr(attr_name)
        return [values[i] for i in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: Any = None) -> None:
        values: list[Any] = [None] * self.num_envs
        for i in self._get_indices(indices):
            values[i] = value
        self.venv.set_attr(attr_name, values)

    def env_method(self, method_name: str, *method_args: Any, indices: Any = None, **method_kwargs: Any) -> list[Any]:
        out = []
        for i in self._get_indices(indices):
            if method_name == "set_fog":
                out.append(self.venv.set_fog(i, *method_args, **method_kwargs))
            elif method_name == "reset":
                out.append(self.venv.reset_one(i, *method_args, **method_kwargs))
            else:
                raise AttributeError(f"{method_name!r}: the native vector env's sub-envs answer set_fog and reset")
        return out

    def env_is_wrapped(self, wrapper_class: type, indices: Any = None) -> list[bool]:
        return [False for _ in self._get_indices(indices)]

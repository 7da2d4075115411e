"""``VectorFogCurriculum``: one fog curriculum over all sub-envs of a Gymnasium vector env."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode, VectorWrapper

from fog_gym.fog.curriculum import Curriculum
from fog_gym.fog.schedules import FogSchedule


class VectorFogCurriculum(VectorWrapper):
    """Drive one fog ``schedule`` over the episodes of all sub-envs (a :class:`~fog_gym.fog.curriculum.Curriculum`,
    episodes counted in the order they start and finish); the level chosen when an episode ends applies to that
    sub-env's very next episode.

    Needs Gymnasium's ``NEXT_STEP`` autoreset (the default of ``gym.make_vec`` and of fog-gym's native vector env):
    a sub-env that finishes in one ``step`` is reset by the next, so its level is set in between through the
    in-place fog wrapper's ``next_fog`` attribute (``set_attr``). ``levels`` (and ``infos["fog_level"]``) holds, per
    sub-env, the level of its current episode or, for a sub-env that just finished, of the episode it starts next.

    >>> import fog_gym
    >>> from fog_gym.fog.schedules import StepSchedule
    >>> envs = gym.make_vec("FogDrive-v0", num_envs=2, vectorization_mode="sync", fog="clear", resolution=(16, 12),
    ...                     cameras=["CAM_FRONT"], labels=None, episode_seconds=0.2)
    >>> envs = VectorFogCurriculum(envs, StepSchedule(episodes_per_level=2))
    >>> _ = envs.reset(seed=0)
    >>> for _ in range(3):
    ...     _ = envs.step(np.ones(2, np.int64))
    >>> envs.levels, envs.curriculum.finished   # two episodes finished, the next two started in light fog
    ([160.0, 160.0], 2)
    """

    def __init__(self, env: gym.vector.VectorEnv, schedule: FogSchedule) -> None:
        super().__init__(env)
        mode = env.metadata.get("autoreset_mode", AutoresetMode.NEXT_STEP)
        if mode != AutoresetMode.NEXT_STEP:
            raise ValueError(f"VectorFogCurriculum needs the NEXT_STEP autoreset mode, got {mode}")
        self.curriculum = Curriculum(schedule)
        self.levels: list[Any] = []

    def reset(self, *, seed: int | list[int] | None = None, options: dict[str, Any] | None = None):
        self.levels = [self.curriculum.next_level() for _ in range(self.num_envs)]
        self.env.set_attr("next_fog", list(self.levels))
        obs, infos = self.env.reset(seed=seed, options=options)
        return obs, self._with_levels(infos)

    def step(self, actions: Any):
        obs, rewards, terminated, truncated, infos = self.env.step(actions)
        done = np.flatnonzero(np.logical_or(terminated, truncated))
        if done.size:
            crashed = np.asarray(infos.get("crashed", np.zeros(self.num_envs, bool)))
            pending: list[Any] = [None] * self.num_envs
            for i in done:
                self.curriculum.finish(not bool(crashed[i]))
                pending[i] = self.levels[i] = self.curriculum.next_level()
            self.env.set_attr("next_fog", pending)
        return obs, rewards, terminated, truncated, self._with_levels(infos)

    def _with_levels(self, infos: dict) -> dict:
        infos = dict(infos)
        infos["fog_level"] = np.array(self.levels, dtype=object)
        infos["_fog_level"] = np.ones(self.num_envs, bool)
        return infos

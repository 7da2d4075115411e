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

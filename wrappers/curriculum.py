"""``FogCurriculum``: a fog curriculum on one env, the level applied before each ``reset``."""

from __future__ import annotations

from typing import Any

import gymnasium as gym

from fog_gym.fog.curriculum import Curriculum
from fog_gym.fog.schedules import FogSchedule


class FogCurriculum(gym.Wrapper):
    """Before each ``reset`` sets the fog of the coming episode from ``schedule`` (through the in-place
    ``FogWrapper``'s ``set_fog``), and after each episode tells the schedule whether it succeeded (no crash); the
    bookkeeping is a :class:`~fog_gym.fog.curriculum.Curriculum` (``self.curriculum``). Episodes are counted per env:
    inside each sub-env of a vector env every sub-env follows the schedule on its own episodes (for one schedule
    over all sub-envs use :class:`~fog_gym.wrappers.VectorFogCurriculum`). ``info["curriculum"]`` gives the episode
    index and the level in force.

    >>> import fog_gym
    >>> from fog_gym.fog.schedules import StepSchedule
    >>> env = FogCurriculum(gym.make("FogDrive-v0", fog="clear", resolution=(16, 12), cameras=["CAM_FRONT"]),
    ...                     StepSchedule(episodes_per_level=1))
    >>> [env.reset(seed=0)[1]["fog"]["visibility_m"] for _ in range(3)]
    [inf, 160.0, 100.0]
    """

    def __init__(self, env: gym.Env, schedule: FogSchedule) -> None:
        super().__init__(env)
        self.curriculum = Curriculum(schedule)
        try:
            env.get_wrapper_attr("set_fog")
        except AttributeError:
            raise ValueError("FogCurriculum needs an in-place fog wrapper below it (gym.make(..., fog='clear'))") from None
        self._running = False

    @property
    def schedule(self) -> FogSchedule:
        return self.curriculum.schedule

    @property
    def episode(self) -> int:
        """0-based index of the current episode (-1 before the first reset)."""
        return self.curriculum.started - 1

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        level = self.curriculum.next_level()
        self.env.get_wrapper_attr("set_fog")(level)
        obs, info = self.env.reset(seed=seed, options=options)
        self._running = True
        return obs, {**info, "curriculum": {"episode": self.episode, "level": level}}

    def step(self, action: Any):
        obs, reward, terminated, truncated, info = self.env.step(action)
        if (terminated or truncated) and self._running:
            self.curriculum.finish(not info.get("crashed", False))
            self._running = False
        return obs, reward, terminated, truncated, {**info, "curriculum": {"episode": self.episode}}

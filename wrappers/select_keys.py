"""``SelectKeys``: keep some keys of a dict observation."""

from __future__ import annotations

from collections.abc import Sequence

import gymnasium as gym
from gymnasium import spaces


class SelectKeys(gym.ObservationWrapper):
    """Keep only ``keys`` of a Dict observation (``single=True`` with one key returns that array: ``CnnPolicy``)."""

    def __init__(self, env: gym.Env, keys: Sequence[str], single: bool = False) -> None:
        super().__init__(env)
        missing = [k for k in keys if k not in env.observation_space.spaces]
        if missing or not keys:
            raise ValueError(f"keys must name observation keys {sorted(env.observation_space.spaces)}, missing {missing}")
        if single and len(keys) != 1:
            raise ValueError("single=True needs exactly one key")
        self.keys, self.single = list(keys), single
        self.observation_space = env.observation_space[keys[0]] if single else spaces.Dict({k: env.observation_space[k] for k in keys})

    def observation(self, observation: dict):
        return observation[self.keys[0]] if self.single else {k: observation[k] for k in self.keys}

"""``StackFrames``: the last k observations of every image key, stacked along the channel axis."""

from __future__ import annotations

from collections import deque

import gymnasium as gym
import numpy as np
from gymnasium import spaces


class StackFrames(gym.Wrapper):
    """Stack the last ``k`` frames of every channel-first image key along the channel axis (oldest first)."""

    def __init__(self, env: gym.Env, k: int = 4) -> None:
        super().__init__(env)
        if isinstance(k, bool) or not isinstance(k, int) or k < 1:
            raise ValueError(f"k must be an integer >= 1, got {k!r}")
        self.k = k
        self._frames: dict[str, deque] = {}
        obs_spaces = {}
        for key, s in env.observation_space.spaces.items():
            obs_spaces[key] = spaces.Box(0, 255, (s.shape[0] * k, *s.shape[1:]), s.dtype) if len(s.shape) == 3 else s
        self.observation_space = spaces.Dict(obs_spaces)

    def _stack(self, obs: dict) -> dict:
        out = {}
        for key, v in obs.items():
            if key in self._frames:
                self._frames[key].append(v)
                out[key] = np.concatenate(list(self._frames[key]), axis=0)
            else:
                out[key] = v
        return out

    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        self._frames = {key: deque([v] * self.k, maxlen=self.k) for key, v in obs.items() if np.ndim(v) == 3}
        return {key: (np.concatenate([v] * self.k, axis=0) if key in self._frames else v) for key, v in obs.items()}, info

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        return self._stack(obs), reward, terminated, truncated, info

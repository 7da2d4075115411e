"""``ResizeCameras``: camera images at the size and layout a CNN policy takes."""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import gymnasium as gym
import numpy as np
from gymnasium import spaces


class ResizeCameras(gym.ObservationWrapper):
    """Camera RGB ``(H, W, 3)`` → ``(C, h, w)`` uint8 (C = 3, or 1 with ``grayscale``), area-averaged.

    >>> import fog_gym
    >>> env = ResizeCameras(fog_gym.FogDriveEnv(resolution=(64, 48), cameras=["CAM_FRONT"]), size=(32, 24), grayscale=True)
    >>> env.observation_space["CAM_FRONT"].shape
    (1, 24, 32)
    """

    def __init__(self, env: gym.Env, size: Sequence[int] = (64, 64), cameras: Sequence[str] | None = None,
                 grayscale: bool = False) -> None:  # fmt: skip
        super().__init__(env)
        w, h = (int(v) for v in size)
        if w <= 0 or h <= 0:
            raise ValueError(f"size must be a (width, height) pair of positive integers, got {size!r}")
        names = [k for k, s in env.observation_space.spaces.items() if s.dtype == np.uint8 and len(s.shape) == 3 and s.shape[-1] == 3]
        self.cameras = list(cameras) if cameras is not None else names
        for c in self.cameras:
            if c not in names:
                raise ValueError(f"cameras must be RGB camera keys of the observation {names}, got {c!r}")
        self.size, self.grayscale = (w, h), bool(grayscale)
        obs_spaces = dict(env.observation_space.spaces)
        for c in self.cameras:
            obs_spaces[c] = spaces.Box(0, 255, (1 if grayscale else 3, h, w), np.uint8)
        self.observation_space = spaces.Dict(obs_spaces)

    def observation(self, observation: dict) -> dict:
        out = dict(observation)
        for c in self.cameras:
            img = observation[c]
            if img.shape[1::-1] != self.size:  # (the same size: area resampling is the identity)
                img = cv2.resize(img, self.size, interpolation=cv2.INTER_AREA)
            if self.grayscale:
                out[c] = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY)[None]
            else:
                out[c] = np.ascontiguousarray(img.transpose(2, 0, 1))
        return out

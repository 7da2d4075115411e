"""Observation shaping for RL: small channel-first cameras, a LiDAR bird's-eye image, frame stacking, key selection.

Each wrapper keeps the observation a flat ``Dict`` of uint8 ``Box`` images that SB3's ``MultiInputPolicy`` accepts
(channel-first, so SB3 does not transpose them).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence

import cv2
import gymnasium as gym
import numpy as np
from gymnasium import spaces

from fog_gym.points import unpack_points


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
            img = cv2.resize(observation[c], self.size, interpolation=cv2.INTER_AREA)
            if self.grayscale:
                out[c] = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY)[None]
            else:
                out[c] = np.ascontiguousarray(img.transpose(2, 0, 1))
        return out


class LidarBEV(gym.ObservationWrapper):
    """A LiDAR channel → a ``(2, size, size)`` uint8 bird's-eye image around the ego (x forward = up, y right =
    right): occupancy of points above the ground, and their highest point (0–255 over 0–4 m above the road).

    The image spans ``metres`` on each side, centred ``ahead`` metres in front of the sensor (0: centred on it):
    a point at (x, y) in the sensor frame falls in row ``floor((metres/2 + ahead − x)·size/metres)`` and column
    ``floor((y + metres/2)·size/metres)``.

    >>> import fog_gym
    >>> env = LidarBEV(fog_gym.FogDriveEnv(resolution=(16, 12), cameras=["CAM_FRONT"]), size=32)
    >>> env.observation_space["LIDAR_BEV"].shape
    (2, 32, 32)
    """

    def __init__(self, env: gym.Env, channel: str = "LIDAR_TOP", size: int = 64, metres: float = 64.0,
                 key: str = "LIDAR_BEV", sensor_height: float = 2.0, drop_channel: bool = True,
                 ahead: float = 0.0) -> None:  # fmt: skip
        super().__init__(env)
        if channel not in env.observation_space.spaces:
            raise ValueError(f"channel {channel!r} is not in the observation (keys: {sorted(env.observation_space.spaces)})")
        if size <= 0 or not metres > 0:
            raise ValueError(f"size must be > 0 pixels and metres > 0, got {size!r} and {metres!r}")
        if not (isinstance(ahead, (int, float)) and math.isfinite(ahead) and abs(ahead) < metres / 2):
            raise ValueError(f"ahead must be a finite offset smaller than half of metres ({metres / 2}), got {ahead!r}")
        self.channel, self.size, self.metres, self.key, self.sensor_height = channel, int(size), float(metres), key, float(sensor_height)
        self.ahead = float(ahead)
        obs_spaces = dict(env.observation_space.spaces)
        if drop_channel:
            obs_spaces.pop(channel)
        obs_spaces[key] = spaces.Box(0, 255, (2, self.size, self.size), np.uint8)
        self.drop_channel = drop_channel
        self.observation_space = spaces.Dict(obs_spaces)

    def observation(self, observation: dict) -> dict:
        pts = unpack_points(observation, self.channel)
        height = pts[:, 2] + self.sensor_height  # above the road
        above = (height > 0.3) & (height < 4.0)
        scale = self.size / self.metres
        col = np.floor(pts[above, 1] * scale + self.size / 2).astype(np.int64)
        row = np.floor((self.ahead - pts[above, 0]) * scale + self.size / 2).astype(np.int64)
        ok = (col >= 0) & (col < self.size) & (row >= 0) & (row < self.size)
        img = np.zeros((2, self.size, self.size), np.uint8)
        img[0, row[ok], col[ok]] = 255
        h = np.clip(height[above][ok] / 4.0 * 255, 0, 255).astype(np.uint8)
        np.maximum.at(img[1], (row[ok], col[ok]), h)
        out = dict(observation)
        if self.drop_channel:
            out.pop(self.channel)
        out[self.key] = img
        return out


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

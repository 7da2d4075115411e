"""``LidarBEV``: the LiDAR sweep as a bird's-eye image a CNN policy takes."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from fog_gym.channels.packing import unpack_points
from fog_gym.render.birds_eye import lidar_bev


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
        pts = unpack_points(observation, self.channel, copy=False)  # (read only)
        img = lidar_bev(pts, self.size, self.metres, self.ahead, self.sensor_height)
        out = dict(observation)
        if self.drop_channel:
            out.pop(self.channel)
        out[self.key] = img
        return out

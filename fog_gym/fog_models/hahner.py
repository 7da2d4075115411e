"""Hahner et al. fog for LiDAR point clouds (:func:`fog_gym.fog.fog_lidar`), on the packed observation.

Each level draws from its own generator (``context.rngs[level name]``).

>>> import numpy as np
>>> from fog_gym.fog import parse_fog
>>> from fog_gym.fog_models.base import FogContext
>>> obs = {"LIDAR_TOP": np.array([[10.0, 0, 0, 1.0], [0, 0, 0, 0]], np.float32)}
>>> lv = parse_fog("clear")
>>> out = Hahner().apply(obs, "LIDAR_TOP", [lv], FogContext(rngs={lv.name: np.random.default_rng(0)}))
>>> out["clear"].shape
(2, 4)
"""

from __future__ import annotations

from fog_gym.fog import fog_lidar
from fog_gym.fog_models.base import register_model
from fog_gym.points import pack_points, unpack_points


@register_model("lidar")
class Hahner:
    name = "hahner"

    def apply(self, obs, channel, levels, context):
        clean = unpack_points(obs, channel)
        capacity = obs[channel].shape[0]
        return {lv.name: pack_points(fog_lidar(clean, lv, context.rngs[lv.name], context.lidar_noise), capacity)
                for lv in levels}  # fmt: skip

"""``SEM_LIDAR_TOP``: the semantic LiDAR (x, y, z, cos incidence, object id, tag), physics in
:func:`fog_gym.lidar.simulate_semantic_lidar`.

>>> from fog_gym.lidar import LidarConfig
>>> s = SemanticLidarSensor(LidarConfig.fogdrive_semantic())
>>> s.channels, s.layout()["SEM_LIDAR_TOP"].folder, s.space().shape[1]
(('SEM_LIDAR_TOP',), 'semantic_lidar', 6)
"""

from __future__ import annotations

import numpy as np

from fog_gym.lidar import SemanticLidarConfig, sensor_to_world, simulate_semantic_lidar
from fog_gym.points import SEMANTIC_LIDAR, lidar_space
from fog_gym.sensors.base import PointSensor, register


@register(SemanticLidarConfig)
class SemanticLidarSensor(PointSensor):
    """Built for a :class:`~fog_gym.lidar.SemanticLidarConfig` (``LidarConfig.fogdrive_semantic()``)."""

    kind = "semantic_lidar"
    default_channel, columns, default_folder = SEMANTIC_LIDAR, 6, "semantic_lidar"

    def space(self):
        return lidar_space(self.config, self.simulation_frequency, semantic=True)

    def measure(self, scene, prims, rng: np.random.Generator, tick: int) -> dict[str, np.ndarray]:
        cfg = self.config
        pts = simulate_semantic_lidar(cfg, sensor_to_world(cfg.pose, scene.ego_pose), prims, scene.static.surface,
                                      rng, self.simulation_frequency, self.start_angle(tick))  # fmt: skip
        return {self.channel: pts}

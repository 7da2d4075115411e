"""``LIDAR_TOP``: the 64-channel LiDAR (x, y, z, intensity), physics in :func:`fog_gym.lidar.simulate_lidar`.

>>> from fog_gym.lidar import LidarConfig
>>> s = LidarSensor(LidarConfig.fogdrive())
>>> s.channels, s.layout()["LIDAR_TOP"].folder, s.layout()["LIDAR_TOP_FOG_DENSE"].folder, s.space().shape[1]
(('LIDAR_TOP',), 'lidar', 'lidar_fog_dense', 4)
"""

from __future__ import annotations

import numpy as np

from fog_gym.dataset.layout import FOG_LEVELS
from fog_gym.lidar import LidarConfig, sensor_to_world, simulate_lidar
from fog_gym.points import LIDAR, lidar_space
from fog_gym.sensors.base import PointSensor, register


@register(LidarConfig)
class LidarSensor(PointSensor):
    kind = "lidar"
    default_channel, columns, default_folder = LIDAR, 4, "lidar"

    def layout(self):
        """The clean channel and its fog variants ``<channel>_FOG_<LEVEL>`` in ``<folder>_fog_<level>``."""
        out = super().layout()
        for lv in FOG_LEVELS:
            out[f"{self.channel}_FOG_{lv}"] = out[self.channel]._replace(folder=f"{self.folder}_fog_{lv.lower()}")
        return out

    def space(self):
        return lidar_space(self.config, self.simulation_frequency, semantic=False)

    def measure(self, scene, prims, rng: np.random.Generator, tick: int) -> dict[str, np.ndarray]:
        cfg = self.config
        pts = simulate_lidar(cfg, sensor_to_world(cfg.pose, scene.ego_pose), prims, scene.static.surface, rng,
                             self.simulation_frequency, self.start_angle(tick))  # fmt: skip
        return {self.channel: pts}

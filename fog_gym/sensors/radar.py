"""``RADAR_FRONT``: the radar (velocity, azimuth, altitude, depth), physics in :func:`fog_gym.lidar.simulate_radar`.

>>> from fog_gym.lidar import RadarConfig
>>> s = RadarSensor(RadarConfig.fogdrive())
>>> s.channels, s.layout()["RADAR_FRONT"].folder, s.space().shape[1]
(('RADAR_FRONT',), 'radar', 4)
"""

from __future__ import annotations

import numpy as np

from fog_gym.lidar import RadarConfig, sensor_to_world, simulate_radar
from fog_gym.points import RADAR, radar_space
from fog_gym.sensors.base import PointSensor, register


@register(RadarConfig)
class RadarSensor(PointSensor):
    kind = "radar"
    default_channel, columns, default_folder = RADAR, 4, "radar"

    def space(self):
        return radar_space(self.config, self.simulation_frequency)

    def measure(self, scene, prims, rng: np.random.Generator, tick: int) -> dict[str, np.ndarray]:
        cfg = self.config
        ego_velocity = scene.vehicles.velocities[scene.vehicles.ids == scene.ego_id][0]
        pts = simulate_radar(cfg, sensor_to_world(cfg.pose, scene.ego_pose), prims, rng, scene.vehicles, ego_velocity,
                             self.simulation_frequency)  # fmt: skip
        return {self.channel: pts}

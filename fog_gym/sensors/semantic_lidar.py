"""``SEM_LIDAR_TOP``: the semantic LiDAR (x, y, z, cos incidence, object id, tag), as CARLA's
``sensor.lidar.ray_cast_semantic``: the LiDAR's ray pattern (:mod:`fog_gym.sensors.lidar`), no intensity, drop-off
or noise; object id = the vehicle id (0 for the static world and the ground), tag from the primitive or, on the
ground, from the road-surface map.

Example:
    >>> s = SemanticLidarSensor(LidarConfig.fogdrive_semantic())
    >>> s.channels, s.layout()["SEM_LIDAR_TOP"].folder, s.space().shape[1]
    (('SEM_LIDAR_TOP',), 'semantic_lidar', 6)
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from numba import njit

from fog_gym.geometry import sensor_to_world
from fog_gym.sensors.base import PointSensor, register
from fog_gym.sensors.lidar import LidarConfig, SemanticLidarConfig, lidar_directions, lidar_space, split_transform
from fog_gym.channels.packing import SEMANTIC_LIDAR
from fog_gym.sensors.raycast import MISS, cast_rays
from fog_gym.world.mesh import MATERIAL_TAG
from fog_gym.world.primitives import Primitives
from fog_gym.world.scenery import SURFACE_TAGS, SurfaceMap


@njit(cache=True, nogil=True)
def _semantic_points(dirs, dist, index, cosine, material, rotation, origin, insts, tags, mat_tag, grid, gx0, gy0, res,
                     surface_tags):  # fmt: skip
    """Returns as (N, 6) float32 x, y, z, cos, id, tag; ground tags from the surface grid (as SurfaceMap.class_at),
    a mesh's tag from the material hit (its instance's where the material has none)."""
    n = dirs.shape[0]
    count = 0
    for i in range(n):
        if index[i] != MISS:
            count += 1
    out = np.empty((count, 6), dtype=np.float32)
    rows, cols = grid.shape
    k = 0
    for i in range(n):
        p = index[i]
        if p == MISS:
            continue
        d = np.float64(dist[i])
        out[k, 0] = dirs[i, 0] * d
        out[k, 1] = dirs[i, 1] * d
        out[k, 2] = dirs[i, 2] * d
        out[k, 3] = cosine[i]
        if p >= 0:
            out[k, 4] = insts[p]
            mt = mat_tag[material[i]] if material[i] < mat_tag.shape[0] else 255
            out[k, 5] = tags[p] if mt == 255 else mt
        else:
            ux, uy, uz = dirs[i, 0], dirs[i, 1], dirs[i, 2]
            wx = origin[0] + d * (rotation[0, 0] * ux + rotation[0, 1] * uy + rotation[0, 2] * uz)
            wy = origin[1] + d * (rotation[1, 0] * ux + rotation[1, 1] * uy + rotation[1, 2] * uz)
            col = int(np.floor((wx - gx0) / res))
            row = int(np.floor((wy - gy0) / res))
            cls = grid[row, col] if 0 <= row < rows and 0 <= col < cols else 0
            out[k, 4] = 0.0
            out[k, 5] = surface_tags[cls]
        k += 1
    return out


def simulate_semantic_lidar(
    cfg: LidarConfig,
    sensor_to_world: np.ndarray,
    prims: Primitives | Mapping[str, Any],
    surface: SurfaceMap,
    rng: np.random.Generator | None = None,
    simulation_frequency: float = 20.0,
    start_angle: float = 0.0,
) -> np.ndarray:
    """One tick of a semantic LiDAR: ``(N, 6)`` float32 x, y, z, cos(incidence), object id, semantic tag.

    Same ray pattern as :func:`simulate_lidar` but no intensity, drop-off or noise, so ``rng`` is not used.
    The object id is the primitive's ``insts`` (vehicle id; 0 for the static world and the ground); the ground's
    tag is ``SURFACE_TAGS[surface.class_at(x, y)]`` at the hit, a mesh's that of the material hit (a tree's trunk and
    crown: vegetation; a car's tyres: the car's class). cos(incidence) is ``|ray · surface normal|``.

    >>> from fog_gym.world.scenery import SurfaceMap
    >>> surface = SurfaceMap(np.zeros((10, 10), np.uint8), (-5.0, -5.0), 1.0)
    >>> box = {"centers": np.array([[10.0, 0, 1]]), "halves": np.array([[1.0, 1, 1]]), "yaws": np.zeros(1),
    ...        "tags": np.array([14], np.uint8), "insts": np.array([7], np.uint16)}
    >>> cfg = LidarConfig.fogdrive_semantic()
    >>> pts = simulate_semantic_lidar(cfg, sensor_to_world(cfg.pose), box, surface)
    >>> car = pts[pts[:, 4] == 7]
    >>> round(float(car[:, 0].min()), 3), set(car[:, 5].tolist())
    (9.0, {14.0})
    """
    rot, origin = split_transform(sensor_to_world)
    dirs = lidar_directions(cfg, simulation_frequency, start_angle)
    prims = Primitives.coerce(prims)
    hits = cast_rays(origin, dirs, cfg.range, prims, rotation=rot)
    grid = np.ascontiguousarray(surface.grid, np.uint8)
    return _semantic_points(
        dirs, hits.distance, hits.index, hits.cos_incidence, hits.material, rot, origin,
        prims.insts, prims.tags, MATERIAL_TAG, grid,
        float(surface.origin[0]), float(surface.origin[1]), float(surface.resolution), SURFACE_TAGS,
    )  # fmt: skip


@register(SemanticLidarConfig)
class SemanticLidarSensor(PointSensor):
    """Built for a :class:`~fog_gym.sensors.lidar.SemanticLidarConfig` (``LidarConfig.fogdrive_semantic()``)."""

    kind = "semantic_lidar"
    default_channel, columns, default_folder = SEMANTIC_LIDAR, 6, "semantic_lidar"

    def space(self):
        return lidar_space(self.config, self.simulation_frequency, semantic=True)

    def measure(self, scene, prims, rng: np.random.Generator, tick: int) -> dict[str, np.ndarray]:
        cfg = self.config
        pts = simulate_semantic_lidar(cfg, sensor_to_world(cfg.pose, scene.ego_pose), prims, scene.static.surface,
                                      rng, self.simulation_frequency, self.start_angle(tick))  # fmt: skip
        return {self.channel: pts}

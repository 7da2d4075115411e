"""Sensors of the rig: cameras (RGB, planar depth, semantic tags, instance ids), LiDAR, semantic LiDAR, radar.

A pure function of (:class:`~fog_gym.scene.Scene`, :class:`~fog_gym.config.RigConfig`): nothing here
steps the world. Cameras that share a resolution are rendered in one batched kernel call.

Example:
    >>> from fog_gym.config import RigConfig
    >>> cams = CameraRig(RigConfig.fogdrive(resolution=(64, 48)))
    >>> cams.names
    ('CAM_FRONT', 'CAM_BACK', 'CAM_LEFT', 'CAM_RIGHT')
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fog_gym import geometry
from fog_gym.config import RigConfig
from fog_gym.lidar import sensor_to_world, simulate_lidar, simulate_radar, simulate_semantic_lidar
from fog_gym.points import LIDAR, RADAR, SEMANTIC_LIDAR
from fog_gym.render.lights import beam_window, concat_lights, cull_lights, lamp_light_map, render_night, street_lamp_lights
from fog_gym.render.raster import render
from fog_gym.primitives import Primitives
from fog_gym.scene import Scene, headlights, prop_primitives
from fog_gym.scenery import SURFACE_TAGS, lamp_heads

#: Lights farther than this from the ego (beyond their own radius) are left out of a night frame [m].
LIGHT_RANGE = 250.0


@dataclass(frozen=True)
class CameraFrame:
    """One camera's buffers at one instant."""

    rgb: np.ndarray  # (H, W, 3) uint8
    depth: np.ndarray  # (H, W) float32, planar depth in metres (sky = far)
    semantic: np.ndarray  # (H, W) uint8, CARLA ≥ 0.9.14 tag ids
    instance: np.ndarray  # (H, W) uint16, vehicle id (0 = static world and sky)


class CameraRig:
    """Renders every camera of a :class:`RigConfig` from a :class:`Scene`."""

    def __init__(self, rig: RigConfig, far: float = 1000.0, render_radius: float = 600.0) -> None:
        self.rig = rig
        self.far = float(far)
        self.render_radius = float(render_radius)
        self.names = tuple(c.name for c in rig.cameras)
        self.intrinsics = {c.name: c.intrinsic() for c in rig.cameras}
        self.sensor_to_vehicle = {c.name: geometry.transform_matrix(c.pose.location, c.pose.rotation) for c in rig.cameras}
        groups: dict[tuple[int, int], list] = {}
        for c in rig.cameras:
            groups.setdefault((c.width, c.height), []).append(c)
        self._groups = list(groups.items())
        self._props_cache: tuple[object, dict] | None = None
        self._lamps_cache: tuple | None = None
        #: Auto-exposure gain of each camera in the latest frame (1 by day).
        self.exposure: dict[str, float] = {}

    def world_to_camera(self, scene: Scene, name: str) -> np.ndarray:
        ego = geometry.yaw_transform(*scene.ego_pose)
        return geometry.world_to_camera(ego, self.sensor_to_vehicle[name])

    def primitives(self, scene: Scene) -> Primitives:
        """Render primitives near the ego: static props (cached per static world) + vehicles."""
        if self._props_cache is None or self._props_cache[0] is not scene.static:
            self._props_cache = (scene.static, prop_primitives(scene.static.props))
        props = self._props_cache[1].near(np.asarray(scene.ego_pose[:2]), self.render_radius)
        return Primitives.concat(props, scene.primitives)

    def render(self, scene: Scene, prims: Primitives | None = None) -> dict[str, CameraFrame]:
        """Every camera's buffers; ``prims`` defaults to :meth:`primitives` of the scene."""
        prims = self.primitives(scene) if prims is None else prims
        light = scene.lighting
        night = light.night
        if night:  # albedo pass, then street lamps, headlights and auto-exposure (fog_gym.render.lights)
            lut, ambient, sun = light.albedo_lut(), 1.0, 0.0
            heads, lights, ground = self.night_lights(scene)
        else:
            lut, ambient, sun = light.surface_lut(), light.ambient, light.sun_intensity
        frames: dict[str, CameraFrame] = {}
        for (width, height), cams in self._groups:
            mats = np.array([self.world_to_camera(scene, c.name) for c in cams])
            ks = np.array([[k[0, 0], k[1, 1], k[0, 2], k[1, 2]] for k in (self.intrinsics[c.name] for c in cams)])
            if night:
                out, gains = render_night(
                    mats[:, :3, :3], mats[:, :3, 3], ks, width, height, self.far, prims, scene.static.tiled, lut,
                    SURFACE_TAGS, light.sky_horizon, light.sky_zenith, lights, ground, heads,
                )  # fmt: skip
            else:
                out = render(
                    mats[:, :3, :3], mats[:, :3, 3], ks, width, height, self.far, prims, scene.static.tiled, lut,
                    SURFACE_TAGS, light.sky_horizon, light.sky_zenith, light.sun_dir, ambient, sun,
                )  # fmt: skip
                gains = np.ones(len(cams))
            for i, c in enumerate(cams):
                frames[c.name] = CameraFrame(out["rgb"][i], out["depth"][i], out["sem"][i], out["inst"][i])
                self.exposure[c.name] = float(gains[i])
        return frames

    def night_lights(self, scene: Scene):
        """Lamp heads (N, 3) near the ego, the :class:`~fog_gym.render.lights.Lights` that light faces, and the
        ground light maps (street lamps over the whole world, built once per static world; a window around the
        ego with the low beams added) of a night scene."""
        if self._lamps_cache is None or self._lamps_cache[0] is not scene.static:
            all_heads = lamp_heads(scene.static.props, scene.static.surface)
            lamp_map = lamp_light_map(street_lamp_lights(all_heads), scene.static.surface.extent)
            self._lamps_cache = (scene.static, all_heads, lamp_map)
        _, heads, lamp_map = self._lamps_cache
        ego = np.array([scene.ego_pose[0], scene.ego_pose[1], 0.0])
        heads = heads[np.linalg.norm(heads[:, :2] - ego[:2], axis=1) <= LIGHT_RANGE + 50.0]
        beams = cull_lights(headlights(scene.vehicles), ego, LIGHT_RANGE)
        lights = cull_lights(concat_lights(street_lamp_lights(heads), beams), ego, LIGHT_RANGE)
        return heads, lights, (lamp_map, beam_window(lamp_map, beams, ego))


class PointSensors:
    """LiDAR (``LIDAR_TOP``), semantic LiDAR (``SEM_LIDAR_TOP``) and radar (``RADAR_FRONT``) of a rig.

    :meth:`measure` returns each configured sensor's points for the tick that ends at the scene's instant,
    in the sensor frame, with CARLA's semantics (see :mod:`fog_gym.lidar`).

    >>> from fog_gym.config import RigConfig
    >>> sorted(PointSensors(RigConfig.fogdrive(cameras=[])).channels)
    ['LIDAR_TOP', 'RADAR_FRONT', 'SEM_LIDAR_TOP']
    """

    def __init__(self, rig: RigConfig, simulation_frequency: float = 20.0) -> None:
        self.rig = rig
        self.simulation_frequency = float(simulation_frequency)
        self.channels = tuple(
            name for name, cfg in ((LIDAR, rig.lidar), (SEMANTIC_LIDAR, rig.semantic_lidar), (RADAR, rig.radar)) if cfg
        )

    def _start_angle(self, cfg, tick: int) -> float:
        # a head that turns less than a full sweep per tick resumes where the previous tick stopped
        return (tick * cfg.tick_angle(self.simulation_frequency)) % cfg.horizontal_fov

    def measure(self, scene: Scene, prims: Primitives, rng: np.random.Generator, tick: int) -> dict[str, np.ndarray]:
        """Points per channel for simulation tick ``tick`` (0-based); ``prims`` exclude the ego's own body."""
        rig, f, out = self.rig, self.simulation_frequency, {}
        surface = scene.static.surface
        if rig.lidar is not None:
            out[LIDAR] = simulate_lidar(rig.lidar, sensor_to_world(rig.lidar.pose, scene.ego_pose), prims, surface,
                                        rng, f, self._start_angle(rig.lidar, tick))  # fmt: skip
        if rig.semantic_lidar is not None:
            cfg = rig.semantic_lidar
            out[SEMANTIC_LIDAR] = simulate_semantic_lidar(cfg, sensor_to_world(cfg.pose, scene.ego_pose), prims,
                                                          surface, rng, f, self._start_angle(cfg, tick))  # fmt: skip
        if rig.radar is not None:
            ego_velocity = scene.vehicles.velocities[scene.vehicles.ids == scene.ego_id][0]
            out[RADAR] = simulate_radar(rig.radar, sensor_to_world(rig.radar.pose, scene.ego_pose), prims, rng,
                                        scene.vehicles, ego_velocity, f)  # fmt: skip
        return out

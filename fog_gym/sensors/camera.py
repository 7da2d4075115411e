"""Cameras: RGB ``C``, planar depth ``C_DEPTH``, semantic tags ``C_SEM`` (and instance ids, not a channel).

:class:`CameraConfig` is one pinhole camera (FogDrive's poses in :data:`FOGDRIVE_CAMERA_POSES`).

A pure function of (:class:`~fog_gym.world.scene.Scene`, :class:`~fog_gym.sensors.rig.RigConfig`): nothing here
steps the world. :class:`CameraRig` renders every camera of a rig, cameras that share a resolution in one
batched kernel call; :class:`CameraSensor` is one camera behind the :class:`~fog_gym.sensors.base.Sensor`
protocol (channels, spaces, dataset layout).

Example:
    >>> from fog_gym.envs.config import RigConfig
    >>> cams = CameraRig(RigConfig.fogdrive(resolution=(64, 48)))
    >>> cams.names
    ('CAM_FRONT', 'CAM_BACK', 'CAM_LEFT', 'CAM_RIGHT')
    >>> CameraSensor(RigConfig.fogdrive(resolution=(64, 48)).cameras[0]).channels
    ('CAM_FRONT', 'CAM_FRONT_DEPTH', 'CAM_FRONT_SEM')
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from fog_gym import geometry
from gymnasium import spaces

from fog_gym.checks import finite
from fog_gym.channels.spec import CAMERA_NAMES, FOG_LEVELS, ChannelSpec  # noqa: F401  (CAMERA_NAMES: re-exported)
from fog_gym.geometry import Pose
from fog_gym.sensors.base import check_sensor_name, register
from fog_gym.sensors.camera_noise import parse_noise
from fog_gym.render.lights import (beam_window, concat_lights, cull_lights, headlights, lamp_light_map, render_night,
                                   street_lamp_lights)  # fmt: skip
from fog_gym.render.antialias import antialias, filter_ground
from fog_gym.render.raster import render
from fog_gym.render.shadows import HALF, ShadowCache
from fog_gym.render.surface import albedo_lut, ground_lut, shadow_lut, tiled_surface
from fog_gym.render.prop_select import select_rows, take_concat
from fog_gym.render.view_cull import in_views
from fog_gym.world.primitives import Primitives
from fog_gym.world.scene import Scene, ego_primitives, prop_primitives
from fog_gym.encoding import SEMANTIC_TAGS
from fog_gym.world.scenery import SURFACE_TAGS, lamp_heads

@dataclass(frozen=True)
class CameraConfig:
    """One pinhole camera; RGB, depth, semantic and instance buffers share its pose and intrinsics. Its name is
    its RGB channel (a FogDrive name of :data:`CAMERA_NAMES`, or any upper-case name for an added camera).

    >>> CameraConfig("CAM_FRONT", Pose(1.8, 0, 1.2), 640, 480).intrinsic()[0, 0].round(2)
    np.float64(268.51)
    """

    name: str
    pose: Pose
    width: int = 1280
    height: int = 960
    fov: float = 100.0  # horizontal field of view, degrees
    #: Sensor noise and motion blur (:mod:`fog_gym.sensors.camera_noise`): None (noise-free, FogDrive's), "default"
    #: (an automotive-class CMOS pixel) or a :class:`~fog_gym.sensors.camera_noise.CameraNoise`.
    noise: Any = None
    #: Anti-aliased RGB (:mod:`fog_gym.render.antialias`): day ground pixels coloured by the mean of the surface over
    #: their footprint, then morphological edge anti-aliasing; depth, semantics and instances stay point-sampled
    antialias: bool = False

    def __post_init__(self) -> None:
        check_sensor_name(self.name)
        object.__setattr__(self, "noise", parse_noise(self.noise, "noise"))
        if not isinstance(self.antialias, (bool, np.bool_)):
            raise ValueError(f"antialias must be True or False, got {self.antialias!r}")
        object.__setattr__(self, "antialias", bool(self.antialias))  # the FogDrive cameras are CAMERA_NAMES; an added camera takes any such name
        object.__setattr__(self, "pose", Pose.coerce(self.pose))
        for attr in ("width", "height"):
            value = getattr(self, attr)
            if isinstance(value, bool) or not isinstance(value, (int,)) and not (
                isinstance(value, float) and value.is_integer()
            ):
                raise ValueError(f"resolution {attr} must be a positive integer, got {value!r}")
            if int(value) <= 0:
                raise ValueError(f"resolution {attr} must be a positive integer, got {value!r}")
            object.__setattr__(self, attr, int(value))
        fov = finite("fov", self.fov)
        if not 0.0 < fov < 180.0:
            raise ValueError(f"fov must lie in the open interval (0, 180) degrees, got {self.fov!r}")
        object.__setattr__(self, "fov", fov)

    def intrinsic(self):
        from fog_gym.geometry import intrinsic_matrix

        return intrinsic_matrix(self.width, self.height, self.fov)


#: Camera poses of FogDrive Table 2.
FOGDRIVE_CAMERA_POSES: dict[str, Pose] = {
    "CAM_FRONT": Pose(1.8, 0.0, 1.2, 0.0, 0.0, 0.0),
    "CAM_BACK": Pose(-2.4, 0.0, 1.2, 0.0, 0.0, 180.0),
    "CAM_LEFT": Pose(0.5, -0.7, 1.5, 0.0, 0.0, -100.0),
    "CAM_RIGHT": Pose(0.5, 0.7, 1.5, 0.0, 0.0, 100.0),
}

#: The props near the ego are re-selected from the whole static world only after it moved this far [m]; in between
#: from the props within ``render_radius`` plus this margin of where they were last selected (the same boxes).
NEAR_MARGIN = 40.0
#: Props within this distance of the ego [m] are drawn as their meshes and parts (every sensor alike), farther ones
#: as their boxes: beyond it a window pane spans under 3 pixels of FogDrive's cameras, and the LiDAR reaches 120 m.
DETAIL_RADIUS = 215.0
#: Lights farther than this from the ego (beyond their own radius) are left out of a night frame [m].
LIGHT_RANGE = 250.0
#: The largest semantic tag id (the bound of a ``C_SEM`` space).
MAX_TAG = max(SEMANTIC_TAGS.values())


@dataclass(frozen=True)
class CameraFrame:
    """One camera's buffers at one instant."""

    rgb: np.ndarray  # (H, W, 3) uint8
    depth: np.ndarray  # (H, W) float32, planar depth in metres (sky = far)
    semantic: np.ndarray  # (H, W) uint8, CARLA ≥ 0.9.14 tag ids
    instance: np.ndarray  # (H, W) uint16, vehicle id (0 = static world and sky)


@dataclass(frozen=True)
class _NearProps:
    """The props within ``render_radius + NEAR_MARGIN`` of where the ego was (``ego``): a box within render_radius of
    the ego lies within that of a point less than NEAR_MARGIN away (1 m spare for rounding), so selecting from this
    subset gives the same boxes in order. ``table`` holds their boxes (the first ``n_boxes`` rows) and then, for a
    static world with meshes, the detailed primitives of those boxes, each with its box's row (``owner``)."""

    ego: np.ndarray
    table: Primitives
    n_boxes: int
    owner: np.ndarray | None
    diagonals: np.ndarray  # every row's half diagonal (the distance test reads the boxes', the view test all rows')

    @classmethod
    def select(cls, boxes: Primitives, detail: tuple | None, ego: np.ndarray, render_radius: float,
               detail_radius: float) -> _NearProps:  # fmt: skip
        keep = boxes.near_mask(ego, render_radius + NEAR_MARGIN)
        kept = np.flatnonzero(keep)
        owner = None
        parts = Primitives.empty()
        if detail is not None:
            local = np.full(len(keep), -1, np.int64)
            local[keep] = np.arange(len(kept))
            rows = local[detail[1]] >= 0
            owner = local[detail[1]][rows]
            parts = take_concat(detail[0], np.flatnonzero(rows), Primitives.empty())
        table = take_concat(boxes, kept, parts)  # the near boxes, then their parts (one gather, not 8 takes each)
        diagonals = np.linalg.norm(table.halves, axis=1)
        return cls(ego, table, len(kept), owner, diagonals)


class CameraRig:
    """Renders every camera of a :class:`~fog_gym.sensors.rig.RigConfig` (or of a sequence of
    :class:`~fog_gym.sensors.camera.CameraConfig`) from a :class:`Scene`."""

    def __init__(self, rig: Any, far: float = 1000.0, render_radius: float = 600.0) -> None:
        self.rig = rig
        cameras = tuple(rig.cameras if hasattr(rig, "cameras") else rig)
        self.far = float(far)
        self.render_radius = float(render_radius)
        # each camera's ground-plane view (position, yaw, half horizontal FOV), for culling props out of every view
        self._flat = all(c.pose.pitch == 0 and c.pose.roll == 0 for c in cameras)
        self._views = np.array([(c.pose.x, c.pose.y, np.radians(c.pose.yaw), np.radians(c.fov) / 2 + 0.02)
                                for c in cameras], np.float64).reshape(-1, 4)  # fmt: skip
        self.names = tuple(c.name for c in cameras)
        self.intrinsics = {c.name: c.intrinsic() for c in cameras}
        self.sensor_to_vehicle = {c.name: geometry.transform_matrix(c.pose.location, c.pose.rotation) for c in cameras}
        groups: dict[tuple[int, int], list] = {}
        for c in cameras:
            groups.setdefault((c.width, c.height), []).append(c)
        self._groups = list(groups.items())
        self._props_cache: tuple | None = None
        self._props_version = 0
        self._shadows: dict[tuple[int, int], ShadowCache] = {}  # per image size
        #: Props within this distance of the ego [m] are drawn as their meshes and parts, farther ones as their boxes.
        self.detail_radius = DETAIL_RADIUS
        self._near_cache: _NearProps | None = None
        self._lamps_cache: tuple | None = None
        #: Auto-exposure gain of each camera in the latest frame (1 by day).
        self.exposure: dict[str, float] = {}

    def world_to_camera(self, scene: Scene, name: str) -> np.ndarray:
        ego = geometry.yaw_transform(*scene.ego_pose)
        return geometry.world_to_camera(ego, self.sensor_to_vehicle[name])

    def _static_props(self, scene: Scene) -> tuple:
        """(static world, its props' boxes, geometry, their meshes and parts with owners or None), built once per
        static world and geometry."""
        if self._props_cache is None or self._props_cache[0] is not scene.static or self._props_cache[2] != scene.geometry:
            boxes = prop_primitives(scene.static.props)
            detail = prop_primitives(scene.static.props, True, owners=True) if scene.geometry == "meshes" else None
            self._props_cache = (scene.static, boxes, scene.geometry, detail)
            self._props_version += 1
            self._near_cache = None
        return self._props_cache

    def primitives(self, scene: Scene, in_view: bool = True) -> Primitives:
        """Render primitives near the ego: static props (cached per static world) + vehicles; with ``in_view`` only the
        props some camera can see (other sensors, the LiDAR's 360° sweep, take ``in_view=False``)."""
        every, seen = self.scene_primitives(scene)
        return seen if in_view else every

    def scene_primitives(self, scene: Scene) -> tuple[Primitives, Primitives]:
        """(every sensor's primitives, the cameras' ones): :meth:`primitives` of the scene with ``in_view`` False and
        True, from one selection of the props."""
        self._static_props(scene)
        ego = np.asarray(scene.ego_pose[:2], np.float64)
        near = self._near_cache
        if near is None or math.hypot(ego[0] - near.ego[0], ego[1] - near.ego[1]) > NEAR_MARGIN - 1.0:
            near = self._near_cache = _NearProps.select(self._props_cache[1], self._props_cache[3], ego,
                                                        self.render_radius, self.detail_radius)  # fmt: skip
        # a box is kept within render_radius of the ego (centre distance less its half diagonal), drawn as its
        # meshes and parts within detail_radius (when the static world has them); the cameras' rows are those some
        # view meets (fog_gym.render.prop_select)
        rows, seen = select_rows(near.table.centers, near.diagonals, near.n_boxes, near.owner, scene.ego_pose,
                                 self.render_radius, self.detail_radius, self._views if self._flat else None)  # fmt: skip
        every = take_concat(near.table, rows, scene.primitives)
        return every, (every if len(seen) == len(rows) else take_concat(near.table, seen, scene.primitives))

    def in_view(self, prims: Primitives, scene: Scene) -> Primitives:
        """``prims`` without the props no camera can see (vehicles are few and always kept)."""
        n_props = len(prims) - len(scene.primitives)
        if n_props <= 0:
            return prims
        props = prims.take(slice(0, n_props))
        return Primitives.concat(self._in_view(props, scene.ego_pose), scene.primitives)

    def _in_view(self, prims: Primitives, ego_pose: tuple[float, float, float]) -> Primitives:
        """``prims`` that some camera can see in the ground plane: a box is kept unless its bounding circle lies wholly
        outside every camera's horizontal field of view (cameras with pitch or roll keep everything)."""
        if not self._flat or len(prims) == 0:
            return prims
        return prims.take(self._view_mask(prims.centers, np.linalg.norm(prims.halves, axis=1) + 0.5, ego_pose))

    def _view_mask(self, centers: np.ndarray, radius: np.ndarray, ego_pose: tuple[float, float, float]) -> np.ndarray:
        """Which boxes (centres, bounding-circle radii) some camera can see (:meth:`_in_view`;
        :func:`fog_gym.render.view_cull.in_views`)."""
        return in_views(centers, radius, ego_pose, self._views)

    def render(self, scene: Scene, prims: Primitives | None = None) -> dict[str, CameraFrame]:
        """Every camera's buffers; ``prims`` defaults to :meth:`primitives` of the scene."""
        prims = self.primitives(scene) if prims is None else prims
        light = scene.lighting
        night = light.night
        if night:  # albedo pass, then street lamps, headlights and auto-exposure (fog_gym.render.lights)
            lut, ambient, sun = albedo_lut(), 1.0, 0.0
            heads, lights, ground = self.night_lights(scene)
        else:
            lut, ambient, sun = ground_lut(light), light.ambient, light.sun_intensity
        shadows = shade = None
        if not night and scene.geometry == "meshes":  # sun shadows on the ground: the props' (every one in reach,
            # seen or not; filled once per stretch of road) and the vehicles', the ego's own among them
            static = self._static_props(scene)[3][0]
            moving = Primitives.concat(scene.primitives, ego_primitives(scene))
            shade = shadow_lut(light)
        frames: dict[str, CameraFrame] = {}
        for (width, height), cams in self._groups:
            if shade is not None:  # shadow-map cells about a pixel wide 15 m away: 0.2 m at 1280 px, 0.8 m at 64 px;
                # the window 80 m around the ego, 40 m for the smallest images (where a car's shadow 40 m away
                # spans about three pixels)
                res = float(np.clip(0.2 * 1280.0 / width, 0.2, 0.8))
                half = float(np.clip(HALF * width / 256.0, HALF / 2, HALF))
                cache = self._shadows.setdefault((width, height), ShadowCache())
                shadows = cache.window(static, self._props_version, moving, light.sun_dir, scene.ego_pose[:2],
                                       half=half, resolution=res)  # fmt: skip
            mats = np.array([self.world_to_camera(scene, c.name) for c in cams])
            ks = np.array([[k[0, 0], k[1, 1], k[0, 2], k[1, 2]] for k in (self.intrinsics[c.name] for c in cams)])
            if night:
                out, gains = render_night(
                    mats[:, :3, :3], mats[:, :3, 3], ks, width, height, self.far, prims, tiled_surface(scene.static), lut,
                    SURFACE_TAGS, light.sky_horizon, light.sky_zenith, lights, ground, heads,
                )  # fmt: skip
            else:
                out = render(
                    mats[:, :3, :3], mats[:, :3, 3], ks, width, height, self.far, prims, tiled_surface(scene.static), lut,
                    SURFACE_TAGS, light.sky_horizon, light.sky_zenith, light.sun_dir, ambient, sun,
                    shadows=shadows, shadow_lut=shade,
                )  # fmt: skip
                gains = np.ones(len(cams))
            smooth = np.array([c.antialias for c in cams])
            if smooth.any():  # filtered ground (by day) and edge anti-aliasing; the other buffers stay point-sampled
                if not night:
                    filter_ground(out, smooth, mats[:, :3, :3], mats[:, :3, 3], ks, self.far, tiled_surface(scene.static),
                                  lut, shade, shadows, light.sky_horizon, light.sky_zenith)  # fmt: skip
                for i in np.flatnonzero(smooth):
                    out["rgb"][i] = antialias(out["rgb"][i], out["depth"][i], out["sem"][i], out["inst"][i])
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


@register(CameraConfig)
class CameraSensor:
    """One camera: channels ``C``, ``C_DEPTH`` (metres, sky = ``far``), ``C_SEM``; in the dataset also
    ``C_FOG_<LEVEL>`` and ``C_BBOX`` under ``c/out_rgb``, ``c/out_fog_<level>``, ``c/out_depth``, ``c/out_seg``,
    ``c/out_bbox`` (``c`` the name in lower case)."""

    kind = "camera"

    def __init__(self, config: CameraConfig, far: float = 1000.0) -> None:
        if not isinstance(config, CameraConfig):
            raise TypeError(f"config must be a CameraConfig, got {type(config).__name__}")
        self.config, self.far = config, float(far)
        self._rig: CameraRig | None = None

    @classmethod
    def build(cls, name: str, config: CameraConfig, simulation_frequency: float = 20.0, far: float = 1000.0):
        """The camera of the rig entry ``(name, config)`` (``name`` is ``config.name``)."""
        return cls(config, far)

    @property
    def channels(self) -> tuple[str, ...]:
        n = self.config.name
        return (n, f"{n}_DEPTH", f"{n}_SEM")

    def observation_spaces(self) -> dict[str, spaces.Space]:
        shape = (self.config.height, self.config.width)
        rgb, depth, sem = self.channels
        return {rgb: spaces.Box(0, 255, shape + (3,), np.uint8), depth: spaces.Box(0.0, self.far, shape, np.float32),
                sem: spaces.Box(0, MAX_TAG, shape, np.uint8)}  # fmt: skip

    def layout(self) -> dict[str, ChannelSpec]:
        n, folder = self.config.name, self.config.name.lower()
        out = {n: ChannelSpec(f"{folder}/out_rgb", "png", "rgb")}
        for lv in FOG_LEVELS:
            out[f"{n}_FOG_{lv}"] = ChannelSpec(f"{folder}/out_fog_{lv.lower()}", "png", "rgb")
        out[f"{n}_DEPTH"] = ChannelSpec(f"{folder}/out_depth", "png", "depth")
        out[f"{n}_SEM"] = ChannelSpec(f"{folder}/out_seg", "png", "semantic")
        out[f"{n}_BBOX"] = ChannelSpec(f"{folder}/out_bbox", "json", "box2d")
        return out

    def measure(self, scene: Scene, prims: Primitives, rng: np.random.Generator, tick: int) -> dict[str, np.ndarray]:
        """The camera's RGB, depth and tags (``rng`` and ``tick`` unused: rendering is deterministic)."""
        if self._rig is None:
            self._rig = CameraRig((self.config,), far=self.far)
        f = self._rig.render(scene, prims)[self.config.name]
        return dict(zip(self.channels, (f.rgb, f.depth, f.semantic)))



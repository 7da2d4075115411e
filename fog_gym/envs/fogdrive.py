"""``FogDrive-v0``: a highway-env traffic world lifted into 3D, seen through the FogDrive camera rig.

Example:
    >>> import gymnasium as gym, fog_gym
    >>> env = gym.make("FogDrive-v0", town="roundabout", resolution=(64, 48))
    >>> obs, info = env.reset(seed=0)
    >>> obs["CAM_FRONT"].shape, obs["CAM_FRONT_DEPTH"].dtype, obs["CAM_FRONT_SEM"].dtype
    ((48, 64, 3), dtype('float32'), dtype('uint8'))
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from fog_gym.envs.config import FogDriveConfig
from fog_gym.envs.warmup import ensure_compiled, path_of
from fog_gym.world.hazards import HazardConfig, hazard_info
from fog_gym.sensors.rig import RigConfig
from fog_gym import geometry as geo
from fog_gym.dataset.layout import extrinsic_key
from fog_gym.labels.boxes import CameraView, LabelConfig, annotate
from fog_gym.geometry import sensor_to_world
from fog_gym.world.scene import Lighting, Scene, StaticWorld, town_static_world, vehicle_primitives
from fog_gym.world.scenery import STYLES, build_surface, place_props
from fog_gym.channels.packing import SEMANTIC_LIDAR, pack_points
from fog_gym.sensors import CameraFrame, CameraRig, PointSensors, rig_layout, rig_sensors
from fog_gym.sensors.camera import CameraConfig
from fog_gym.sensors.camera_effects import CameraEffects
from fog_gym.sensors.camera_noise import parse_noise
from fog_gym.world.fleet import EGO_ID
from fog_gym.world.traffic_world import make_world
from fog_gym.world.towns import TOWN_SPECS
from fog_gym.seeds import stream

MAX_SPEED = 40.0  # highway-env's Vehicle.MAX_SPEED [m/s]: bounds where the ego can get in one episode


class FogDriveEnv(gym.Env):
    """The FogDrive rig in a highway-env world. Observation: a flat ``Dict`` keyed by FogDrive channel names.

    The channels follow the rig (:class:`RigConfig`, a sequence of named sensors). For each camera ``C`` of the
    rig (the FogDrive four, or any added one): ``C`` (H, W, 3) uint8 RGB, ``C_DEPTH`` (H, W) float32 planar depth in
    metres (sky = 1000), ``C_SEM`` (H, W) uint8 CARLA ≥ 0.9.14 tag ids. Point sensors, as fixed-capacity float32
    arrays (points first, zero rows after; :func:`fog_gym.unpack_points` gives the exact (N, C) array):
    ``LIDAR_TOP`` (x, y, z, intensity), ``SEM_LIDAR_TOP`` (x, y, z, cos incidence, object id, tag),
    ``RADAR_FRONT`` (velocity, azimuth, altitude, depth), and each added point sensor's channel. Instance ids per camera are in
    :attr:`instance_buffers` (not a FogDrive channel). Actions, reward and termination are highway-env's.

    Arguments (all optional): ``town`` (one of :data:`fog_gym.TOWNS`), ``time_of_day`` ("day"/"night"),
    ``resolution`` (W, H) for every camera, ``cameras`` (subset of camera names), ``rig`` (a full
    :class:`RigConfig`), ``episode_seconds``, ``simulation_frequency``, ``keyframe_frequency``,
    ``highway_config`` (highway-env config overrides), ``traffic`` ("fast", the default traffic core, or
    "reference", highway-env's own Python path; same trajectories), ``hazards`` (a :class:`HazardConfig`: stalled
    vehicles ahead of the ego at every reset; ``info["hazards"]`` then holds, per stalled vehicle (the first
    ``info["hazard_count"]`` rows of a fixed ``(capacity, 4)`` array, zeros after), its offset from the
    ego in metres ahead and to the right, its length and width), ``geometry`` ("boxes" or "meshes": what the sensors
    see of vehicles and props, :mod:`fog_gym.world.bodies`, :mod:`fog_gym.world.prop_meshes`), ``lidar_intensity``
    ("carla", FogDrive's distance model, or "reflectance": the surface's reflectivity × incidence × range loss),
    ``lidar_returns`` ("strongest", FogDrive's; "last"; or "dual": both echoes with a ``return`` column — the LiDAR's
    channels are then ``LIDAR_TOP_LAST`` / ``LIDAR_TOP_DUAL`` and their fog variants, :mod:`fog_gym.fog.returns`),
    ``lidar_motion`` ("instant", FogDrive's; or "continuous": each azimuth fires at its time within the sweep, points
    carry a ``time`` column and the channels are ``LIDAR_TOP_MOTION`` …, :mod:`fog_gym.sensors.motion`),
    ``camera_noise`` (None, the default: noise-free frames; "default" or a
    :class:`~fog_gym.sensors.camera_noise.CameraNoise`: every camera records with shot and read noise, a gain that
    follows its auto-exposure and, if asked, motion blur; :attr:`frames` keep the noise-free images),
    ``antialias`` (True: every camera's RGB with filtered ground and edge anti-aliasing, :mod:`fog_gym.render.antialias`;
    depth and semantics stay point-sampled), or ``config`` (a complete :class:`FogDriveConfig`).

    Public attributes (what wrappers and tools may use): ``config`` (the validated :class:`FogDriveConfig`),
    ``episode_seed`` (set by ``reset``; every random stream of the episode derives from it), ``scene`` (the
    latest :class:`~fog_gym.world.scene.Scene`), ``frames`` (the latest :class:`~fog_gym.sensors.CameraFrame` per
    camera), ``points`` (the latest ``(N, C)`` sweep per point sensor), :attr:`camera_names`, :attr:`intrinsics`,
    :attr:`instance_buffers`, :attr:`idle_action`, :meth:`ground_truth`, ``cameras`` (the
    :class:`~fog_gym.sensors.CameraRig`), ``sensors`` (every sensor, rig order), ``point_sensors`` and ``world`` (the :class:`~fog_gym.world.traffic_world.TrafficWorld`).

    >>> env = FogDriveEnv(town="merge", resolution=(32, 24), cameras=["CAM_FRONT"])
    >>> sorted(env.observation_space.spaces)
    ['CAM_FRONT', 'CAM_FRONT_DEPTH', 'CAM_FRONT_SEM', 'LIDAR_TOP', 'RADAR_FRONT', 'SEM_LIDAR_TOP']
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(
        self,
        town: str | None = None,
        time_of_day: str | None = None,
        resolution: Sequence[int] | None = None,
        cameras: Sequence[str] | None = None,
        rig: RigConfig | None = None,
        episode_seconds: float | None = None,
        simulation_frequency: int | None = None,
        keyframe_frequency: int | None = None,
        highway_config: dict[str, Any] | None = None,
        visibility: str | None = None,
        labels: LabelConfig | None | str = "default",
        config: FogDriveConfig | None = None,
        render_mode: str | None = None,
        traffic: str | None = None,
        hazards: HazardConfig | None = None,
        static_world: str | None = None,
        geometry: str | None = None,
        lidar_intensity: str | None = None,
        lidar_returns: str | None = None,
        lidar_motion: str | None = None,
        camera_noise: Any = None,
        antialias: bool | None = None,
        world: Any = None,
    ) -> None:
        cfg = config if config is not None else FogDriveConfig()
        if not isinstance(cfg, FogDriveConfig):
            raise ValueError(f"config must be a FogDriveConfig, got {type(cfg).__name__}")
        rig_cfg = rig if rig is not None else cfg.rig
        if cameras is not None:
            if isinstance(cameras, str):
                raise ValueError(f"cameras must be a sequence of camera names, got the string {cameras!r}")
            rig_cfg = replace(rig_cfg, cameras=tuple(_camera(rig_cfg, n) for n in cameras))
        if resolution is not None:
            rig_cfg = rig_cfg.with_resolution(resolution)
        for name, value in (("intensity", lidar_intensity), ("returns", lidar_returns), ("motion", lidar_motion)):
            # intensity "reflectance": reflectivity × incidence × range loss; returns "last" / "dual": the echoes a
            # beam reports in fog (fog_gym.sensors.lidar, fog_gym.fog.returns)
            if value is None:
                continue
            if rig_cfg.lidar is None:
                raise ValueError(f"lidar_{name} needs a rig with a LiDAR")
            lidar = replace(rig_cfg.lidar, **{name: value})  # checked by LidarConfig
            rig_cfg = RigConfig(tuple((n, lidar if c is rig_cfg.lidar else c) for n, c in rig_cfg.sensors))
        camera_updates: dict[str, Any] = {}
        if camera_noise is not None:  # every camera of the rig records through this sensor (None keeps the rig's)
            camera_updates["noise"] = parse_noise(camera_noise)
        if antialias is not None:  # every camera anti-aliased, or none (None keeps the rig's)
            camera_updates["antialias"] = antialias  # checked by CameraConfig
        if camera_updates:
            rig_cfg = RigConfig(tuple((n, replace(c, **camera_updates) if isinstance(c, CameraConfig) else c)
                                      for n, c in rig_cfg.sensors))  # fmt: skip
        label_cfg = cfg.labels if isinstance(labels, str) and labels == "default" else labels
        if visibility is not None:
            label_cfg = replace(label_cfg if label_cfg is not None else LabelConfig(), visibility=visibility)
        updates = {
            k: v
            for k, v in dict(
                town=town, time_of_day=time_of_day, episode_seconds=episode_seconds,
                simulation_frequency=simulation_frequency, keyframe_frequency=keyframe_frequency,
                highway_config=highway_config, traffic=traffic, hazards=hazards, static_world=static_world,
                geometry=geometry,
            ).items()
            if v is not None
        }  # fmt: skip
        self.config = replace(cfg, rig=rig_cfg, labels=label_cfg, **updates)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}")
        self.render_mode = render_mode

        c = self.config
        self.metadata = {**self.metadata, "render_fps": c.keyframe_frequency}
        ensure_compiled(*path_of(c))
        # ``world``: a prebuilt world (a vector env's view of its shared traffic core); else one of its own
        self.world = world if world is not None else make_world(c.town, c.simulation_frequency, c.keyframe_frequency,
                                                                c.episode_seconds, dict(c.highway_config),
                                                                traffic=c.traffic, hazards=c.hazards)  # fmt: skip
        self.cameras = CameraRig(c.rig, far=c.far_distance)
        #: Motion blur and sensor noise of the cameras that have them (falsy when none has: noise-free frames).
        self.camera_effects = CameraEffects(c.rig.cameras)
        self._recording: Any = None  # the frame's camera noise under way (CameraEffects.begin), until _recorded
        self.action_space = self.world.action_space
        rig_layout(c.rig)  # channel or folder clashes between the rig's sensors fail here, before any work
        #: Every sensor of the rig, in rig order (the observation's channels are theirs).
        self.sensors = rig_sensors(c.rig, c.simulation_frequency, c.far_distance)
        obs_spaces: dict[str, spaces.Space] = {}
        for sensor in self.sensors:
            obs_spaces.update(sensor.observation_spaces())
        self.point_sensors = PointSensors(c.rig, c.simulation_frequency)
        # ground truth lives in the LiDAR frame (FogDrive's 3D boxes); the FogDrive roof pose if the rig has no LiDAR
        label_lidar = c.rig.lidar or c.rig.semantic_lidar
        self._mounts: dict[str, np.ndarray] = {}  # channel → its sensor's frame → vehicle (sensor_to_world)
        self._label_lidar_to_vehicle = sensor_to_world(label_lidar.pose if label_lidar else (0.0, 0.0, 2.0))
        self._extrinsics = {
            cam.name: geo.lidar_to_camera(self._label_lidar_to_vehicle, self.cameras.sensor_to_vehicle[cam.name])
            for cam in c.rig.cameras
        }
        self.observation_space = spaces.Dict(obs_spaces)
        self.scene: Scene | None = None
        self.frames: dict[str, CameraFrame] = {}
        self.points: dict[str, np.ndarray] = {}  # the latest sweep of each point sensor, (N, C) float32
        self._packed: dict[str, np.ndarray] = {}  # the point channels of the latest observation, as packed here
        self._static: StaticWorld | None = None
        self._lighting: Lighting | None = None
        self._steps = 0
        self.episode_seed: int | None = None

    @staticmethod
    def episode_seed_for(seed: int) -> int:
        """The :attr:`episode_seed` that ``reset(seed=seed)`` draws (the world's highway-env seed; every random
        stream of the episode derives from it)."""
        from gymnasium.utils import seeding

        return int(seeding.np_random(seed)[0].integers(0, 2**31 - 1))

    # -- Gymnasium API --------------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        world_seed = int(self.np_random.integers(0, 2**31 - 1))  # = episode_seed_for(seed) when a seed is given
        self.episode_seed = world_seed  # everything random in the episode derives from it (fog noise too)
        self.world.reset(seed=world_seed)
        self.action_space = self.world.action_space
        rng = stream(world_seed, "scenery")
        self._static = self.town_static_world() if self.config.static_world == "town" else self.build_static_world(rng)
        self._lighting = Lighting.for_time_of_day(self.config.time_of_day, rng)
        self._sensor_rng = stream(world_seed, "sensors")
        self._noise_seed = int(stream(world_seed, "camera_noise").integers(0, 2**63 - 1))
        self._steps = 0
        obs = self._observe(overlap=True)
        info = self._info({})
        return self._recorded(obs), info

    def step(self, action: Any):
        if self.scene is None:
            raise RuntimeError("call reset() before step()")
        reward, terminated, hw_info = self.world.step(action)
        self._steps += 1
        truncated = self._steps >= self.config.episode_steps and not terminated
        obs = self._observe(overlap=True)
        info = self._info(hw_info)
        return self._recorded(obs), reward, terminated, truncated, info

    def render(self) -> np.ndarray | None:
        if self.render_mode != "rgb_array" or self.scene is None:
            return None
        from fog_gym.render.birds_eye import birds_eye_view, composite

        front = self.frames.get("CAM_FRONT") or next(iter(self.frames.values()), None)
        return composite(None if front is None else front.rgb, birds_eye_view(self.scene))

    def close(self) -> None:
        self.world.close()

    # -- internals ------------------------------------------------------------------------------------
    def build_static_world(self, rng: np.random.Generator) -> StaticWorld:
        """The episode's static world (road surface map and props) around the world's start, drawn from ``rng``
        (what ``reset`` builds from the episode's scenery stream)."""
        radius = MAX_SPEED * self.config.episode_seconds + 250.0
        lanes = self.world.lane_geometry(self.world.start_position, radius)
        surface = build_surface(lanes, resolution=self.config.surface_resolution)
        props = place_props(lanes, surface, rng, STYLES[TOWN_SPECS[self.config.town].scenery])
        return StaticWorld.build(surface, props)

    def town_static_world(self) -> StaticWorld:
        """The town's static world (:func:`fog_gym.world.scene.town_static_world`), built once per process."""
        c = self.config
        lanes_count = dict(c.highway_config).get("lanes_count", TOWN_SPECS[c.town].config.get("lanes_count"))
        return town_static_world(self.world, c.town, lanes_count, c.surface_resolution,
                                 MAX_SPEED * c.episode_seconds + 250.0)  # fmt: skip

    def build_scene(self) -> Scene:
        """The :class:`Scene` of the world's current state (what every sensor sees)."""
        state = self.world.vehicle_state()
        prev = self.scene if self._steps > 0 else None  # the keyframe before, within the episode
        return Scene(
            time=self.world.time,
            ego_id=EGO_ID,
            ego_pose=self.world.ego_pose,
            vehicles=state,
            static=self._static,
            lighting=self._lighting,
            primitives=vehicle_primitives(state, self._lighting.night, exclude_id=EGO_ID,  # never see the own body
                                          meshes=self.config.geometry == "meshes"),
            geometry=self.config.geometry,
            previous=None if prev is None or not prev.time < self.world.time else (prev.time - self.world.time, prev.vehicles),
        )

    def _observe(self, overlap: bool = False) -> dict[str, np.ndarray]:
        """The observation of the world's current state. With ``overlap``, cameras with noise record on the
        background thread while the points (and the caller's labels) are computed: their entries hold the
        noise-free images until :meth:`_recorded` puts in what they recorded."""
        self.scene = self.build_scene()
        prims, seen = self.cameras.scene_primitives(self.scene)  # every sensor's world, and what the cameras see
        self.frames = self.cameras.render(self.scene, seen)
        fx = self.camera_effects
        obs: dict[str, np.ndarray] = {}
        for name, f in self.frames.items():
            obs[name] = f.rgb
            obs[f"{name}_DEPTH"] = f.depth
            obs[f"{name}_SEM"] = f.semantic
        if fx:
            fx.prepare(self._noise_seed, self._steps, self.cameras.exposure, self.scene.lighting.night, self._flows())
            self._recording = fx.begin({name: f.rgb for name, f in self.frames.items()}, 0, overlap=overlap)
        tick = max(self.world.tick - 1, 0)  # the simulation tick this keyframe closes
        self.points = self.point_sensors.measure(self.scene, prims, self._sensor_rng, tick)
        for name, pts in self.points.items():
            obs[name] = pack_points(pts, self.observation_space[name].shape[0])
        self._packed = {name: obs[name] for name in self.points}
        return obs if overlap else self._recorded(obs)

    def _recorded(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """``obs`` with the cameras' recorded images of this frame (waiting for the background thread's noise)."""
        if self._recording is not None:
            recording, self._recording = self._recording, None
            obs.update(recording())
        return obs

    def _flows(self) -> dict[str, tuple]:
        """The arguments of :func:`~fog_gym.sensors.motion_blur.image_flow` (but the exposure) of each camera with
        motion blur: depth, instance ids, intrinsics, pose, world velocity by instance id and the ego's velocity."""
        blurred = [n for n, noise in self.camera_effects.noise.items() if noise.motion_blur and n in self.frames]
        if not blurred:
            return {}
        state = self.scene.vehicles
        velocities = np.zeros((max(int(state.ids.max(initial=0)), 0) + 1, 3))
        velocities[state.ids] = state.velocities
        ego = velocities[self.scene.ego_id]
        return {n: (self.frames[n].depth, self.frames[n].instance, self.intrinsics[n], self.sensor_to_world(n),
                    velocities, ego) for n in blurred}  # fmt: skip

    def camera_record(self, name: str, rgb: np.ndarray, variant: int) -> np.ndarray:
        """What camera ``name`` records of the noise-free image ``rgb`` of this frame (the clean frame, ``variant``
        0, or a fogged version of it, its own integer): motion blur and noise when the camera has them
        (:mod:`fog_gym.sensors.camera_effects`), else ``rgb`` itself."""
        return self.camera_effects.apply(name, rgb, variant)

    def _info(self, hw_info: dict) -> dict[str, Any]:
        info = {
            "town": self.config.town,
            "town_number": self.config.town_number,
            "time_of_day": self.config.time_of_day,
            "sim_time": self.world.time,
            "step": self._steps,
            "speed": self.world.ego_speed,
            "crashed": self.world.ego_crashed,
        }
        for sensor in self.point_sensors.sensors:  # a sweep that takes time: the ego's poses it was cast from
            if getattr(sensor, "ego_poses", None) is not None:
                info["lidar_ego_poses"] = sensor.ego_poses  # (S + 1, 4): t, x, y, yaw (fog_gym.sensors.deskew)
        if self.config.hazards is not None:
            info.update(hazard_info(self.world.hazards_ego(), self.config.hazards))
        if "rewards" in hw_info:
            info["rewards"] = {k: float(v) for k, v in hw_info["rewards"].items()}
        if self.config.labels is not None:
            info.update(self.ground_truth())
        return info

    def ground_truth(self, labels: LabelConfig | None = None) -> dict[str, Any]:
        """``boxes_3d``, ``boxes_2d`` (per camera), ``intrinsics`` and ``extrinsics`` of the current frame, under the
        env's label config or, for this call only, ``labels`` (a :class:`LabelConfig`; the env is not changed)."""
        if labels is not None and not isinstance(labels, LabelConfig):
            raise ValueError(f"labels must be a LabelConfig or None, got {type(labels).__name__}")
        label_cfg = labels if labels is not None else self.config.labels
        if label_cfg is None:
            raise ValueError("this env was built with labels=None: pass labels=LabelConfig(...)")
        if self.scene is None:
            raise RuntimeError("call reset() before ground_truth()")
        scene, rig = self.scene, self.config.rig
        ego_to_world = geo.yaw_transform(*scene.ego_pose)
        world_to_lidar = np.linalg.inv(ego_to_world @ self._label_lidar_to_vehicle)
        views = [
            CameraView(c.name, self._extrinsics[c.name], self.cameras.intrinsics[c.name], c.width, c.height,
                       self.frames[c.name].instance)  # fmt: skip
            for c in rig.cameras
        ]
        v = scene.vehicles
        others = v.ids != scene.ego_id
        sem = self.points.get(SEMANTIC_LIDAR)
        boxes_3d, boxes_2d = annotate(v.ids[others], v.classes[others], v.centers[others], v.sizes[others],
                                      v.yaws[others], v.velocities[others], world_to_lidar, views, sem,
                                      label_cfg)  # fmt: skip
        boxes_3d, boxes_2d = self._visibility_labels(boxes_3d, boxes_2d, world_to_lidar)
        return {
            "boxes_3d": boxes_3d,
            "boxes_2d": boxes_2d,
            "intrinsics": {c.name: self.cameras.intrinsics[c.name].copy() for c in rig.cameras},
            "extrinsics": {extrinsic_key(c.name): self._extrinsics[c.name].copy() for c in rig.cameras},
        }

    def _visibility_labels(self, boxes_3d: Any, boxes_2d: dict[str, Any], world_to_lidar: np.ndarray) -> tuple[Any, dict]:
        """Per 3D box the clean LiDAR's and the radar's points inside it (``num_lidar_pts``, ``num_radar_pts``), per
        2D box its intrinsic contrast against its background (``contrast``; :mod:`fog_gym.labels.visibility`)."""
        from fog_gym.labels.visibility import box_contrast, points_in_boxes, radar_xyz

        def in_boxes(channel: str, pts: np.ndarray, margin: float) -> np.ndarray:
            m = world_to_lidar @ self.sensor_to_world(channel)
            p = pts[:, :3] @ m[:3, :3].T + m[:3, 3]
            return points_in_boxes(p, boxes_3d["center"], boxes_3d["size"], boxes_3d["yaw"], margin)

        lidar = next((s.channel for s in self.sensors if getattr(s, "kind", "") == "lidar"), None)
        radar = next((s.channel for s in self.sensors if getattr(s, "kind", "") == "radar"), None)
        n = len(boxes_3d["vehicle_ids"])
        zeros = np.zeros(n, np.int64)
        boxes_3d = boxes_3d.with_fields(
            num_lidar_pts=in_boxes(lidar, self.points[lidar], 0.0) if lidar and n else zeros,
            # radar detections lie on the surface; a margin of 0.2 m keeps them from rounding out of the box
            num_radar_pts=in_boxes(radar, radar_xyz(self.points[radar]), 0.2) if radar and n else zeros)  # fmt: skip
        out = {}
        for cam, b in boxes_2d.items():
            frame = self.frames.get(cam)
            c = (box_contrast(frame.rgb, frame.instance, b["bboxes"], b["vehicle_ids"])
                 if frame is not None and frame.instance is not None and len(b["vehicle_ids"]) else np.zeros(len(b["vehicle_ids"])))  # fmt: skip
            out[cam] = b.with_fields(contrast=c)
        return boxes_3d, out

    def point_rows(self, obs: dict[str, np.ndarray]) -> dict[str, int]:
        """Per point channel of ``obs`` that is the very array this env packed for its latest observation, the number
        of its leading rows that are points (the rest are zero): a reader takes them without scanning the channel
        (the LiDAR fog). A channel a wrapper replaced is not listed."""
        return {name: len(self.points[name]) for name, packed in self._packed.items() if obs.get(name) is packed}

    def sensor_to_world(self, channel: str) -> np.ndarray:
        """4×4 transform of the sensor that fills ``channel`` at the current frame: a camera's optical frame (x right,
        y down, z forward: what its intrinsics project) → world, or a point sensor's own frame → world."""
        if self.scene is None:
            raise RuntimeError("call reset() before sensor_to_world()")
        mount = self._mounts.get(channel)
        if mount is None:  # the sensor's frame → vehicle: fixed for the rig, found once per channel
            if channel in self.cameras.sensor_to_vehicle:
                mount = self.cameras.sensor_to_vehicle[channel] @ np.linalg.inv(geo.SENSOR_TO_CAMERA)
            else:
                sensor = next((s for s in self.sensors if channel in s.channels), None)
                if sensor is None:
                    raise ValueError(f"no sensor of this rig fills channel {channel!r}; channels: "
                                     f"{list(self.observation_space)}")  # fmt: skip
                mount = sensor_to_world(sensor.config.pose)
            self._mounts[channel] = mount
        return geo.yaw_transform(*self.scene.ego_pose) @ mount

    @property
    def idle_action(self) -> Any:
        """The action that keeps lane and speed: highway-env's ``IDLE`` meta-action (1), zeros if continuous."""
        space = self.action_space
        return 1 if space.shape == () else np.zeros(space.shape, space.dtype)

    @property
    def camera_names(self) -> tuple[str, ...]:
        """The rig's camera names, in rig order."""
        return self.cameras.names

    @property
    def intrinsics(self) -> dict[str, np.ndarray]:
        """Each camera's 3×3 intrinsic matrix K (pixel centres at +0.5; CARLA's pinhole)."""
        return self.cameras.intrinsics

    def ego_pose_record(self) -> dict[str, Any]:
        """The ego's pose at the current frame as the dataset writer stores it (:mod:`fog_gym.dataset.poses`):
        ``translation`` and ``yaw`` of the ego origin (ground under its centre) and its ``velocity``, in the world
        frame (CARLA's axes), and ``lidar_to_ego``, the 4×4 mount of the LiDAR whose frame the 3D boxes use."""
        if self.scene is None:
            raise RuntimeError("call reset() before ego_pose_record()")
        x, y, yaw = self.scene.ego_pose
        v = self.scene.vehicles
        velocity = v.velocities[v.ids == self.scene.ego_id][0]
        return {"translation": (x, y, 0.0), "yaw": yaw, "velocity": tuple(float(c) for c in velocity),
                "lidar_to_ego": self._label_lidar_to_vehicle.copy()}  # fmt: skip

    @property
    def instance_buffers(self) -> dict[str, np.ndarray]:
        """Per-camera instance ids of the latest frame (vehicle id; 0 = static world and sky)."""
        return {name: f.instance for name, f in self.frames.items()}


def _camera(rig: RigConfig, name: str):
    """The camera ``name`` of the rig, or a FogDrive camera at the rig's camera size (``cameras=`` of the env)."""
    from fog_gym.sensors.camera import CAMERA_NAMES, FOGDRIVE_CAMERA_POSES, CameraConfig

    known = tuple(dict.fromkeys((*CAMERA_NAMES, *(c.name for c in rig.cameras))))
    if name not in known:
        raise ValueError(f"camera name must be one of {known}, got {name!r}")
    try:
        return rig.camera(name)
    except KeyError:
        ref = rig.cameras[0] if rig.cameras else None
        return CameraConfig(name, FOGDRIVE_CAMERA_POSES[name], *((ref.width, ref.height, ref.fov, ref.noise, ref.antialias) if ref else ()))

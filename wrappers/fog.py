"""``FogWrapper``: calibrated fog on FogDrive-v0's cameras and LiDAR, in place or paired with the clean data."""

from __future__ import annotations

import functools
import math
import zlib
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np

from fog_gym.fog import FogLevel, atmospheric_light, night_airlight, parse_fog
from fog_gym.fog.fields import field_info, field_json, world_optical_depth
from fog_gym.fog.models import FogContext, model_for
from fog_gym.fog.physics import FogField
from fog_gym.geometry import yaw_transform
from fog_gym.seeds import stream

FogSpec = str | float | int | FogField


def parse_fog_levels(fog: FogSpec | Sequence[FogSpec]) -> tuple[tuple[FogField, ...], bool]:
    """``(levels, paired)``: one level or fog field (in place) or a list of distinct ones (paired; fields beside
    level names, each named by its ``name``). Errors before any work."""
    if isinstance(fog, (list, tuple)):
        if not fog:
            raise ValueError("fog list must name at least one level, e.g. ['light', 'moderate', 'dense']")
        levels = tuple(parse_fog(f) for f in fog)
        names = [lv.name for lv in levels]
        if len(set(names)) != len(names):
            raise ValueError(f"fog list must not repeat a level or field name, got {names!r} (fields take name=...)")
        if any(lv.is_clear for lv in levels):
            raise ValueError("fog list (paired mode) holds fog levels; the clean channels are kept anyway, drop 'clear'")
        return levels, True
    return (parse_fog(fog),), False


class FogWrapper(gym.Wrapper):
    """Fog on camera RGB (Koschmieder) and LiDAR (Hahner et al.) at any visibility; ground truth untouched.

    The fogged channels follow the rig: every sensor whose kind has a fog model (:mod:`fog_gym.fog.models`) —
    every camera, added ones included, and every LiDAR.

    * **In place** (``fog`` a single level: "clear", "light" 160 m, "moderate" 100 m, "dense" 50 m, or metres):
      fogged ``CAM_*`` RGB and ``LIDAR_TOP`` replace the clean data under the same keys; the observation space
      does not depend on the level, so :meth:`set_fog` can change it between episodes (curricula).
    * **Paired** (``fog`` a list): the clean channels stay and ``CAM_*_FOG_<LEVEL>`` and ``LIDAR_TOP_FOG_<LEVEL>``
      are added, all from the same render — FogDrive's pairing.

    Depth, semantic camera, semantic LiDAR, radar and ground truth are never changed; each box gains a
    ``transmittance``: ``exp(−α·d)`` camera → box centre in ``boxes_2d``, the LiDAR's two-way ``exp(−2α·d)`` in
    ``boxes_3d`` (paired: one array per level name). ``info["fog"]`` reports
    ``{"visibility_m": V, "alpha": α}`` (paired: one such dict per level name). The atmospheric light is
    estimated once per episode per camera from the first clean frame (dark channel, top 0.1 %, median grey),
    or fixed with ``airlight=(r, g, b)``. LiDAR fog noise comes from a generator seeded by the episode and level.

    >>> import fog_gym
    >>> env = FogWrapper(fog_gym.FogDriveEnv(town="merge", resolution=(32, 24), cameras=["CAM_FRONT"]), "dense")
    >>> obs, info = env.reset(seed=0)
    >>> info["fog"]["visibility_m"]
    50.0
    """

    def __init__(self, env: gym.Env, fog: FogSpec | Sequence[FogSpec] = "dense", airlight: str | Sequence[float] = "estimate",
                 lidar_noise: float = 10.0) -> None:  # fmt: skip
        levels, paired = parse_fog_levels(fog)
        if isinstance(airlight, str):
            if airlight != "estimate":
                raise ValueError(f"airlight must be 'estimate' or an (r, g, b) triple in 0–255, got {airlight!r}")
            fixed = None
        else:
            fixed = np.asarray(airlight, np.float64)
            if fixed.shape != (3,) or not np.all(np.isfinite(fixed)) or fixed.min() < 0 or fixed.max() > 255:
                raise ValueError(f"airlight must be 'estimate' or an (r, g, b) triple in 0–255, got {airlight!r}")
        if not math.isfinite(lidar_noise) or lidar_noise < 0:
            raise ValueError(f"lidar_noise must be >= 0 metres, got {lidar_noise!r}")
        super().__init__(env)
        base = env.unwrapped
        if not hasattr(base, "intrinsics") or not hasattr(base, "episode_seed"):
            raise ValueError("FogWrapper wraps a FogDrive-v0 environment")
        self.levels, self.paired = levels, paired
        self._fixed_airlight, self.lidar_noise = fixed, float(lidar_noise)
        self._pending: FogLevel | None = None
        self._last: dict | None = None
        self._fog_lidar: tuple[str, dict[str, np.ndarray]] | None = None
        self.cameras = list(base.camera_names)
        # the fogged channels and their models, from the rig in rig order: each sensor's first channel (a camera's
        # RGB, a LiDAR's points) gets the model of its kind (fog_gym.fog.models); kinds without one stay clean
        self.models = {}
        for sensor in base.sensors:
            model = model_for(sensor.kind)
            if model is not None and sensor.channels[0] in env.observation_space.spaces:
                self.models[sensor.channels[0]] = model
        self.has_lidar = any(model_for("lidar") is m for m in self.models.values())
        self.airlight: dict[str, np.ndarray] = {}
        self._rngs: dict[str, np.random.Generator] = {}
        #: The field frame (x0, y0, heading) of the episode and its start time, set at reset while a fog field is in force.
        self.field_frame, self._t0 = (0.0, 0.0, 0.0), 0.0
        if paired:
            spaces = dict(env.observation_space.spaces)
            for lv in levels:
                for ch in self.models:
                    spaces[f"{ch}_{lv.channel_suffix}"] = env.observation_space[ch]
            self.observation_space = gym.spaces.Dict(spaces)

    # -- API ------------------------------------------------------------------------------------------------
    @property
    def fog(self) -> FogLevel | tuple[FogLevel, ...]:
        """The level in force (in place) or the levels (paired)."""
        return self.levels if self.paired else self.levels[0]

    @property
    def next_fog(self) -> FogLevel | None:
        """The level :meth:`set_fog` asked for the next ``reset`` (None: keep the current one). Assigning a level
        (or None for no change) is ``set_fog``; vector envs reach it per sub-env with ``set_attr("next_fog", [...])``."""
        return self._pending

    @next_fog.setter
    def next_fog(self, fog: FogSpec | None) -> None:
        if fog is not None:
            self.set_fog(fog)

    def set_fog(self, fog: FogSpec) -> None:
        """Change the level from the next ``reset`` on (in-place mode). Reachable via ``env_method``."""
        if self.paired:
            raise ValueError("set_fog works in in-place mode; a paired wrapper's channels are fixed at construction")
        self._pending = parse_fog(fog)

    def fog_channels(self, obs: dict) -> dict[str, dict[str, np.ndarray]]:
        """The fogged camera RGB and LiDAR channels of the env's clean ``obs`` at every level in force, by level
        name (what ``step`` adds; the LiDAR noise draws advance as in a step)."""
        return self._fogged(obs, self.levels)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        if self._pending is not None:
            self.levels, self._pending = (self._pending,), None
        obs, info = self.env.reset(seed=seed, options=options)
        base = self.env.unwrapped
        night = base.scene is not None and base.scene.lighting.night  # night: the fog is lit by the scene's lights
        clean, _ = self._clean_rgb(obs)
        obs_clean = {**obs, **clean}  # the airlight of the light itself, not of a noisy recording of it
        self.airlight = {
            cam: self._fixed_airlight if self._fixed_airlight is not None
            else night_airlight(obs_clean[cam], obs[f"{cam}_DEPTH"]) if night else atmospheric_light(obs_clean[cam])
            for cam in self.cameras
        }
        self._rngs = {
            lv.name: stream(base.episode_seed, "fog", _level_key(lv))
            for lv in self.levels
        }
        # the field frame (homogeneous fog needs none, but a dataset of fields records it for every level)
        self.field_frame, self._t0 = self._frame_at_reset(base), base.scene.time if base.scene is not None else 0.0
        return self._apply(obs), self._info(info)

    def step(self, action: Any):
        obs, reward, terminated, truncated, info = self.env.step(action)
        return self._apply(obs), reward, terminated, truncated, self._info(info)

    def render(self):
        """In place: the fogged front camera beside the bird's-eye view; paired: the base env's render."""
        frame = self.env.render()
        base = self.env.unwrapped
        if frame is None or self.paired or self.levels[0].is_clear or self._last is None or base.scene is None:
            return frame
        from fog_gym.render.birds_eye import birds_eye_view, composite

        cam = "CAM_FRONT" if "CAM_FRONT" in self._last else (self.cameras[0] if self.cameras else None)
        return composite(None if cam is None else self._last[cam], birds_eye_view(base.scene))

    # -- internals ------------------------------------------------------------------------------------------
    @property
    def fields(self) -> bool:
        """Whether a level in force is a fog field that is not homogeneous (the sensors then need their poses)."""
        return not all(lv.is_homogeneous for lv in self.levels)

    def field_record(self, always: bool = False) -> dict[str, Any] | None:
        """The fields in force now, as a dataset records them beside a sample (:mod:`fog_gym.dataset.fog_record`):
        ``{"frame": (x0, y0, heading), "time": seconds since reset, "fields": {name: field}}``; None while the fog
        is homogeneous (a level's visibility says all) unless ``always``."""
        if not (self.fields or always):
            return None
        return {"frame": self.field_frame, "time": self._field_time(),
                "fields": {lv.name: field_info(lv) for lv in self.levels}}  # fmt: skip

    def _frame_at_reset(self, base) -> tuple[float, float, float]:
        """The field frame: the LiDAR origin (the 3D boxes' frame) at reset, on the road, and the ego's heading."""
        if base.scene is None or not hasattr(base, "ego_pose_record"):
            return 0.0, 0.0, 0.0
        origin = self._lidar_to_world()[:3, 3]
        return float(origin[0]), float(origin[1]), float(base.scene.ego_pose[2])

    def _field_time(self) -> float:
        base = self.env.unwrapped
        return base.scene.time - self._t0 if base.scene is not None else 0.0

    def _info(self, info: dict) -> dict:
        info = dict(info)
        describe = field_info if self.fields else (lambda lv: lv.info())
        info["fog"] = {lv.name: describe(lv) for lv in self.levels} if self.paired else describe(self.levels[0])
        if "boxes_3d" in info:  # how much fog stands between each sensor and each box (ground truth is unchanged)
            def transmittance(distance: np.ndarray, two_way: bool, depth=None) -> np.ndarray | dict[str, np.ndarray]:
                k = 2.0 if two_way else 1.0
                values = {lv.name: np.exp(-k * (lv.alpha * distance if depth is None or lv.is_homogeneous
                                                else depth[lv.name])) for lv in self.levels}  # fmt: skip
                return values if self.paired else values[self.levels[0].name]

            b3 = info["boxes_3d"]
            depths = self._box_depths(b3, info["boxes_2d"]) if self.fields else {}
            info["boxes_3d"] = b3.with_fields(transmittance=transmittance(b3["distance"], True, depths.get(None)),
                                              **self._fogged_counts(b3))  # fmt: skip
            info["boxes_2d"] = {cam: self._perceivable(b.with_fields(transmittance=transmittance(b["distance"], False,
                                                                                                depths.get(cam))))
                                for cam, b in info["boxes_2d"].items()}  # fmt: skip
        return info

    def _fogged_counts(self, b3) -> dict[str, Any]:
        """``num_lidar_pts`` in the fogged sweep(s): the level's counts (in place), or per level with the clean
        sweep's under "clear" (paired); nothing when the rig has no LiDAR or the base env counted none."""
        if "num_lidar_pts" not in b3 or not self._fog_lidar:
            return {}
        from fog_gym.channels.packing import unpack_points
        from fog_gym.labels.visibility import points_in_boxes

        base = self.env.unwrapped
        channel, clouds = self._fog_lidar
        m = np.linalg.inv(self._lidar_to_world()) @ base.sensor_to_world(channel)
        counts = {name: points_in_boxes(p[:, :3] @ m[:3, :3].T + m[:3, 3], b3["center"], b3["size"], b3["yaw"])
                  for name, p in ((n, unpack_points(c, channel, copy=False)) for n, c in clouds.items())}  # fmt: skip
        if not self.paired:
            return {"num_lidar_pts": counts[self.levels[0].name]}
        return {"num_lidar_pts": {"clear": b3["num_lidar_pts"], **counts}}

    def _perceivable(self, b) -> Any:
        """``perceivable``: the box's apparent contrast ``|C₀|·t`` at its range reaches 5 % (in place: at the level;
        paired: per level, with "clear" for the clean frame); :func:`fog_gym.labels.visibility.perceivable`."""
        if "contrast" not in b:
            return b
        from fog_gym.labels.visibility import perceivable

        t = b["transmittance"]
        if not self.paired:
            return b.with_fields(perceivable=perceivable(b["contrast"], t))
        return b.with_fields(perceivable={"clear": perceivable(b["contrast"], np.ones(len(b["contrast"]))),
                                          **{name: perceivable(b["contrast"], v) for name, v in t.items()}})  # fmt: skip

    def _box_depths(self, boxes_3d, boxes_2d) -> dict[str | None, dict[str, np.ndarray]]:
        """Each field's optical depth from the LiDAR origin (key None) and from each camera's centre to each box
        centre, by level name."""
        base = self.env.unwrapped
        lidar = self._lidar_to_world()
        centres = np.asarray(boxes_3d["center"], np.float64).reshape(-1, 3) @ lidar[:3, :3].T + lidar[:3, 3]
        row = {int(v): k for k, v in enumerate(boxes_3d["vehicle_ids"])}
        t = self._field_time()

        def depths(origin: np.ndarray, ends: np.ndarray) -> dict[str, np.ndarray]:
            return {lv.name: world_optical_depth(lv, self.field_frame, t, origin, ends) for lv in self.levels}

        out: dict[str | None, dict[str, np.ndarray]] = {None: depths(lidar[:3, 3], centres)}
        for cam, b in boxes_2d.items():
            ends = centres[[row[int(v)] for v in b["vehicle_ids"]]] if len(b["vehicle_ids"]) else np.zeros((0, 3))
            out[cam] = depths(base.sensor_to_world(cam)[:3, 3], ends)
        return out

    def _lidar_to_world(self) -> np.ndarray:
        """The 3D boxes' LiDAR frame → world at the current frame."""
        base = self.env.unwrapped
        return yaw_transform(*base.scene.ego_pose) @ base.ego_pose_record()["lidar_to_ego"]

    def _fogged(self, obs: dict, levels: tuple[FogLevel, ...]) -> dict[str, dict[str, np.ndarray]]:
        """Fogged channels per level name (all levels of a channel in one pass)."""
        base = self.env.unwrapped
        out: dict[str, dict[str, np.ndarray]] = {lv.name: {} for lv in levels}
        lidar = base.config.rig.lidar if hasattr(base, "config") else None
        reflect = lidar.atmosphere_attenuation_rate if lidar is not None and lidar.intensity == "reflectance" else None
        poses = {}
        if self.fields:  # each fogged sensor's pose in the world, for the fields' optical depths
            poses = {ch: base.sensor_to_world(ch) for ch in self.models}
        clean, record = self._clean_rgb(obs)
        context = FogContext(base.intrinsics, self.airlight, self._rngs,
                             base.scene is not None and base.scene.lighting.night, self.lidar_noise, reflect, poses,
                             self.field_frame, self._field_time(),
                             lidar.returns if lidar is not None else "strongest", clean, record,
                             {lv.name: _level_key(lv) + 1 for lv in levels},
                             base.point_rows(obs) if hasattr(base, "point_rows") else {})  # fmt: skip
        for channel, model in self.models.items():  # the model of each sensor kind (fog_gym.fog.models)
            for name, fogged in model.apply(obs, channel, levels, context).items():
                out[name][channel] = fogged
        return out

    def _clean_rgb(self, obs: dict) -> tuple[dict[str, np.ndarray], Any]:
        """The noise-free images of the cameras that record with noise (fog is light in the scene: it is added
        before the sensor's noise) and the env's ``camera_record``; none when no camera has noise (or an inner
        wrapper changed the images)."""
        base = self.env.unwrapped
        effects = getattr(base, "camera_effects", None)
        if not effects:
            return {}, None
        clean = {cam: base.frames[cam].rgb for cam in effects.noise
                 if cam in base.frames and cam in obs and base.frames[cam].rgb.shape == np.shape(obs[cam])}  # fmt: skip
        return clean, base.camera_record if clean else None

    def _keep_lidar(self, obs: dict, fogged: dict[str, dict[str, np.ndarray]]) -> None:
        """The fogged LiDAR sweeps of this frame (their packed channels: :meth:`_fogged_counts`, in the same call,
        unpacks them only when the boxes ask for ``num_lidar_pts``)."""
        lidar = next((ch for ch, m in self.models.items() if getattr(m, "name", "") == "hahner"), None)
        self._fog_lidar = None if lidar is None else (lidar, {name: f[lidar] for name, f in fogged.items()
                                                              if lidar in f})  # fmt: skip

    def _apply(self, obs: dict) -> dict:
        if not self.paired:
            level = self.levels[0]
            if level.is_clear:
                self._last = obs
                self._keep_lidar(obs, {level.name: obs})
            else:
                fogged = self._fogged(obs, self.levels)
                self._keep_lidar(obs, fogged)
                self._last = {**obs, **fogged[level.name]}
            return self._last
        out = dict(obs)
        fogged = self._fogged(obs, self.levels)
        self._keep_lidar(obs, fogged)
        for lv in self.levels:
            out.update({f"{k}_{lv.channel_suffix}": v for k, v in fogged[lv.name].items()})
        return out


def _level_key(level: FogField) -> int:
    """The fog noise stream of a level: its visibility in mm (homogeneous), a checksum of a field's parameters
    (remembered per field: a frame asks for it once per level)."""
    if level.is_homogeneous:
        return 0 if level.is_clear else int(round(level.visibility_m * 1000))
    try:
        return _field_key(level)
    except TypeError:  # a field with an unhashable parameter
        return _field_key.__wrapped__(level)


@functools.lru_cache(maxsize=256)
def _field_key(level: FogField) -> int:
    return zlib.crc32(field_json(level).encode())

"""Log FogDrive data to `Rerun <https://rerun.io>`_: every sensor, clean beside each fog level, with boxes.

One sample is a ``{channel: array}`` dict with the dataset's channel names (``CAM_FRONT``,
``CAM_FRONT_FOG_DENSE``, ``CAM_FRONT_DEPTH``, ``LIDAR_TOP_FOG_LIGHT``, ``BBOX_3D``, …), made either from a recorded
dataset (:func:`sample_from_dataset`) or from a live paired-fog episode (:func:`sample_from_env`), and logged by
:func:`log_sample` on the ``sample_time`` timeline (seconds from the scene's first sample). Entities:

* ``world/ego/lidar``: the LiDAR frame. Below it ``points/clean`` and
  ``points/fog_<level>`` (coloured by intensity), ``semantic`` (class = CARLA tag, Cityscapes colours),
  ``boxes`` (3D boxes, labelled by vehicle id) and one pinhole per camera (``CAM_FRONT`` …: its frustum in 3D)
  holding ``rgb``, ``fog_<level>``, ``depth``, ``semantic`` and ``boxes`` (2D boxes).
* ``world/ego/radar``: the front radar's detections, coloured by radial velocity (red approaching).
* ``world/trajectory``: the ego's path so far (live episodes only: a recorded FogDrive scene stores no ego poses,
  so there the world frame is the ego's own at every sample).

Rerun draws right-handed frames only (and a camera only under a rotation), while fog-gym's frames are CARLA's
left-handed ones (+x forward, +y right, +z up); the viewer therefore shows every 3D quantity mirrored to +x forward,
**+y left**, +z up (y negated: :data:`DISPLAY`). Files and observations are untouched; images are not mirrored.

Needs the ``viz`` extra (``rerun-sdk``). :func:`view_dataset` and :func:`view_live` write an ``.rrd`` file with
``save=`` (no display needed; open it later with ``rerun FILE.rrd``) or else open the viewer.

Example:
    >>> import numpy as np
    >>> box_params(np.array([[[2, 1, -1], [2, -1, -1], [-2, -1, -1], [-2, 1, -1],
    ...                        [2, 1, 1], [2, -1, 1], [-2, 1, 1], [-2, 1, 1]]], float))[1].tolist()
    [[2.0, 1.0, 1.0]]
"""

from __future__ import annotations

import math
import os
import re
import sys
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from fog_gym.dataset.layout import CAMERAS, CHANNELS  # noqa: F401  (CHANNELS: the viewer's documented channel list)
from fog_gym.encoding import CITYSCAPES_PALETTE, TAG_NAMES
from fog_gym.checks import option

LIDAR_PATH = "world/ego/lidar"
RADAR_PATH = "world/ego/radar"
TIMELINE = "sample_time"
BOX_COLOR = (255, 200, 0)
#: CARLA's left-handed frames → Rerun's right-handed display frame (x forward, y left, z up): negate y.
DISPLAY = np.diag([1.0, -1.0, 1.0, 1.0])
#: Gradient for intensities in [0, 1] (dark blue → teal → yellow), interpolated linearly.
_INTENSITY_STOPS = np.array([[40, 30, 110], [30, 120, 160], [60, 190, 110], [250, 230, 40]], np.float64)


def _require_rerun():
    try:
        import rerun as rr
    except ImportError:  # pragma: no cover - depends on the install
        raise ImportError("the viewer needs Rerun: pip install 'fog-gym[viz]' (rerun-sdk)") from None
    return rr


def intensity_colors(intensity: np.ndarray) -> np.ndarray:
    """``(N, 3)`` uint8 colours for intensities (clipped to [0, 1]).

    >>> intensity_colors(np.array([0.0, 1.0])).tolist()
    [[40, 30, 110], [250, 230, 40]]
    """
    x = np.clip(np.nan_to_num(np.asarray(intensity, np.float64)), 0.0, 1.0) * (len(_INTENSITY_STOPS) - 1)
    i = np.minimum(x.astype(np.int64), len(_INTENSITY_STOPS) - 2)
    f = (x - i)[:, None]
    return np.rint(_INTENSITY_STOPS[i] * (1 - f) + _INTENSITY_STOPS[i + 1] * f).astype(np.uint8)


def box_params(corners: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Centres ``(N, 3)``, half sizes ``(N, 3)`` and yaws ``(N,)`` [rad] of boxes given by their eight corners."""
    from fog_gym.geometry import corners_to_boxes

    b = corners_to_boxes(corners)
    return b[:, :3], b[:, 3:6] / 2.0, b[:, 6]


def radar_to_xyz(radar: np.ndarray) -> np.ndarray:
    """Radar rows (velocity, azimuth [rad], altitude [rad], depth) → points in the radar frame.

    >>> radar_to_xyz(np.array([[0.0, 0.0, 0.0, 10.0]])).round(6).tolist()
    [[10.0, 0.0, 0.0]]
    """
    r = np.asarray(radar, np.float64).reshape(-1, 4)
    az, alt, d = r[:, 1], r[:, 2], r[:, 3]
    return np.stack([d * np.cos(alt) * np.cos(az), d * np.cos(alt) * np.sin(az), d * np.sin(alt)], axis=1)


def fog_channels(channels: Iterable[str], prefix: str) -> dict[str, str]:
    """``{level name (lower case): channel}`` for the fogged copies of ``prefix`` among ``channels``.

    >>> fog_channels(["CAM_BACK", "CAM_BACK_FOG_DENSE", "CAM_BACK_FOG_150M", "CAM_FRONT_FOG_LIGHT"], "CAM_BACK")
    {'dense': 'CAM_BACK_FOG_DENSE', '150m': 'CAM_BACK_FOG_150M'}
    """
    pat = re.compile(re.escape(prefix) + r"_FOG_([A-Z0-9_.]+)$")
    return {m.group(1).lower(): ch for ch in channels if (m := pat.match(ch))}


# -- samples ------------------------------------------------------------------------------------------------------
def sample_from_dataset(ds: Any, sample_token: str) -> dict[str, Any]:
    """Decode every file of one sample of a :class:`fog_gym.dataset.access.FogDrive` dataset."""
    from fog_gym.dataset.decode import load_channel

    layout = getattr(ds, "channels", {})  # the set's layout: added sensors' channels decode as their rig declared
    return {ch: load_channel(ch, path, layout.get(ch)) for ch, path in ds.get_sample_paths(sample_token).items()}


def sample_from_env(obs: Mapping[str, np.ndarray], info: Mapping[str, Any]) -> dict[str, Any]:
    """One sample from a live FogDrive-v0 step (paired fog and ground truth on): the dataset's channel names."""
    from fog_gym.channels.packing import COLUMNS, unpack_points

    out: dict[str, Any] = {}
    for key, value in obs.items():
        base = key.split("_FOG_")[0]
        out[key] = unpack_points(obs, key) if base in COLUMNS else value
    for cam, b in info.get("boxes_2d", {}).items():
        out[f"{cam}_BBOX"] = {k: np.asarray(b[k]) for k in ("bboxes", "vehicle_ids", "vehicle_class")}
    if "boxes_3d" in info:
        b3 = info["boxes_3d"]
        out["BBOX_3D"] = {"bboxes_3d": np.asarray(b3["corners"]), "vehicle_ids": np.asarray(b3["vehicle_ids"]),
                          "vehicle_class": np.asarray(b3["vehicle_class"])}  # fmt: skip
    return out


# -- logging ------------------------------------------------------------------------------------------------------
def log_static(rec: Any, cameras: Mapping[str, tuple[np.ndarray, np.ndarray, int, int]],
               lidar_to_vehicle: np.ndarray, radar_to_vehicle: np.ndarray) -> None:  # fmt: skip
    """Frames, the semantic colour table and one pinhole per camera: ``{name: (extrinsic E, K, width, height)}``,
    E mapping LiDAR-frame points to the camera's (x right, y down, z forward) frame."""
    rr = _require_rerun()
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)  # display frame: forward, left, up
    rec.log("world", rr.AnnotationContext([(t, TAG_NAMES[t], tuple(int(v) for v in CITYSCAPES_PALETTE[t]))
                                           for t in sorted(TAG_NAMES)]), static=True)  # fmt: skip
    rec.log(LIDAR_PATH, _transform(rr, DISPLAY @ lidar_to_vehicle @ DISPLAY), static=True)
    rec.log(RADAR_PATH, _transform(rr, DISPLAY @ radar_to_vehicle @ DISPLAY), static=True)
    for name, (extrinsic, K, width, height) in cameras.items():
        cam_to_lidar = DISPLAY @ np.linalg.inv(np.asarray(extrinsic, np.float64))  # a rotation: det +1
        path = f"{LIDAR_PATH}/{name}"
        rec.log(path, _transform(rr, cam_to_lidar), static=True)
        rec.log(path, rr.Pinhole(image_from_camera=np.asarray(K, np.float64), resolution=[width, height],
                                 camera_xyz=rr.ViewCoordinates.RDF, image_plane_distance=2.0), static=True)  # fmt: skip


def _show(points: np.ndarray) -> np.ndarray:
    """Points ``(N, 3)`` in a CARLA frame → the display frame (y negated)."""
    p = np.array(points, np.float64).reshape(-1, 3)
    p[:, 1] *= -1.0
    return p


def _transform(rr: Any, matrix: np.ndarray):
    m = np.asarray(matrix, np.float64)
    return rr.Transform3D(translation=m[:3, 3], mat3x3=m[:3, :3])


def log_sample(rec: Any, t: float, sample: Mapping[str, Any], ego_pose: Sequence[float] | None = None,
               trajectory: np.ndarray | None = None) -> None:  # fmt: skip
    """Log one sample at ``t`` seconds; ``ego_pose`` (x, y, yaw rad) places the ego in the world (live episodes)."""
    rr = _require_rerun()
    rec.set_time(TIMELINE, duration=float(t))
    if ego_pose is not None:
        x, y, yaw = (float(v) for v in ego_pose)
        c, s = math.cos(-yaw), math.sin(-yaw)
        rec.log("world/ego", rr.Transform3D(translation=[x, -y, 0.0], mat3x3=[[c, -s, 0], [s, c, 0], [0, 0, 1]]))
    if trajectory is not None and len(trajectory) > 1:
        rec.log("world/trajectory", rr.LineStrips3D([_show(trajectory)], colors=[(255, 140, 0)]))
    channels = list(sample)
    if "LIDAR_TOP" in sample:
        for level, ch in {"clean": "LIDAR_TOP", **fog_channels(channels, "LIDAR_TOP")}.items():
            pts = np.asarray(sample[ch])
            rec.log(f"{LIDAR_PATH}/points/{level if level == 'clean' else 'fog_' + level}",
                    rr.Points3D(_show(pts[:, :3]), colors=intensity_colors(pts[:, 3]), radii=0.04))  # fmt: skip
    if "SEM_LIDAR_TOP" in sample:
        pts = np.asarray(sample["SEM_LIDAR_TOP"])
        rec.log(f"{LIDAR_PATH}/semantic", rr.Points3D(_show(pts[:, :3]), class_ids=pts[:, 5].astype(np.uint16), radii=0.04))
    if "RADAR_FRONT" in sample:
        r = np.asarray(sample["RADAR_FRONT"])
        vel = r[:, 0] if len(r) else np.zeros(0)
        colors = np.where((vel < 0)[:, None], [[230, 40, 40]], [[40, 120, 230]]).astype(np.uint8)
        rec.log(RADAR_PATH, rr.Points3D(_show(radar_to_xyz(r)), colors=colors, radii=0.15))
    if "BBOX_3D" in sample:
        b = sample["BBOX_3D"]
        centers, half, yaw = box_params(b["bboxes_3d"])
        quats = [(0.0, 0.0, math.sin(-a / 2), math.cos(-a / 2)) for a in yaw]  # xyzw about +z, mirrored yaw
        rec.log(f"{LIDAR_PATH}/boxes", rr.Boxes3D(centers=_show(centers), half_sizes=half, quaternions=quats,
                                                   labels=[str(int(i)) for i in b["vehicle_ids"]],
                                                   colors=[BOX_COLOR] * len(centers)))  # fmt: skip
    for cam in CAMERAS:
        if cam not in sample:
            continue
        path = f"{LIDAR_PATH}/{cam}"
        rec.log(f"{path}/rgb", rr.Image(np.asarray(sample[cam])))
        for level, ch in fog_channels(channels, cam).items():
            rec.log(f"{path}/fog_{level}", rr.Image(np.asarray(sample[ch])))
        if f"{cam}_DEPTH" in sample:
            rec.log(f"{path}/depth", rr.DepthImage(np.asarray(sample[f"{cam}_DEPTH"], np.float32), meter=1.0))
        if f"{cam}_SEM" in sample:
            rec.log(f"{path}/semantic", rr.SegmentationImage(np.asarray(sample[f"{cam}_SEM"])))
        if f"{cam}_BBOX" in sample:
            b2 = sample[f"{cam}_BBOX"]
            boxes = np.asarray(b2["bboxes"], np.float64).reshape(-1, 4)  # (x0, y0), (x1, y1)
            rec.log(f"{path}/boxes", rr.Boxes2D(array=boxes, array_format=rr.Box2DFormat.XYXY,
                                                labels=[str(int(i)) for i in b2["vehicle_ids"]],
                                                colors=[BOX_COLOR] * len(boxes)))  # fmt: skip


def blueprint(cameras: Sequence[str], levels: Sequence[str], active: str = "clean"):
    """The layout: on the left one 3D tab per fog level (that level's LiDAR, semantic LiDAR in its own tab, boxes,
    radar, frusta, trajectory; the camera follows the ego), on the right one tab per fog level with a grid of the
    cameras and their 2D boxes, and a tab of depth and semantic images. ``active`` (``clean`` or a level) opens."""
    import rerun.blueprint as rrb

    names = ["clean", *levels]
    eye = rrb.EyeControls3D(position=(-24.0, 0.0, 16.0), look_target=(14.0, 0.0, 0.0), eye_up=(0.0, 0.0, 1.0))
    common = ["+ world/trajectory", "+ world/ego/radar/**", f"+ {LIDAR_PATH}/boxes"] + [
        f"+ {LIDAR_PATH}/{cam}" for cam in cameras] + [f"+ {LIDAR_PATH}/{cam}/rgb" for cam in cameras]  # fmt: skip
    scenes = [rrb.Spatial3DView(origin="world/ego", name=f"3D {n}", eye_controls=eye, contents=[
        *common, f"+ {LIDAR_PATH}/points/{'clean' if n == 'clean' else 'fog_' + n}"]) for n in names]  # fmt: skip
    scenes.append(rrb.Spatial3DView(origin="world/ego", name="3D semantic", eye_controls=eye,
                                    contents=[*common, f"+ {LIDAR_PATH}/semantic"]))  # fmt: skip
    grids = []
    for n in names:
        image = "rgb" if n == "clean" else f"fog_{n}"
        grids.append(rrb.Grid(*[rrb.Spatial2DView(origin=f"{LIDAR_PATH}/{cam}", name=f"{cam} {n}",
                                                  contents=[f"$origin/{image}", "$origin/boxes"]) for cam in cameras],
                              name=n))  # fmt: skip
    grids.append(rrb.Grid(*[rrb.Spatial2DView(origin=f"{LIDAR_PATH}/{cam}", name=f"{cam} {kind}",
                                              contents=[f"$origin/{kind}"])
                            for cam in cameras[:2] for kind in ("depth", "semantic")], name="depth & semantic"))
    at = names.index(active) if active in names else 0
    return rrb.Blueprint(rrb.Horizontal(rrb.Tabs(*scenes, active_tab=at), rrb.Tabs(*grids, active_tab=at)),
                         collapse_panels=True)  # fmt: skip


def _check_display(save: str | Path | None) -> None:
    if save is None and sys.platform.startswith("linux") and not (os.environ.get("DISPLAY")
                                                                 or os.environ.get("WAYLAND_DISPLAY")):  # fmt: skip
        raise ValueError(f"no display to open the viewer on: pass {option('save', repr('FILE.rrd'), 'FILE.rrd')} and open "
                         "the file where there is one (rerun FILE.rrd)")


def _open(application: str, save: str | Path | None):
    rr = _require_rerun()
    _check_display(save)
    rec = rr.RecordingStream(application)
    if save is not None:
        Path(save).parent.mkdir(parents=True, exist_ok=True)
        rec.save(str(save))
    else:
        rec.spawn()
    return rec


# -- entry points ---------------------------------------------------------------------------------------------------
def view_dataset(root: str | Path, scene: str | None = None, save: str | Path | None = None,
                 progress: bool = True, tab: str = "clean") -> int:  # fmt: skip
    """Log one scene of a recorded dataset (the first by name when ``scene`` is None); returns the samples logged.

    Camera intrinsics follow the FogDrive rig (100° horizontal FOV, CARLA's pinhole) at each image's size; the
    LiDAR and radar mounts are the FogDrive rig's; ``tab`` (``clean`` or a fog level) is the tab the layout opens
    on. A scene that does not exist raises ``KeyError`` naming the
    scenes there are, before anything is written.
    """
    from tqdm import tqdm

    from fog_gym.sensors.rig import RigConfig
    from fog_gym.dataset.access import FogDrive
    from fog_gym.geometry import intrinsic_matrix
    from fog_gym.labels.boxes import EXTRINSIC_KEYS
    from fog_gym.geometry import sensor_to_world

    _check_display(save)
    ds = FogDrive(root)
    names = ds.list_scene_names()
    if not names:
        raise ValueError(f"{root}: the dataset holds no scenes")
    if scene is not None and scene not in names:
        raise KeyError(f"no scene named {scene!r}; the scenes are {', '.join(names)}")
    rec_scene = ds.get_scene_by_name(scene if scene is not None else names[0])
    samples = ds.get_samples_for_scene(rec_scene["token"])
    extrinsics = ds.load_extrinsic_config(rec_scene["token"])
    first = {r["channel"]: r for r in ds.get_sample_data_for_sample(samples[0]["token"])}
    rig = RigConfig.fogdrive()
    fov = {c.name: c.fov for c in rig.cameras}
    cams = {}
    for cam in CAMERAS:
        if cam in first and EXTRINSIC_KEYS[cam] in extrinsics:
            w, h = int(first[cam]["width"]), int(first[cam]["height"])
            cams[cam] = (np.asarray(extrinsics[EXTRINSIC_KEYS[cam]]), intrinsic_matrix(w, h, fov[cam]), w, h)
    rec = _open("fog-gym", save)
    levels = list(fog_channels(first, "LIDAR_TOP")) or list(fog_channels(first, CAMERAS[0]))
    rec.send_blueprint(blueprint(list(cams), levels, active=tab))
    log_static(rec, cams, sensor_to_world(rig.lidar.pose), sensor_to_world(rig.radar.pose))
    t0 = samples[0]["timestamp"]
    for s in tqdm(samples, desc=f"logging {rec_scene['name']}", unit="sample", disable=not progress):
        log_sample(rec, (s["timestamp"] - t0) / 1e6, sample_from_dataset(ds, s["token"]))
    rec.flush()
    if save is not None:
        rec.disconnect()
    return len(samples)


def view_live(town: str = "highway", fog: Sequence[Any] = ("light", "moderate", "dense"), steps: int = 20,
              resolution: Sequence[int] = (320, 240), time_of_day: str = "day", seed: int = 0,
              save: str | Path | None = None, policy: Callable[[Any], Any] | None = None,
              progress: bool = True, tab: str = "clean") -> int:  # fmt: skip
    """Drive ``steps`` keyframes of a live paired-fog FogDrive-v0 episode and log them; returns the samples logged.

    ``policy`` maps an observation to an action (default: highway-env's idle action, keep lane and speed). The
    episode ends early on a crash. Bad arguments fail before the world is built.
    """
    from tqdm import tqdm

    from fog_gym.envs.presets import make_fogdrive
    from fog_gym.geometry import sensor_to_world
    from fog_gym.wrappers.fog import parse_fog_levels

    if isinstance(steps, bool) or not isinstance(steps, int) or steps <= 0:
        raise ValueError(f"steps must be a positive integer, got {steps!r}")
    levels, _ = parse_fog_levels(list(fog))
    _check_display(save)
    env = make_fogdrive(fog=list(fog), town=town, time_of_day=time_of_day, resolution=tuple(resolution))
    base = env.unwrapped
    rig = base.config.rig
    obs, info = env.reset(seed=seed)
    cams = {c.name: (info["extrinsics"][_ext_key(c.name)], info["intrinsics"][c.name], c.width, c.height)
            for c in rig.cameras}  # fmt: skip
    lidar_pose = (rig.lidar or rig.semantic_lidar).pose
    rec = _open("fog-gym", save)
    rec.send_blueprint(blueprint(list(cams), [lv.name.lower() for lv in levels], active=tab))
    log_static(rec, cams, sensor_to_world(lidar_pose), sensor_to_world(rig.radar.pose) if rig.radar else np.eye(4))
    path: list[tuple[float, float, float]] = []
    n = 0
    period = 1.0 / base.config.keyframe_frequency
    for k in tqdm(range(steps), desc=f"logging {town} ({time_of_day})", unit="step", disable=not progress):
        ego = base.scene.ego_pose
        path.append((float(ego[0]), float(ego[1]), 0.05))
        log_sample(rec, k * period, sample_from_env(obs, info), ego_pose=ego, trajectory=np.asarray(path))
        n += 1
        if k + 1 == steps:
            break
        action = policy(obs) if policy is not None else base.idle_action
        obs, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            break
    env.close()
    rec.flush()
    if save is not None:
        rec.disconnect()
    return n


def _ext_key(camera: str) -> str:
    from fog_gym.labels.boxes import EXTRINSIC_KEYS

    return EXTRINSIC_KEYS[camera]


def read_rrd(path: str | Path) -> dict[str, int]:
    """``{entity path: number of distinct sample_time values}`` of an ``.rrd`` file, read with Rerun's own reader
    (static entities count 0)."""
    _require_rerun()
    from rerun.chunk import RrdReader

    times: dict[str, set] = {}
    for chunk in RrdReader(path).stream().collect().stream():
        entry = times.setdefault(chunk.entity_path, set())
        if TIMELINE in chunk.timeline_names:
            entry.update(chunk.to_record_batch().column(TIMELINE).cast("int64").to_pylist())  # nanoseconds
    return {k: len(v) for k, v in times.items()}


__all__ = ["box_params", "fog_channels", "intensity_colors", "log_sample", "log_static", "radar_to_xyz",
           "read_rrd", "sample_from_dataset", "sample_from_env", "view_dataset", "view_live"]  # fmt: skip

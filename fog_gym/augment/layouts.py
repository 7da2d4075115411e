"""The data sets ``fog-gym augment`` reads: KITTI object, nuScenes and fog-gym's own FogDrive layout, each as a list
of :class:`Task` — one per file — holding everything its fog needs (paths, calibration, airlight), so that a file
is fogged on its own, in any worker, and the same way every time.

* **KITTI** (``--format kitti``): every ``velodyne/<id>.bin`` (float32 × 4: x, y, z forward-left-up, reflectance in
  [0, 1]; profile ``kitti``) and every ``image_2/<id>.png`` / ``image_3/<id>.png`` with its ``calib/<id>.txt``
  (``P2`` / ``P3``, ``R0_rect``, ``Tr_velo_to_cam``) and the frame's scan for depth.
* **nuScenes** (``--format nuscenes``): every ``sample_data`` record of the version folder's tables — LiDAR
  ``.pcd.bin`` (float32 × 5: x, y, z, intensity 0–255, ring; profile ``nuscenes``; the field frame is the ego
  frame, through ``calibrated_sensor``) and camera ``.jpg`` (``camera_intrinsic``; the LIDAR_TOP scan nearest in
  time, moved into the camera through both ego poses, for depth), key frames and sweeps alike.
* **FogDrive** (``--format fogdrive``): every ``LIDAR_TOP`` file (profile ``fogdrive``) and every camera image,
  with its own depth channel (exact) and the airlight fog-gym made the set's fog with (the scene's first clean
  frame: dark channel by day, :func:`fog_gym.fog.night_airlight` at night).

Every other file is linked (hard link, or copied where links cannot be made).
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

FORMATS = ("kitti", "nuscenes", "fogdrive")


class LayoutError(ValueError):
    """A data set that is not of the format asked for (said before any work, naming what is missing)."""


@dataclass(frozen=True)
class Task:
    """One file: ``rel`` (its path under the source root, the same under the output), ``kind`` ("lidar", "image"
    or "link") and what its fog needs in ``info`` (JSON-ready: calibration as lists, paths relative to the source)."""

    rel: str
    kind: str
    info: dict[str, Any] = field(default_factory=dict)


# -- KITTI ------------------------------------------------------------------------------------------------------
def read_kitti_calib(path: Path) -> dict[str, np.ndarray]:
    """A KITTI calib file's matrices (``P0``…``P3`` 3 × 4, ``R0_rect`` 3 × 3, ``Tr_velo_to_cam`` 3 × 4, …)."""
    out = {}
    for line in Path(path).read_text().splitlines():
        if ":" not in line:
            continue
        name, values = line.split(":", 1)
        nums = [float(v) for v in values.split()]
        if not nums:
            continue
        shape = (3, 3) if name.strip() == "R0_rect" else (3, 4) if len(nums) == 12 else (len(nums),)
        if int(np.prod(shape)) != len(nums):
            raise ValueError(f"{path}: {name.strip()} has {len(nums)} numbers")
        out[name.strip()] = np.array(nums).reshape(shape)
    return out


def kitti_camera(calib: dict[str, np.ndarray], camera: int) -> tuple[np.ndarray, np.ndarray]:
    """``(K, T_cam_lidar)`` of KITTI camera 2 or 3 from a calib file's matrices: ``P = K [I | t]`` (rectified),
    ``T = [I | K⁻¹ P[:, 3]] · R0_rect · Tr_velo_to_cam``."""
    for key in (f"P{camera}", "R0_rect", "Tr_velo_to_cam"):
        if key not in calib:
            raise ValueError(f"the calib file has no {key}")
    P = calib[f"P{camera}"]
    K = P[:, :3]
    shift = np.eye(4)
    shift[:3, 3] = np.linalg.solve(K, P[:, 3])
    R0 = np.eye(4)
    R0[:3, :3] = calib["R0_rect"]
    Tr = np.vstack([calib["Tr_velo_to_cam"], [0, 0, 0, 1]])
    return K, shift @ R0 @ Tr


def plan_kitti(src: Path, sensors: tuple[str, ...]) -> list[Task]:
    tasks = []
    velodyne = sorted(src.rglob("velodyne/*.bin"))
    images = sorted(p for p in src.rglob("image_[23]/*.png"))
    if not velodyne and not images:
        raise LayoutError(f"{src} holds no KITTI velodyne/*.bin or image_2/*.png files")
    fogged = set()
    if "lidar" in sensors:
        for p in velodyne:
            rel = p.relative_to(src).as_posix()
            tasks.append(Task(rel, "lidar", {"format": "kitti"}))
            fogged.add(rel)
    if "cameras" in sensors:
        for p in images:
            frame = p.stem
            base = p.parent.parent
            rel = p.relative_to(src).as_posix()
            tasks.append(Task(rel, "image", {"format": "kitti", "camera": int(p.parent.name[-1]),
                                             "calib": (base / "calib" / f"{frame}.txt").relative_to(src).as_posix(),
                                             "scan": (base / "velodyne" / f"{frame}.bin").relative_to(src).as_posix()}))  # fmt: skip
            fogged.add(rel)
    return tasks + _links(src, fogged)


# -- nuScenes ---------------------------------------------------------------------------------------------------
def quaternion_matrix(q: list[float]) -> np.ndarray:
    """Rotation matrix of a unit quaternion ``[w, x, y, z]`` (nuScenes' order).

    >>> quaternion_matrix([math.cos(math.pi / 4), 0, 0, math.sin(math.pi / 4)]).round(6).tolist()[0]
    [0.0, -1.0, 0.0]
    """
    w, x, y, z = (float(v) for v in q)
    n = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])  # fmt: skip


def _transform(record: dict[str, Any]) -> np.ndarray:
    m = np.eye(4)
    m[:3, :3] = quaternion_matrix(record["rotation"])
    m[:3, 3] = record["translation"]
    return m


def _tables(src: Path) -> tuple[Path, dict[str, list[dict]]]:
    folders = [p.parent for p in src.glob("*/sample_data.json")]
    if not folders:
        raise LayoutError(f"{src} holds no nuScenes version folder (<version>/sample_data.json)")
    if len(folders) > 1:
        raise LayoutError(f"{src} holds several nuScenes versions ({', '.join(sorted(p.name for p in folders))}); "
                          "augment one root per version")  # fmt: skip
    tables = {}
    for name in ("sample_data", "calibrated_sensor", "ego_pose", "sensor"):
        path = folders[0] / f"{name}.json"
        try:
            tables[name] = json.loads(path.read_text())
        except (OSError, json.JSONDecodeError) as e:
            raise LayoutError(f"{path}: not a readable nuScenes table ({e})") from None
    return folders[0], tables


def plan_nuscenes(src: Path, sensors: tuple[str, ...]) -> list[Task]:
    _, t = _tables(src)
    calib = {c["token"]: c for c in t["calibrated_sensor"]}
    sensor = {s["token"]: s for s in t["sensor"]}
    pose = {p["token"]: p for p in t["ego_pose"]}
    lidar_records = []
    for sd in t["sample_data"]:
        cs = calib[sd["calibrated_sensor_token"]]
        if sensor[cs["sensor_token"]]["channel"] == "LIDAR_TOP":
            lidar_records.append(sd)
    lidar_records.sort(key=lambda r: r["timestamp"])
    stamps = np.array([r["timestamp"] for r in lidar_records], np.int64)
    tasks, fogged = [], set()
    for sd in t["sample_data"]:
        cs = calib[sd["calibrated_sensor_token"]]
        s = sensor[cs["sensor_token"]]
        rel = sd["filename"]
        if s["modality"] == "lidar" and s["channel"] == "LIDAR_TOP" and "lidar" in sensors:
            tasks.append(Task(rel, "lidar", {"format": "nuscenes", "sensor_to_field": _transform(cs).tolist()}))
            fogged.add(rel)
        elif s["modality"] == "camera" and "cameras" in sensors:
            if not len(stamps):
                raise LayoutError(f"{src}: camera images need a LIDAR_TOP scan for their depth, and the set has none")
            k = int(np.argmin(np.abs(stamps - sd["timestamp"])))
            lsd = lidar_records[k]
            lcs = calib[lsd["calibrated_sensor_token"]]
            lidar_to_global = _transform(pose[lsd["ego_pose_token"]]) @ _transform(lcs)
            cam_to_ego = _transform(cs)
            cam_to_global = _transform(pose[sd["ego_pose_token"]]) @ cam_to_ego
            T = np.linalg.inv(cam_to_global) @ lidar_to_global
            up = np.linalg.inv(lidar_to_global)[:3, :3] @ np.array([0.0, 0.0, 1.0])  # the world's up in the LiDAR
            tasks.append(Task(rel, "image", {"format": "nuscenes", "K": cs["camera_intrinsic"], "T": T.tolist(),
                                             "scan": lsd["filename"], "camera_to_field": cam_to_ego.tolist(),
                                             "up": up.tolist()}))  # fmt: skip
            fogged.add(rel)
    return tasks + _links(src, fogged)


# -- FogDrive ---------------------------------------------------------------------------------------------------
def plan_fogdrive(src: Path, sensors: tuple[str, ...]) -> list[Task]:
    from fog_gym.dataset.access import DatasetError, FogDrive
    from fog_gym.dataset.layout import extrinsic_key, layout_cameras

    try:
        ds = FogDrive(src)
    except (DatasetError, FileNotFoundError, ValueError) as e:
        raise LayoutError(f"{src} is not a FogDrive dataset: {e}") from None
    channels = ds.list_channels()
    cameras = [c for c in layout_cameras(ds.channels) if c in channels]
    tasks, fogged = [], set()
    for scene in ds.scene:
        samples = ds.get_samples_for_scene(scene["token"])
        if not samples:
            continue
        extrinsics = ds.load_extrinsic_config(scene["token"]) if cameras else {}
        for s in samples:
            paths = ds.get_sample_paths(s["token"])
            if "lidar" in sensors and "LIDAR_TOP" in paths:
                rel = Path(paths["LIDAR_TOP"]).relative_to(src).as_posix()
                tasks.append(Task(rel, "lidar", {"format": "fogdrive"}))
                fogged.add(rel)
            if "cameras" not in sensors:
                continue
            first = ds.get_sample_paths(samples[0]["token"])
            for cam in cameras:
                depth = f"{cam}_DEPTH"
                if cam not in paths or depth not in paths:
                    continue
                rel = Path(paths[cam]).relative_to(src).as_posix()
                E = np.asarray(extrinsics.get(extrinsic_key(cam), np.eye(4)), np.float64)
                tasks.append(Task(rel, "image", {"format": "fogdrive", "camera": cam,
                                                 "depth": Path(paths[depth]).relative_to(src).as_posix(),
                                                 "first": Path(first[cam]).relative_to(src).as_posix(),
                                                 "first_depth": Path(first[depth]).relative_to(src).as_posix(),
                                                 "night": "_night_" in scene["name"],
                                                 "T": E.tolist() if E.shape == (4, 4) else None}))  # fmt: skip
                fogged.add(rel)
    if not tasks:
        raise LayoutError(f"{src}: the dataset has no LIDAR_TOP or camera files to fog")
    return tasks + _links(src, fogged)


def _links(src: Path, fogged: set[str]) -> list[Task]:
    """Every other file of the source, to be linked (fog-gym's own lock and progress files left out)."""
    from fog_gym.dataset.lock import LOCK_FILE

    out = []
    for dirpath, dirnames, filenames in os.walk(src):
        dirnames[:] = sorted(d for d in dirnames if not d.startswith(".fog-gym"))
        for name in sorted(filenames):
            rel = (Path(dirpath) / name).relative_to(src).as_posix()
            if rel not in fogged and name != LOCK_FILE and not name.startswith(".fog-gym"):
                out.append(Task(rel, "link"))
    return out


PLANNERS = {"kitti": plan_kitti, "nuscenes": plan_nuscenes, "fogdrive": plan_fogdrive}

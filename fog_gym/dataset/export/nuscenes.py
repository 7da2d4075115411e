"""nuScenes v1.0 export: the thirteen tables under ``OUT/v1.0-trainval/``, LiDAR sweeps and camera images under
``OUT/samples/<CHANNEL>/``, one drivable-area map per scene under ``OUT/maps/``. The nuScenes devkit loads it
(``NuScenes(version="v1.0-trainval", dataroot=OUT)``); docs/exports.md has the frames, the class mapping and the
limits.

* Frames: the LiDAR, ego and global frames are right-handed (+x forward, +y left, +z up): FogDrive's with y negated
  (:mod:`~fog_gym.dataset.export.frames`). The LiDAR's calibrated pose is its mount on the ego; a camera's is
  derived from the FogDrive extrinsic. The global frame is the world frame reflected and shifted, per scene, by
  whole metres so that the scene's map starts at (0, 0) (``log.json`` records the shift as ``world_origin``).
* Ego poses are the recorded ones (``ego_pose/``); a scene without them gets identity poses: each sample's
  global frame is then its own LiDAR frame and box velocities mean nothing (the export says so).
* LiDAR: ``.pcd.bin`` float32 × 5 — x, y, z, intensity × 255 (nuScenes' 0–255 range), ring index. A last-return
  set exports its LiDAR as is; a dual-return set every echo of a beam as a point (the format has no return column).
* Annotations: ``num_lidar_pts`` counts the exported sweep's points in each box (at the export's fog level);
  ``num_radar_pts`` the radar detections in it, as the set's ``BBOX_3D`` files record them (0 in sets made before
  fog-gym recorded them); ``visibility_token`` nuScenes' bin of the best-seen camera.
* Keyframes only (FogDrive has 10 Hz samples and no sweeps between them); one ego pose per sample, shared by its
  sensors (FogDrive's sensors are synchronous).
* FogDrive's splits are the devkit's custom splits ``fogdrive_train``, ``fogdrive_val``, ``fogdrive_test``
  (``v1.0-trainval/splits.json``): ``DetectionEval(..., eval_set="fogdrive_val")`` evaluates on them.
"""

from __future__ import annotations

import json
from datetime import datetime, timezone

import cv2
import numpy as np

from fog_gym.dataset.export.common import LIDAR, Sink, Source
from fog_gym.dataset.export.frames import (
    FLIP, NUSCENES_CATEGORIES, FOGDRIVE_CLASSES, boxes_from_corners, camera_intrinsic, matrix_quaternion,
    nuscenes_visibility, occlusion, points_in_boxes, reflect_points, reflect_transform, ring_index, yaw_matrix,
)  # fmt: skip
from fog_gym.dataset.layout import parse_scene_folder
from fog_gym.dataset.poses import EgoPose
from fog_gym.dataset.writer import token_for

VERSION = "v1.0-trainval"
MAP_RESOLUTION = 0.1  # metres per map pixel: the devkit's default
MAP_MARGIN_M = 130.0  # map margin around the ego's path: beyond the LiDAR's 120 m
EPOCH_US = 1_514_764_800_000_000  # 2018-01-01 00:00 UTC: the clock of the first scene
SCENE_SPACING_US = 3_600_000_000  # one hour between the clocks of consecutive scenes of the set
ROAD_TAGS = (1, 24)  # CARLA's Road and RoadLine
MOVING_M_S = 0.5  # an annotation moving faster than this is vehicle.moving, else vehicle.stopped
ATTRIBUTES = {"vehicle.moving": "Vehicle is moving.", "vehicle.stopped": "Vehicle, with a driver/rider in/on it, "
              "is currently stationary but has an intent to move.", "vehicle.parked": "Vehicle is stationary "
              "(usually for a long period of time) with no immediate intent to move."}  # fmt: skip
VISIBILITY = {"1": "v0-40", "2": "v40-60", "3": "v60-80", "4": "v80-100"}


def tok(*parts: object) -> str:
    """A deterministic 32-hex-digit nuScenes token."""
    return token_for("nuscenes", *parts).replace("-", "")


def _identity_pose() -> EgoPose:
    return EgoPose(np.zeros(3), 0.0, np.zeros(3), np.eye(4))


def _pose_record(token: str, T: np.ndarray, timestamp: int) -> dict:
    return {"token": token, "timestamp": timestamp, "rotation": matrix_quaternion(T[:3, :3]).tolist(),
            "translation": T[:3, 3].tolist()}  # fmt: skip


def _points_file(points: np.ndarray) -> bytes:
    """FogDrive (N, 4) x, y, z, intensity [0, 1] → nuScenes float32 (N, 5) x, −y, z, intensity × 255, ring."""
    rh = reflect_points(points[:, :3].astype(np.float64))
    out = np.empty((len(points), 5), np.float32)
    out[:, :3] = rh
    out[:, 3] = points[:, 3] * 255.0
    out[:, 4] = ring_index(rh)
    return out.tobytes()


class _Scene:
    """One scene's tables, built sample by sample."""

    def __init__(self, src: Source, scene: dict, tables: dict[str, list], notes: list[str]) -> None:
        self.src, self.scene, self.tables = src, scene, tables
        self.folder = src.folder(scene)
        self.samples = src.samples(scene)
        poses = [src.ego_pose(s["token"]) for s in self.samples]
        self.has_poses = all(p is not None for p in poses)
        if not self.has_poses:
            notes.append(f"scene {scene['name']} has no ego poses: exported with identity poses (each sample's global "
                         "frame is its LiDAR frame; box velocities and the map are meaningless)")  # fmt: skip
            poses = [_identity_pose()] * len(self.samples)
        self.lidar_to_ego = reflect_transform(poses[0].lidar_to_ego)
        world = [reflect_transform(p.ego_to_world()) for p in poses]
        xy = np.array([w[:2, 3] for w in world]).reshape(-1, 2)
        self.origin = np.floor(xy.min(axis=0) - MAP_MARGIN_M)
        self.extent = np.ceil(xy.max(axis=0) + MAP_MARGIN_M) - self.origin
        shift = np.eye(4)
        shift[:2, 3] = -self.origin
        self.ego_to_global = [shift @ w for w in world]
        self.clock = EPOCH_US + src.scene_number[scene["token"]] * SCENE_SPACING_US
        self.log = tok("log", self.folder)
        town = parse_scene_folder(self.folder)[0]
        date = datetime.fromtimestamp(self.clock / 1e6, timezone.utc).strftime("%Y-%m-%d")
        tables["log"].append({"token": self.log, "logfile": self.folder, "vehicle": "fog-gym ego", "date_captured": date,
                              "location": f"fog-gym-T{town}", "world_origin": self.origin.tolist()})  # fmt: skip
        self.road = np.zeros((int(self.extent[1] / MAP_RESOLUTION), int(self.extent[0] / MAP_RESOLUTION)), np.uint8)
        self.calibrated = {LIDAR: self._calibrated(LIDAR, self.lidar_to_ego, [])}
        self.extrinsics = {cam: src.extrinsic(scene, cam) for cam in src.all_cameras}
        for cam in src.cameras:
            cam_to_ego = self.lidar_to_ego @ FLIP @ np.linalg.inv(self.extrinsics[cam])
            w, h = src.image_size(self.samples[0]["token"], cam)
            self.calibrated[cam] = self._calibrated(cam, cam_to_ego, camera_intrinsic(w, h).tolist())
        self.prev_data: dict[str, dict] = {}
        self.annotations: dict[int, list[dict]] = {}

    def _calibrated(self, channel: str, T: np.ndarray, intrinsic: list) -> str:
        token = tok("calibrated_sensor", self.folder, channel)
        self.tables["calibrated_sensor"].append({
            "token": token, "sensor_token": tok("sensor", channel), "translation": T[:3, 3].tolist(),
            "rotation": matrix_quaternion(T[:3, :3]).tolist(), "camera_intrinsic": intrinsic,
        })  # fmt: skip
        return token

    def timestamp(self, sample: dict) -> int:
        return self.clock + int(round(sample["timestamp"]))

    def add_sample(self, k: int, sample: dict, sink: Sink) -> None:
        src, fog_token = self.src, sample["token"]
        token, ts = fog_token.replace("-", ""), self.timestamp(sample)
        samples = self.samples
        self.tables["sample"].append({
            "token": token, "timestamp": ts, "scene_token": self.scene["token"].replace("-", ""),
            "prev": samples[k - 1]["token"].replace("-", "") if k else "",
            "next": samples[k + 1]["token"].replace("-", "") if k + 1 < len(samples) else "",
        })  # fmt: skip
        pose_token = tok("ego_pose", fog_token)
        self.tables["ego_pose"].append(_pose_record(pose_token, self.ego_to_global[k], ts))
        points = src.lidar(fog_token)
        base = f"samples/{{0}}/{self.folder}__{{0}}__{ts}"
        self._data(token, pose_token, LIDAR, base.format(LIDAR) + ".pcd.bin", "pcd", ts, 0, 0)
        sink.write(base.format(LIDAR) + ".pcd.bin", lambda: _points_file(points))
        for cam in src.cameras:
            w, h = src.image_size(fog_token, cam)
            self._data(token, pose_token, cam, base.format(cam) + ".png", "png", ts, w, h)
            sink.copy(base.format(cam) + ".png", src.image_path(fog_token, cam))
        self._annotate(k, fog_token, token, points)
        self._map_points(k, fog_token)

    def _data(self, sample: str, pose: str, channel: str, filename: str, fmt: str, ts: int, w: int, h: int) -> None:
        rec = {"token": tok("sample_data", sample, channel), "sample_token": sample, "ego_pose_token": pose,
               "calibrated_sensor_token": self.calibrated[channel], "timestamp": ts, "fileformat": fmt,
               "is_key_frame": True, "height": h, "width": w, "filename": filename, "prev": "", "next": ""}  # fmt: skip
        prev = self.prev_data.get(channel)
        if prev is not None:
            prev["next"], rec["prev"] = rec["token"], prev["token"]
        self.prev_data[channel] = rec
        self.tables["sample_data"].append(rec)

    def _annotate(self, k: int, fog_token: str, token: str, points: np.ndarray) -> None:
        boxes = self.src.boxes(fog_token)
        centers, sizes, yaws = boxes_from_corners(boxes.corners)
        counts = points_in_boxes(reflect_points(points[:, :3].astype(np.float64)), centers, sizes, yaws)
        visible = self._visibility(fog_token, boxes)
        radar = self.src.radar_counts(fog_token)  # radar is not fogged: the set's own count
        to_global = self.ego_to_global[k] @ self.lidar_to_ego
        for b, vid in enumerate(boxes.ids.tolist()):
            rotation = to_global[:3, :3] @ yaw_matrix(yaws[b])
            self.annotations.setdefault(vid, []).append({
                "token": tok("sample_annotation", fog_token, vid), "sample_token": token,
                "instance_token": tok("instance", self.folder, vid), "visibility_token": visible.get(vid, ""),
                "attribute_tokens": [], "translation": (to_global @ [*centers[b], 1.0])[:3].tolist(),
                "size": [sizes[b, 1], sizes[b, 0], sizes[b, 2]], "rotation": matrix_quaternion(rotation).tolist(),
                "prev": "", "next": "", "num_lidar_pts": int(counts[b]),
                "num_radar_pts": int(radar[b]) if radar is not None else 0,
                "category_token": tok("category", NUSCENES_CATEGORIES.get(int(boxes.classes[b]), "vehicle.car")),
                "_time": self.samples[k]["timestamp"] / 1e6,
            })  # fmt: skip

    def _visibility(self, fog_token: str, boxes) -> dict[int, str]:
        """Per vehicle: nuScenes' visibility bin of its best-seen camera (depth-based occlusion), where the set has
        depth images; empty otherwise."""
        best: dict[int, float] = {}
        for cam in self.src.all_cameras:
            b2 = self.src.boxes_2d(fog_token, cam)
            if not len(b2["vehicle_ids"]):
                continue
            depth = self.src.depth(fog_token, cam)
            if depth is None:
                return {}
            h, w = depth.shape
            K, E = camera_intrinsic(w, h), self.extrinsics[cam]
            index = {int(v): i for i, v in enumerate(boxes.ids.tolist())}
            for vid in b2["vehicle_ids"].tolist():
                if vid in index:
                    corners = boxes.corners[index[vid]] @ E[:3, :3].T + E[:3, 3]
                    best[vid] = max(best.get(vid, 0.0), occlusion(depth, corners, K)[1])
        return {vid: nuscenes_visibility(v) for vid, v in best.items()}

    def _map_points(self, k: int, fog_token: str) -> None:
        if not self.has_poses or "SEM_LIDAR_TOP" not in self.src.ds.get_sample_paths(fog_token, ["SEM_LIDAR_TOP"]):
            return
        sem = self.src.load(fog_token, "SEM_LIDAR_TOP")
        road = reflect_points(sem[np.isin(sem[:, 5].astype(np.int64), ROAD_TAGS), :3].astype(np.float64))
        g = road @ (self.ego_to_global[k] @ self.lidar_to_ego)[:3, :3].T + (self.ego_to_global[k] @ self.lidar_to_ego)[:3, 3]
        px = np.rint(g[:, 0] / MAP_RESOLUTION).astype(np.int64)  # the devkit's MapMask.to_pixel_coords
        py = np.rint(self.road.shape[0] - g[:, 1] / MAP_RESOLUTION).astype(np.int64)
        ok = (px >= 0) & (px < self.road.shape[1]) & (py >= 0) & (py < self.road.shape[0])
        self.road[py[ok], px[ok]] = 255

    def finish(self, sink: Sink) -> None:
        """Link each vehicle's annotations, set attributes, write the instances, the scene and its map."""
        t = self.tables
        for vid, anns in self.annotations.items():
            for a, b in zip(anns, anns[1:]):
                a["next"], b["prev"] = b["token"], a["token"]
            for i, a in enumerate(anns):
                first, last = anns[max(i - 1, 0)], anns[min(i + 1, len(anns) - 1)]
                dt = last["_time"] - first["_time"]
                if self.has_poses and dt > 0:
                    speed = np.linalg.norm(np.subtract(last["translation"][:2], first["translation"][:2])) / dt
                    a["attribute_tokens"] = [tok("attribute", "vehicle.moving" if speed > MOVING_M_S else "vehicle.stopped")]
            t["instance"].append({"token": anns[0]["instance_token"], "category_token": anns[0]["category_token"],
                                  "nbr_annotations": len(anns), "first_annotation_token": anns[0]["token"],
                                  "last_annotation_token": anns[-1]["token"]})  # fmt: skip
            for a in anns:
                del a["category_token"], a["_time"]
                t["sample_annotation"].append(a)
        names = [s["token"].replace("-", "") for s in self.samples]
        t["scene"].append({"token": self.scene["token"].replace("-", ""), "log_token": self.log,
                           "nbr_samples": len(names), "first_sample_token": names[0], "last_sample_token": names[-1],
                           "name": self.scene["name"], "description": f"{self.scene.get('description', '')}, "
                           f"fog={self.src.fog}"})  # fmt: skip
        map_token = tok("map", self.folder)
        t["map"].append({"token": map_token, "log_tokens": [self.log], "category": "semantic_prior",
                         "filename": f"maps/{map_token}.png"})  # fmt: skip
        road = cv2.dilate(self.road, np.ones((9, 9), np.uint8)) if self.road.any() else self.road
        sink.write(f"maps/{map_token}.png", lambda: _gray_png(road))


def _gray_png(mask: np.ndarray) -> bytes:
    ok, buf = cv2.imencode(".png", mask)
    if not ok:
        raise RuntimeError("PNG encoding failed")
    return buf.tobytes()


def static_tables(src: Source) -> dict[str, list]:
    """The tables that do not depend on the scenes: category, attribute, visibility, sensor."""
    return {
        "category": [{"token": tok("category", name), "name": name,
                      "description": f"FogDrive class {c}: {FOGDRIVE_CLASSES[c]}"}
                     for c, name in NUSCENES_CATEGORIES.items()],
        "attribute": [{"token": tok("attribute", n), "name": n, "description": d} for n, d in ATTRIBUTES.items()],
        "visibility": [{"token": t, "level": lv, "description": f"visibility of whole object is between "
                        f"{lv[1:].replace('-', ' and ')} %"} for t, lv in VISIBILITY.items()],
        "sensor": [{"token": tok("sensor", c), "channel": c, "modality": "lidar" if c == LIDAR else "camera"}
                   for c in (LIDAR, *src.cameras)],
    }  # fmt: skip


def write_nuscenes(src: Source, sink: Sink, bar) -> list[str]:
    """Write the export; returns notes for the user (scenes without ego poses, …). ``bar`` is updated per sample."""
    notes: list[str] = []
    tables: dict[str, list] = {**static_tables(src), **{n: [] for n in ("instance", "calibrated_sensor", "ego_pose",
                               "log", "scene", "sample", "sample_data", "sample_annotation", "map")}}  # fmt: skip
    for scene in src.scenes:
        sc = _Scene(src, scene, tables, notes)
        for k, sample in enumerate(sc.samples):
            sc.add_sample(k, sample, sink)
            bar.update()
        sc.finish(sink)
    if not src.cameras:
        notes.append("the set has no cameras: the export has the LiDAR only, and no visibility per annotation")
    files = {f"{VERSION}/{name}.json": json.dumps(table, indent=0).encode() for name, table in tables.items()}
    splits = {f"fogdrive_{s}": [sc["name"] for sc in src.scenes if src.split_of(sc) == s] for s in ("train", "val", "test")}
    files[f"{VERSION}/splits.json"] = json.dumps(splits, indent=1).encode()  # the devkit's custom splits
    sink.write_all(files)
    return notes

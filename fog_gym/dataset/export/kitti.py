"""KITTI object export: ``OUT/training/{image_2,velodyne,calib,label_2}/<id>`` for the front camera and the same
tree under ``OUT/<CAMERA>/`` for every other camera asked for; ``ImageSets/{train,val,test,trainval}.txt`` beside
each ``training/`` (FogDrive's splits) and ``ImageSets/fogdrive_samples.txt`` (frame id → FogDrive sample).

* ``velodyne/<id>.bin``: float32 × 4 — x, y, z in KITTI's right-handed LiDAR frame (+x forward, +y left, +z up:
  FogDrive's with y negated) and the reflectance in [0, 1] (FogDrive's intensity).
* ``calib/<id>.txt``: the camera is KITTI's reference camera and is already rectified: ``R0_rect`` = I,
  ``P0`` … ``P3`` = ``[K | 0]`` (K from the image size and FogDrive's 100° field of view), ``Tr_velo_to_cam`` = the
  FogDrive extrinsic composed with the reflection, ``Tr_imu_to_velo`` = I.
* ``label_2/<id>.txt``: one line per vehicle annotated in that camera (FogDrive's 2D rule): type (Car, Truck,
  Van), truncation (share of the projected box outside the image), occlusion (0/1/2 from the share of its image
  region hidden by something nearer in the depth image; 3 where the set has no depth), alpha, the 2D box (FogDrive's,
  inclusive pixels), height, width, length [m], location (bottom centre, camera frame) and rotation_y.
"""

from __future__ import annotations

import math

import numpy as np

from fog_gym.dataset.export.common import Boxes, Sink, Source
from fog_gym.dataset.export.frames import (
    FLIP, KITTI_TYPES, camera_intrinsic, kitti_occlusion, occlusion, reflect_points, wrap_angle,
)  # fmt: skip
from fog_gym.geometry import corners_to_boxes
from fog_gym.labels.boxes import boxes_2d as project_boxes

FRONT = "CAM_FRONT"


def tree(camera: str) -> str:
    """The folder of a camera's KITTI tree inside ``OUT`` (the front camera's is ``OUT`` itself)."""
    return "" if camera == FRONT else f"{camera}/"


def _matrix_line(name: str, m: np.ndarray) -> str:
    return f"{name}: " + " ".join(f"{v:.12e}" for v in np.asarray(m, np.float64).ravel())


def calib_text(K: np.ndarray, extrinsic: np.ndarray) -> str:
    """A KITTI calib file for a camera with intrinsic ``K`` and FogDrive extrinsic (LiDAR → camera)."""
    P = np.hstack([K, np.zeros((3, 1))])
    velo_to_cam = (np.asarray(extrinsic, np.float64) @ FLIP)[:3]
    lines = [_matrix_line(f"P{i}", P) for i in range(4)]
    lines += [_matrix_line("R0_rect", np.eye(3)), _matrix_line("Tr_velo_to_cam", velo_to_cam),
              _matrix_line("Tr_imu_to_velo", np.eye(4)[:3])]  # fmt: skip
    return "\n".join(lines) + "\n"


def label_lines(boxes: Boxes, b2: dict[str, np.ndarray], extrinsic: np.ndarray, K: np.ndarray, size: tuple[int, int],
                depth: np.ndarray | None) -> list[str]:  # fmt: skip
    """The KITTI label lines of one camera image (module docstring)."""
    index = {int(v): i for i, v in enumerate(boxes.ids.tolist())}
    E = np.asarray(extrinsic, np.float64)
    lines = []
    for j, vid in enumerate(b2["vehicle_ids"].tolist()):
        i = index.get(int(vid))
        if i is None:  # a 2D box without a 3D box: not FogDrive's rule, never written by fog-gym
            continue
        corners = boxes.corners[i]
        length, width, height, yaw = corners_to_boxes(corners[None])[0, 3:]
        center = corners.mean(axis=0)
        loc = E[:3, :3] @ (center - [0.0, 0.0, height / 2]) + E[:3, 3]
        heading = E[:3, :3] @ [math.cos(yaw), math.sin(yaw), 0.0]
        ry = wrap_angle(math.atan2(-heading[2], heading[0]))
        c_cam = E[:3, :3] @ center + E[:3, 3]
        alpha = wrap_angle(ry - math.atan2(c_cam[0], c_cam[2]))
        truncation = float(project_boxes(corners[None], E, K, size[0], size[1])["truncation"][0])
        if depth is None:
            occluded = 3
        else:
            occluded = kitti_occlusion(occlusion(depth, corners @ E[:3, :3].T + E[:3, 3], K)[0])
        (x0, y0), (x1, y1) = b2["bboxes"][j].tolist()
        kind = KITTI_TYPES.get(int(b2["vehicle_class"][j]), "Misc")
        lines.append(f"{kind} {truncation:.2f} {occluded} {alpha:.4f} {x0:.2f} {y0:.2f} {x1:.2f} {y1:.2f} "
                     f"{height:.4f} {width:.4f} {length:.4f} {loc[0]:.4f} {loc[1]:.4f} {loc[2]:.4f} {ry:.4f}")  # fmt: skip
    return lines


def _velodyne(points: np.ndarray) -> bytes:
    out = np.empty((len(points), 4), np.float32)
    out[:, :3] = reflect_points(points[:, :3])
    out[:, 3] = points[:, 3]
    return out.tobytes()


def write_kitti(src: Source, sink: Sink, bar) -> list[str]:
    """Write the export; returns notes for the user. ``bar`` is updated per sample."""
    notes: list[str] = []
    lists = {cam: {s: [] for s in ("train", "val", "test")} for cam in src.cameras}
    mapping: list[str] = []
    frame = 0
    for scene in src.scenes:
        split = src.split_of(scene)
        extrinsics = {cam: src.extrinsic(scene, cam) for cam in src.cameras}
        for k, sample in enumerate(src.samples(scene)):
            token, fid = sample["token"], f"{frame:06d}"
            velodyne = _velodyne(src.lidar(token))
            boxes = src.boxes(token)
            for cam in src.cameras:
                base = f"{tree(cam)}training"
                size = src.image_size(token, cam)
                K = camera_intrinsic(*size)
                depth = src.depth(token, cam)
                if depth is None and not notes:
                    notes.append("the set has no depth images: every KITTI occlusion is 3 (unknown)")
                sink.copy(f"{base}/image_2/{fid}.png", src.image_path(token, cam))
                sink.write(f"{base}/velodyne/{fid}.bin", velodyne)
                sink.write(f"{base}/calib/{fid}.txt", calib_text(K, extrinsics[cam]).encode())
                labels = label_lines(boxes, src.boxes_2d(token, cam), extrinsics[cam], K, size, depth)
                sink.write(f"{base}/label_2/{fid}.txt", "".join(f"{line}\n" for line in labels).encode())
                lists[cam][split].append(fid)
            mapping.append(f"{fid} {token} {scene['name']} {k}")
            frame += 1
            bar.update()
    for cam in src.cameras:
        sets = {**lists[cam], "trainval": lists[cam]["train"] + lists[cam]["val"]}
        files = {f"{tree(cam)}ImageSets/{name}.txt": "".join(f"{i}\n" for i in ids).encode() for name, ids in sets.items()}
        files[f"{tree(cam)}ImageSets/fogdrive_samples.txt"] = "".join(f"{m}\n" for m in mapping).encode()
        sink.write_all(files)
    return notes

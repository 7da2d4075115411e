"""Sweeps of a FogDrive dataset as training / evaluation items for Experiment 1's detectors (the ``torch`` extra).

An item is one sample of one scene at one fog level: the LiDAR channel of that level
(:data:`~fog_gym.experiments.detection3d.protocol.LEVEL_CHANNEL`) and the sample's ``BBOX_3D`` (the same boxes at
every level: fog changes the sweep, not the world). Ground truth is kept inside the grid (±40 m) and given classes
by height.

**The cache** (:class:`SweepCache`): each sweep is read, cropped to the grid and pillarised once
(:func:`~.pillars.pillarise`), and kept with its ground truth in one ``.npz`` per sweep under the study's output
folder; every epoch, and both detectors, read that. The pillar detector decorates the cached pillars' points
(:func:`~.pillars.pillar_points`); the small BEV detector computes its five hand-made features from the cached
points (:func:`~.bev.point_features`, the same points it would find in the file: the cache keeps every point
inside the grid).

**Augmentation**: each training item is mirrored across the x axis (``y → −y``, yaw → −yaw) and, independently,
across the y axis (``x → −x``, yaw → π − yaw) with probability ½ each (CenterPoint's flips), drawn from
(``seed``, epoch, item), so an epoch is reproducible. The grid is symmetric about the LiDAR, so a mirrored sweep's
pillars are the cached pillars at mirrored cells (:func:`~.pillars.mirror`).
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch

from fog_gym.dataset.access import FogDrive
from fog_gym.dataset.decode import load_channel
from fog_gym.experiments.detection3d.bev import BEVGrid, class_from_height, make_targets, point_features
from fog_gym.experiments.detection3d.pillars import Pillars, mirror, pillar_points, pillarise
from fog_gym.experiments.detection3d.protocol import LEVEL_CHANNEL
from fog_gym.geometry import corners_to_boxes

#: The detectors Experiment 1 trains: the PointPillars encoder with CenterPoint heads, and the small BEV network.
DETECTORS = ("pillars", "bev")


def ground_truth(bbox_3d: dict, grid: BEVGrid) -> dict[str, np.ndarray]:
    """``{"boxes": (N, 7), "classes": (N,)}`` of one BBOX_3D file's boxes inside the grid."""
    boxes = corners_to_boxes(bbox_3d["bboxes_3d"])
    boxes = boxes[grid.in_range(boxes)]
    return {"boxes": boxes, "classes": class_from_height(boxes[:, 5])}


def mirror_boxes(boxes: np.ndarray, flip_y: bool, flip_x: bool) -> np.ndarray:
    """Boxes ``(N, 7)`` mirrored like their sweep (:func:`~.pillars.mirror`)."""
    b = np.array(boxes, np.float64).reshape(-1, 7)
    if flip_y:
        b[:, 1], b[:, 6] = -b[:, 1], -b[:, 6]
    if flip_x:
        b[:, 0], b[:, 6] = -b[:, 0], np.pi - b[:, 6]
    b[:, 6] = (b[:, 6] + np.pi) % (2 * np.pi) - np.pi
    return b


class SweepCache:
    """Pillarised sweeps (on ``grid``) and their ground truth, one ``.npz`` per sweep file under ``folder``; a
    sweep missing there is computed and written (atomically) on first use."""

    VERSION = 1

    def __init__(self, folder: str | Path, grid: BEVGrid) -> None:
        self.folder, self.grid = Path(folder), grid
        g = grid
        self._tag = f"v{self.VERSION}|{g.range_m}|{g.cell_m}|{g.z_min}|{g.z_max}"

    def path(self, lidar_path: str) -> Path:
        st = os.stat(lidar_path)
        key = hashlib.sha1(f"{self._tag}|{os.path.abspath(lidar_path)}|{st.st_size}|{st.st_mtime_ns}".encode())
        name = key.hexdigest()
        return self.folder / name[:2] / f"{name}.npz"

    def get(self, channel: str, lidar_path: str, box_path: str) -> tuple[Pillars, dict[str, np.ndarray]]:
        path = self.path(lidar_path)
        try:
            with np.load(path) as z:
                return Pillars.load(z), {"boxes": z["gt_boxes"], "classes": z["gt_classes"]}
        except (FileNotFoundError, ValueError, OSError, KeyError):
            pass
        within = "/".join(Path(lidar_path).parts[-3:])  # scene folder / channel folder / file: where the set lies does not count
        p = pillarise(load_channel(channel, lidar_path), self.grid, seed=int(hashlib.sha1(within.encode()).hexdigest()[:8], 16))
        gt = ground_truth(load_channel("BBOX_3D", box_path), self.grid)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp.npz")
        np.savez(tmp, **p.save(), gt_boxes=gt["boxes"], gt_classes=gt["classes"])
        os.replace(tmp, path)
        return p, gt


def sweep_items(ds: FogDrive, pairs: Sequence[tuple[str, str]], every: int = 1) -> list[tuple[str, str, str, str]]:
    """``(LiDAR channel, its file, the BBOX_3D file, scene name)`` of every ``every``-th sample of each (scene,
    level) pair."""
    if isinstance(every, bool) or not isinstance(every, int) or every < 1:
        raise ValueError(f"every must be a positive integer, got {every!r}")
    items = []
    for scene_name, level in pairs:
        if level not in LEVEL_CHANNEL:
            raise ValueError(f"level must be one of {tuple(LEVEL_CHANNEL)}, got {level!r}")
        channel = LEVEL_CHANNEL[level]
        scene = ds.get_scene_by_name(scene_name)
        for s in ds.get_samples_for_scene(scene["token"])[::every]:
            paths = ds.get_sample_paths(s["token"], [channel, "BBOX_3D"])
            if len(paths) != 2:
                raise ValueError(f"scene {scene_name} has no {channel} channel")
            items.append((channel, str(paths[channel]), str(paths["BBOX_3D"]), scene_name))
    return items


class SweepDataset(torch.utils.data.Dataset):
    """Items for one detector (``"pillars"`` or ``"bev"``) over (scene, level) pairs; every ``every``-th sample.

    ``grid`` is the detector's grid (its targets' output cells); the cache's grid must cover the same range and
    heights. ``augment`` mirrors items as the module docstring says."""

    def __init__(self, ds: FogDrive, pairs: Sequence[tuple[str, str]], cache: SweepCache, detector: str = "pillars",
                 grid: BEVGrid | None = None, every: int = 1, augment: bool = False, seed: int = 0,
                 max_points: int = 32) -> None:  # fmt: skip
        if detector not in DETECTORS:
            raise ValueError(f"detector must be one of {DETECTORS}, got {detector!r}")
        self.cache, self.detector = cache, detector
        self.grid = grid or cache.grid
        g, c = self.grid, cache.grid
        if (g.range_m, g.z_min, g.z_max) != (c.range_m, c.z_min, c.z_max) or (detector == "pillars" and g.cell_m != c.cell_m):
            raise ValueError(f"the detector's grid {g} does not match the cache's {c}")
        self.augment, self.seed, self.epoch, self.max_points = augment, seed, 0, max_points
        self.items = sweep_items(ds, pairs, every)
        if not self.items:
            raise ValueError("the subset has no sweeps")

    def __len__(self) -> int:
        return len(self.items)

    def thin(self, n: int, seed: int) -> None:
        """Keep ``n`` of the items, a uniform random subset drawn from ``seed`` (in their original order)."""
        if n < len(self.items):
            keep = np.sort(np.random.default_rng([seed, 0x7A1]).choice(len(self.items), n, replace=False))
            self.items = [self.items[k] for k in keep]

    def flips(self, i: int) -> tuple[bool, bool]:
        if not self.augment:
            return False, False
        u = np.random.default_rng([self.seed, self.epoch, i]).random(2)
        return bool(u[0] < 0.5), bool(u[1] < 0.5)

    def __getitem__(self, i: int):
        channel, lidar_path, box_path, _ = self.items[i]
        p, gt = self.cache.get(channel, lidar_path, box_path)
        flip_y, flip_x = self.flips(i)
        if flip_y or flip_x:
            p = mirror(p, self.cache.grid, flip_y, flip_x)
            gt = {"boxes": mirror_boxes(gt["boxes"], flip_y, flip_x), "classes": gt["classes"]}
        targets = make_targets(gt["boxes"], gt["classes"], self.grid)
        if self.detector == "pillars":
            feats, pillar = pillar_points(p, self.grid, self.max_points)
            return {"feats": feats, "pillar": pillar, "cells": p.cells}, targets, gt
        return {"x": point_features(p.points, self.grid)}, targets, gt


def collate(batch) -> dict[str, Any]:
    """A batch: the model's ``inputs`` (stacked BEV features, or the pillars' points with their pillar, cell and
    sample indices), heatmaps, the boxes' centre cells with their batch index, regression targets, ground truth."""
    inputs = [b[0] for b in batch]
    if "x" in inputs[0]:
        model_inputs = {"x": torch.from_numpy(np.stack([b["x"] for b in inputs]))}
    else:
        sizes = np.array([len(b["cells"]) for b in inputs])
        offsets = np.concatenate([[0], np.cumsum(sizes)[:-1]])
        model_inputs = {
            "feats": torch.from_numpy(np.concatenate([b["feats"] for b in inputs])),
            "pillar": torch.from_numpy(np.concatenate([b["pillar"] + o for b, o in zip(inputs, offsets)]).astype(np.int64)),
            "cells": torch.from_numpy(np.concatenate([b["cells"] for b in inputs]).astype(np.int64)),
            "batch": torch.from_numpy(np.repeat(np.arange(len(inputs)), sizes).astype(np.int64)),
            "batch_size": len(inputs),
        }  # fmt: skip
    t = [b[1] for b in batch]
    return {
        "inputs": model_inputs,
        "heatmap": torch.from_numpy(np.stack([x["heatmap"] for x in t])),
        "batch_index": torch.from_numpy(np.concatenate([np.full(len(x["index"]), k) for k, x in enumerate(t)]).astype(np.int64)),
        "cell_index": torch.from_numpy(np.concatenate([x["index"] for x in t]).astype(np.int64)),
        "regression": torch.from_numpy(np.concatenate([x["regression"] for x in t]).reshape(-1, 8).astype(np.float32)),
        "gt": [b[2] for b in batch],
    }  # fmt: skip


def to_device(inputs: dict[str, Any], device: torch.device) -> dict[str, Any]:
    return {k: v.to(device, non_blocking=True) if torch.is_tensor(v) else v for k, v in inputs.items()}

"""Sweeps of a FogDrive dataset as training / evaluation items for the BEV detector (the ``torch`` extra).

An item is one sample of one scene at one fog level: the LiDAR channel of that level
(:data:`~fog_gym.experiments.detection3d.protocol.LEVEL_CHANNEL`) and the sample's ``BBOX_3D`` (the same boxes at every level:
fog changes the sweep, not the world). Ground truth is kept inside the grid (±40 m) and given classes by height.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch

from fog_gym.dataset.access import FogDrive
from fog_gym.dataset.decode import load_channel
from fog_gym.experiments.detection3d.bev import BEVGrid, class_from_height, make_targets, point_features
from fog_gym.experiments.detection3d.protocol import LEVEL_CHANNEL
from fog_gym.geometry import corners_to_boxes


def ground_truth(bbox_3d: dict, grid: BEVGrid) -> dict[str, np.ndarray]:
    """``{"boxes": (N, 7), "classes": (N,)}`` of one BBOX_3D file's boxes inside the grid."""
    boxes = corners_to_boxes(bbox_3d["bboxes_3d"])
    boxes = boxes[grid.in_range(boxes)]
    return {"boxes": boxes, "classes": class_from_height(boxes[:, 5])}


class SweepDataset(torch.utils.data.Dataset):
    """Items ``(features (5, H, W), targets, ground truth)`` for (scene, level) pairs; every ``every``-th sample.

    ``augment`` mirrors half the items left–right (y → −y, yaw → −yaw) with a generator seeded by ``seed`` and the
    item index, so an epoch is reproducible.
    """

    def __init__(self, ds: FogDrive, pairs: Sequence[tuple[str, str]], grid: BEVGrid = BEVGrid(), every: int = 1,
                 augment: bool = False, seed: int = 0) -> None:  # fmt: skip
        if every < 1:
            raise ValueError(f"every must be >= 1, got {every}")
        self.grid, self.augment, self.seed, self.epoch = grid, augment, seed, 0
        self.items: list[tuple[str, str, str]] = []  # (LiDAR channel, its file, the BBOX_3D file)
        for scene_name, level in pairs:
            if level not in LEVEL_CHANNEL:
                raise ValueError(f"level must be one of {tuple(LEVEL_CHANNEL)}, got {level!r}")
            scene = ds.get_scene_by_name(scene_name)
            for s in ds.get_samples_for_scene(scene["token"])[::every]:
                paths = ds.get_sample_paths(s["token"], [LEVEL_CHANNEL[level], "BBOX_3D"])
                if len(paths) != 2:
                    raise ValueError(f"scene {scene_name} has no {LEVEL_CHANNEL[level]} channel")
                channel = LEVEL_CHANNEL[level]
                self.items.append((channel, str(paths[channel]), str(paths["BBOX_3D"])))

    def __len__(self) -> int:
        return len(self.items)

    def __getitem__(self, i: int):
        channel, lidar_path, box_path = self.items[i]
        points = load_channel(channel, lidar_path)
        gt = ground_truth(load_channel("BBOX_3D", box_path), self.grid)
        if self.augment and np.random.default_rng([self.seed, self.epoch, i]).random() < 0.5:
            points = points * np.float32([1, -1, 1, 1])
            gt = {"boxes": gt["boxes"] * [1, -1, 1, 1, 1, 1, -1], "classes": gt["classes"]}
        return point_features(points, self.grid), make_targets(gt["boxes"], gt["classes"], self.grid), gt


def collate(batch):
    """Stack features and heatmaps; concatenate the boxes' centre cells with their batch index."""
    feats = torch.from_numpy(np.stack([b[0] for b in batch]))
    heat = torch.from_numpy(np.stack([b[1]["heatmap"] for b in batch]))
    bidx = torch.from_numpy(np.concatenate([np.full(len(b[1]["index"]), k) for k, b in enumerate(batch)]).astype(np.int64))
    cidx = torch.from_numpy(np.concatenate([b[1]["index"] for b in batch]).astype(np.int64))
    reg = torch.from_numpy(np.concatenate([b[1]["regression"] for b in batch]).reshape(-1, 8).astype(np.float32))
    return feats, heat, bidx, cidx, reg, [b[2] for b in batch]

"""A small CenterNet 2D detector ("Objects as Points", Zhou et al. 2019) in pure PyTorch for Experiment 2.

Why not a library detector: torchvision's detectors (FCOS, RetinaNet, Faster R-CNN) are the natural choice, but
PyPI's torchvision does not import beside the CPU build of torch 2.13.0 the project pins, and the only
torchvision that does is a 5.5 GB CUDA build — too heavy for CI; every other maintained detection library we
checked (ultralytics, timm/effdet, detectron2, mmdet) depends on torchvision or on compiled CUDA ops. So the
network is ours (0.25 M parameters at the default width) and the evaluation is the COCO reference (:mod:`fog_gym.metrics.detection2d`).

Images are resized to ``input_size`` (320 × 240 by default, FogDrive's 4:3); a strided stem and three stages
(strides 4, 8, 16) merged top-down to stride 4 feed CenterNet's heads: a per-class centre heatmap (Gaussian focal
loss, shared with the 3D detector), box width/height in output cells (L1, weight 0.1) and the sub-cell offset (L1).
Decoding keeps 3 × 3 local maxima. Classes: car (0), bigger car (4), truck (1).
"""

from __future__ import annotations

import math

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F

from fog_gym.experiments.detection3d.model import _block, focal_loss

CLASSES = (0, 4, 1)
STRIDE = 4


class CenterNet2D(nn.Module):
    """``forward(images (B, 3, H, W) in [0, 1]) → {"heatmap": (B, K, H/4, W/4) logits, "wh": (B, 2, …),
    "offset": (B, 2, …)}``."""

    def __init__(self, width: int = 24, classes: int = len(CLASSES)) -> None:
        super().__init__()
        w = width
        self.stem = _block(3, w, 2, 1)  # /2
        self.s4 = _block(w, w, 2, 2)  # /4
        self.s8 = _block(w, 2 * w, 2, 2)  # /8
        self.s16 = _block(2 * w, 4 * w, 2, 2)  # /16
        self.l16 = nn.Conv2d(4 * w, 2 * w, 1)
        self.m8 = _block(4 * w, 2 * w, 1, 1)
        self.l8 = nn.Conv2d(2 * w, w, 1)
        self.m4 = _block(2 * w, w, 1, 2)
        self.heat = nn.Sequential(nn.Conv2d(w, w, 3, 1, 1), nn.ReLU(inplace=True), nn.Conv2d(w, classes, 1))
        self.wh = nn.Sequential(nn.Conv2d(w, w, 3, 1, 1), nn.ReLU(inplace=True), nn.Conv2d(w, 2, 1))
        self.offset = nn.Sequential(nn.Conv2d(w, w, 3, 1, 1), nn.ReLU(inplace=True), nn.Conv2d(w, 2, 1))
        nn.init.constant_(self.heat[-1].bias, -2.19)

    def forward(self, x: torch.Tensor) -> dict[str, torch.Tensor]:
        f4 = self.s4(self.stem(x))
        f8 = self.s8(f4)
        f16 = self.s16(f8)
        m8 = self.m8(torch.cat([f8, F.interpolate(self.l16(f16), size=f8.shape[-2:], mode="nearest")], 1))
        m4 = self.m4(torch.cat([f4, F.interpolate(self.l8(m8), size=f4.shape[-2:], mode="nearest")], 1))
        return {"heatmap": self.heat(m4), "wh": self.wh(m4), "offset": self.offset(m4)}


def gaussian_radius(h: float, w: float, min_overlap: float = 0.7) -> float:
    """CenterNet's radius for a box of ``h`` × ``w`` cells: corners within it keep IoU ≥ ``min_overlap``."""
    a1, b1, c1 = 1, h + w, w * h * (1 - min_overlap) / (1 + min_overlap)
    r1 = (b1 + math.sqrt(b1**2 - 4 * a1 * c1)) / 2
    a2, b2, c2 = 4, 2 * (h + w), (1 - min_overlap) * w * h
    r2 = (b2 + math.sqrt(b2**2 - 4 * a2 * c2)) / 2
    a3, b3, c3 = 4 * min_overlap, -2 * min_overlap * (h + w), (min_overlap - 1) * w * h
    r3 = (b3 + math.sqrt(b3**2 - 4 * a3 * c3)) / 2
    return max(0.0, min(r1, r2, r3))


def make_targets(boxes: np.ndarray, classes: np.ndarray, out_hw: tuple[int, int]) -> dict[str, np.ndarray]:
    """Targets on the stride-4 output grid for boxes ``(N, 4)`` ``[x0, y0, x1, y1]`` in *input* pixels."""
    h, w = out_hw
    b = np.asarray(boxes, np.float64).reshape(-1, 4) / STRIDE
    cls = np.asarray(classes, np.int64).reshape(-1)
    keep = np.isin(cls, CLASSES) & (b[:, 2] > b[:, 0]) & (b[:, 3] > b[:, 1])
    b, cls = b[keep], cls[keep]
    cx, cy = (b[:, 0] + b[:, 2]) / 2, (b[:, 1] + b[:, 3]) / 2
    ix, iy = np.clip(np.floor(cx), 0, w - 1).astype(np.int64), np.clip(np.floor(cy), 0, h - 1).astype(np.int64)
    heat = np.zeros((len(CLASSES), h, w), np.float32)
    ys, xs = np.arange(h)[:, None], np.arange(w)[None, :]
    for k in range(len(b)):
        r = max(0, int(gaussian_radius(b[k, 3] - b[k, 1], b[k, 2] - b[k, 0])))
        sigma = (2 * r + 1) / 6
        g = np.exp(-((xs - ix[k]) ** 2 + (ys - iy[k]) ** 2) / (2 * sigma * sigma)).astype(np.float32)
        c = CLASSES.index(int(cls[k]))
        heat[c] = np.maximum(heat[c], g)
    return {"heatmap": heat, "index": iy * w + ix, "wh": np.stack([b[:, 2] - b[:, 0], b[:, 3] - b[:, 1]], 1).astype(np.float32),
            "offset": np.stack([cx - ix, cy - iy], 1).astype(np.float32)}  # fmt: skip


def loss_fn(out: dict[str, torch.Tensor], heatmap: torch.Tensor, batch_index: torch.Tensor, cell_index: torch.Tensor,
            wh: torch.Tensor, offset: torch.Tensor) -> tuple[torch.Tensor, dict[str, float]]:  # fmt: skip
    lh = focal_loss(out["heatmap"], heatmap)
    b, _, h, w = out["wh"].shape
    if len(cell_index):
        pw = out["wh"].permute(0, 2, 3, 1).reshape(b, h * w, 2)[batch_index, cell_index]
        po = out["offset"].permute(0, 2, 3, 1).reshape(b, h * w, 2)[batch_index, cell_index]
        lw, lo = F.l1_loss(pw, wh), F.l1_loss(po, offset)
    else:
        lw = lo = out["wh"].sum() * 0.0
    total = lh + 0.1 * lw + lo
    return total, {"heatmap": float(lh.detach()), "wh": float(lw.detach()), "offset": float(lo.detach())}


@torch.no_grad()
def decode(out: dict[str, torch.Tensor], threshold: float = 0.05, top_k: int = 100,
           scale: tuple[float, float] = (1.0, 1.0)) -> list[dict[str, np.ndarray]]:  # fmt: skip
    """Per image ``{"boxes" (N, 4) [x0, y0, x1, y1], "classes", "scores"}``, boxes multiplied by ``scale`` (sx, sy)
    to go from input pixels back to the original image."""
    heat = torch.sigmoid(out["heatmap"])
    heat = heat * (heat == F.max_pool2d(heat, 3, 1, 1))
    b, k, h, w = heat.shape
    scores, flat = heat.reshape(b, -1).topk(min(top_k, k * h * w))
    wh = out["wh"].permute(0, 2, 3, 1).reshape(b, h * w, 2)
    off = out["offset"].permute(0, 2, 3, 1).reshape(b, h * w, 2)
    res = []
    for i in range(b):
        m = scores[i] >= threshold
        cls, cell = flat[i][m] // (h * w), flat[i][m] % (h * w)
        cx = (cell % w).float() + off[i, cell, 0]
        cy = (cell // w).float() + off[i, cell, 1]
        bw, bh = wh[i, cell, 0].clamp(min=0), wh[i, cell, 1].clamp(min=0)
        boxes = torch.stack([cx - bw / 2, cy - bh / 2, cx + bw / 2, cy + bh / 2], 1) * STRIDE
        boxes = boxes * torch.tensor([scale[0], scale[1], scale[0], scale[1]])
        res.append({"boxes": boxes.cpu().numpy().astype(np.float64), "classes": np.asarray(CLASSES)[cls.cpu().numpy()],
                    "scores": scores[i][m].cpu().numpy()})  # fmt: skip
    return res

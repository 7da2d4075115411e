"""A one-stage, anchor-free 2D detector of the YOLO family in pure PyTorch (CPU or CUDA), trained from scratch.

Written from the published designs (no code of theirs): CSP blocks with a split-and-concatenate bottleneck stack
(CSPNet, Wang et al. 2019; the C2f form of YOLOv8) and a fast spatial pyramid pooling block (SPPF) in the
backbone; a PAN-FPN neck (Liu et al. 2018) that merges the scales top-down and again bottom-up; a decoupled head
per output level — a box branch predicting each side's distance as a distribution over ``reg_max`` bins
(Distribution Focal Loss, GFL, Li et al. 2020) and a class branch — with one prediction per location and no anchor
boxes. Training (:mod:`~.yolo_loss`): TOOD's task-aligned assignment (Feng et al. 2021), a binary cross-entropy
class loss against the alignment-weighted soft targets, the CIoU box loss (Zheng et al. 2020) and DFL.

Small objects: fog-gym's frames hold many vehicles under 12 pixels high (at 640 × 480, 41 % of the boxes), so the
output levels are strides **4, 8 and 16** (P2–P4; the backbone still reaches stride 32 for context) rather than
YOLO's usual 8, 16, 32: a stride-8 grid has no cell centre inside a 5-pixel box.

:class:`YoloConfig` holds width, depth and ``reg_max``; ``YoloConfig()`` is the CPU configuration and
:data:`GPU_YOLO` the GPU one.

Example:
    >>> net = YoloDetector(YoloConfig(width=8, depth=1))
    >>> out = net(torch.zeros(1, 3, 96, 128))
    >>> [tuple(o.shape) for o in out]  # per level (B, 4·reg_max + classes, H/s, W/s)
    [(1, 67, 24, 32), (1, 67, 12, 16), (1, 67, 6, 8)]
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F
from numba import njit

#: FogDrive class ids in the detector's channel order: car, bigger car, truck.
CLASSES = (0, 4, 1)
STRIDES = (4, 8, 16)


@dataclass(frozen=True)
class YoloConfig:
    """Base ``width`` (stem channels; the stages have w, 2w, 4w, 8w, 8w), ``depth`` (bottlenecks per CSP block,
    doubled in the middle stages) and ``reg_max`` (bins of each side's distance distribution, in stride units)."""

    width: int = 16
    depth: int = 1
    reg_max: int = 16
    classes: int = len(CLASSES)

    def __post_init__(self) -> None:
        for name in ("width", "depth", "reg_max", "classes"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ValueError(f"{name} must be a positive integer, got {v!r}")
        if self.reg_max < 2:
            raise ValueError(f"reg_max must be >= 2, got {self.reg_max}")


#: The GPU configuration: twice the width and depth.
GPU_YOLO = YoloConfig(width=32, depth=2)


class Conv(nn.Sequential):
    """Convolution, batch norm, SiLU."""

    def __init__(self, cin: int, cout: int, k: int = 1, s: int = 1) -> None:
        super().__init__(nn.Conv2d(cin, cout, k, s, k // 2, bias=False), nn.BatchNorm2d(cout), nn.SiLU(inplace=True))


class Bottleneck(nn.Module):
    def __init__(self, c: int, shortcut: bool = True) -> None:
        super().__init__()
        self.cv1, self.cv2, self.add = Conv(c, c, 3), Conv(c, c, 3), shortcut

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        y = self.cv2(self.cv1(x))
        return x + y if self.add else y


class C2f(nn.Module):
    """CSP block: a 1 × 1 convolution to ``2c``, split in halves; ``n`` bottlenecks on the second half, one after
    another; every intermediate output concatenated and fused by a 1 × 1 convolution."""

    def __init__(self, cin: int, cout: int, n: int = 1, shortcut: bool = True) -> None:
        super().__init__()
        self.c = cout // 2
        self.cv1 = Conv(cin, 2 * self.c)
        self.m = nn.ModuleList(Bottleneck(self.c, shortcut) for _ in range(n))
        self.cv2 = Conv((2 + n) * self.c, cout)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        y = list(self.cv1(x).chunk(2, 1))
        for m in self.m:
            y.append(m(y[-1]))
        return self.cv2(torch.cat(y, 1))


class SPPF(nn.Module):
    """Spatial pyramid pooling, fast: three 5 × 5 max-pools in sequence, concatenated with their input."""

    def __init__(self, c: int) -> None:
        super().__init__()
        self.cv1, self.cv2 = Conv(c, c // 2), Conv(2 * c, c)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        y = [self.cv1(x)]
        for _ in range(3):
            y.append(F.max_pool2d(y[-1], 5, 1, 2))
        return self.cv2(torch.cat(y, 1))


class Head(nn.Module):
    """Decoupled head of one level: a box branch (``4 · reg_max`` distribution logits) and a class branch."""

    def __init__(self, c: int, reg_max: int, classes: int, stride: int) -> None:
        super().__init__()
        cb = max(16, c, 4 * reg_max // 2)
        self.box = nn.Sequential(Conv(c, cb, 3), Conv(cb, cb, 3), nn.Conv2d(cb, 4 * reg_max, 1))
        self.cls = nn.Sequential(Conv(c, c, 3), Conv(c, c, 3), nn.Conv2d(c, classes, 1))
        # each side's distance distribution starts ∝ e^(−k/2) over bins k: an expected 1.5 strides, so that the first
        # predicted boxes are near the size of the level's objects (YOLOv8 starts from a flat distribution — 7.5
        # strides — whose boxes overlap a small object so little that its task-aligned targets, and with them its
        # box loss, stay near zero for a long time: fatal for the 5-pixel vehicles here on a CPU budget)
        with torch.no_grad():
            self.box[-1].bias.copy_((-0.5 * torch.arange(reg_max, dtype=torch.float32)).repeat(4))
        # a prior of ≈ 5 objects per 640 × 640 image spread over the level's cells (YOLOv8's initialisation)
        nn.init.constant_(self.cls[-1].bias, math.log(5 / classes / (640 / stride) ** 2))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return torch.cat([self.box(x), self.cls(x)], 1)


class YoloDetector(nn.Module):
    """``forward(images (B, 3, H, W) in [0, 1])`` → per output level ``(B, 4·reg_max + classes, H/s, W/s)`` for
    strides 4, 8, 16 (H and W multiples of 32)."""

    strides = STRIDES

    def __init__(self, config: YoloConfig = YoloConfig()) -> None:
        super().__init__()
        self.config = c = config
        w, n = c.width, c.depth
        self.stem = Conv(3, w, 3, 2)  # /2
        self.b2 = nn.Sequential(Conv(w, 2 * w, 3, 2), C2f(2 * w, 2 * w, n))  # /4
        self.b3 = nn.Sequential(Conv(2 * w, 4 * w, 3, 2), C2f(4 * w, 4 * w, 2 * n))  # /8
        self.b4 = nn.Sequential(Conv(4 * w, 8 * w, 3, 2), C2f(8 * w, 8 * w, 2 * n))  # /16
        self.b5 = nn.Sequential(Conv(8 * w, 8 * w, 3, 2), C2f(8 * w, 8 * w, n), SPPF(8 * w))  # /32
        # top-down (FPN)
        self.td4 = C2f(16 * w, 8 * w, n, shortcut=False)
        self.td3 = C2f(12 * w, 4 * w, n, shortcut=False)
        self.td2 = C2f(6 * w, 2 * w, n, shortcut=False)
        # bottom-up (PAN)
        self.down2 = Conv(2 * w, 2 * w, 3, 2)
        self.bu3 = C2f(6 * w, 4 * w, n, shortcut=False)
        self.down3 = Conv(4 * w, 4 * w, 3, 2)
        self.bu4 = C2f(12 * w, 8 * w, n, shortcut=False)
        self.heads = nn.ModuleList(Head(ch, c.reg_max, c.classes, s) for ch, s in zip((2 * w, 4 * w, 8 * w), STRIDES))

    def forward(self, x: torch.Tensor) -> list[torch.Tensor]:
        if x.shape[-1] % 32 or x.shape[-2] % 32:
            raise ValueError(f"image height and width must be multiples of 32, got {tuple(x.shape[-2:])}")
        p2 = self.b2(self.stem(x))
        p3 = self.b3(p2)
        p4 = self.b4(p3)
        p5 = self.b5(p4)
        up = lambda t: F.interpolate(t, scale_factor=2.0, mode="nearest")  # noqa: E731
        n4 = self.td4(torch.cat([up(p5), p4], 1))
        n3 = self.td3(torch.cat([up(n4), p3], 1))
        o2 = self.td2(torch.cat([up(n3), p2], 1))
        o3 = self.bu3(torch.cat([self.down2(o2), n3], 1))
        o4 = self.bu4(torch.cat([self.down3(o3), n4], 1))
        return [h(o).float() for h, o in zip(self.heads, (o2, o3, o4))]


def anchor_points(shapes: list[tuple[int, int]], strides=STRIDES, device=None) -> tuple[torch.Tensor, torch.Tensor]:
    """Cell centres ``(A, 2)`` (x, y) in pixels of every level's ``(H, W)`` grid, row-major, level after level,
    and each one's stride ``(A,)``."""
    pts, st = [], []
    for (h, w), s in zip(shapes, strides, strict=True):
        ys, xs = torch.meshgrid(torch.arange(h, device=device), torch.arange(w, device=device), indexing="ij")
        pts.append((torch.stack([xs, ys], -1).reshape(-1, 2).float() + 0.5) * s)
        st.append(torch.full((h * w,), float(s), device=device))
    return torch.cat(pts), torch.cat(st)


def flatten(outputs: list[torch.Tensor], reg_max: int) -> tuple[torch.Tensor, torch.Tensor]:
    """The levels' outputs as ``(B, A, 4, reg_max)`` distance logits and ``(B, A, classes)`` class logits."""
    b = outputs[0].shape[0]
    flat = torch.cat([o.flatten(2) for o in outputs], 2).transpose(1, 2)  # (B, A, C)
    return flat[..., : 4 * reg_max].reshape(b, -1, 4, reg_max), flat[..., 4 * reg_max :]


def distances(dist_logits: torch.Tensor) -> torch.Tensor:
    """Expected distance (in stride units) of each side: ``Σ softmax(logits) · bin`` → ``(…, 4)``."""
    bins = torch.arange(dist_logits.shape[-1], dtype=dist_logits.dtype, device=dist_logits.device)
    return (dist_logits.softmax(-1) * bins).sum(-1)


def boxes_from_distances(points: torch.Tensor, ltrb: torch.Tensor) -> torch.Tensor:
    """Boxes ``[x0, y0, x1, y1]`` from points and their left/top/right/bottom distances (pixels)."""
    return torch.cat([points - ltrb[..., :2], points + ltrb[..., 2:]], -1)


def parameter_count(model: nn.Module) -> int:
    return sum(p.numel() for p in model.parameters())


@njit(cache=True, nogil=True)
def _nms(boxes, order, iou_threshold, max_keep):
    """Greedy non-maximum suppression over ``boxes`` (N, 4) visited in ``order`` (descending score)."""
    n = len(order)
    suppressed = np.zeros(n, np.bool_)
    keep = np.empty(min(n, max_keep), np.int64)
    m = 0
    for ii in range(n):
        if m >= max_keep:
            break
        i = order[ii]
        if suppressed[ii]:
            continue
        keep[m] = i
        m += 1
        ax0, ay0, ax1, ay1 = boxes[i, 0], boxes[i, 1], boxes[i, 2], boxes[i, 3]
        area_a = max(ax1 - ax0, 0.0) * max(ay1 - ay0, 0.0)
        for jj in range(ii + 1, n):
            if suppressed[jj]:
                continue
            j = order[jj]
            iw = min(ax1, boxes[j, 2]) - max(ax0, boxes[j, 0])
            ih = min(ay1, boxes[j, 3]) - max(ay0, boxes[j, 1])
            if iw <= 0.0 or ih <= 0.0:
                continue
            inter = iw * ih
            area_b = max(boxes[j, 2] - boxes[j, 0], 0.0) * max(boxes[j, 3] - boxes[j, 1], 0.0)
            if inter / (area_a + area_b - inter) > iou_threshold:
                suppressed[jj] = True
    return keep[:m]


def nms(boxes: np.ndarray, scores: np.ndarray, classes: np.ndarray, iou_threshold: float = 0.6,
        max_keep: int = 300) -> np.ndarray:  # fmt: skip
    """Indices kept by class-aware greedy NMS (boxes of different classes never suppress each other), in
    descending score, at most ``max_keep``.

    >>> b = np.array([[0, 0, 10, 10], [1, 1, 11, 11], [0, 0, 10, 10]], float)
    >>> nms(b, np.array([0.9, 0.8, 0.7]), np.array([0, 0, 1])).tolist()
    [0, 2]
    """
    b = np.asarray(boxes, np.float64).reshape(-1, 4)
    if len(b) == 0:
        return np.zeros(0, np.int64)
    span = float(b.max()) + 1.0
    shifted = b + (np.asarray(classes, np.float64) * span * 2.0)[:, None]  # classes far apart: never overlapping
    order = np.argsort(-np.asarray(scores, np.float64), kind="stable")
    return _nms(shifted, order, float(iou_threshold), int(max_keep))


@torch.no_grad()
def decode(outputs: list[torch.Tensor], reg_max: int = 16, conf: float = 0.001, iou: float = 0.6, max_det: int = 300,
           pre_nms: int = 5000) -> list[dict[str, np.ndarray]]:  # fmt: skip
    """Per image ``{"boxes" (N, 4) pixels at the input size, "classes" FogDrive ids, "scores"}``: every (location,
    class) pair scoring at least ``conf`` (several classes per location, as YOLO's validation), the best
    ``pre_nms``, class-aware NMS at IoU ``iou``, at most ``max_det`` (the paper's validation settings: conf 0.001,
    NMS IoU 0.6)."""
    dist_logits, cls_logits = flatten(outputs, reg_max)
    points, stride = anchor_points([tuple(o.shape[-2:]) for o in outputs], STRIDES, outputs[0].device)
    boxes = boxes_from_distances(points, distances(dist_logits.float()) * stride[:, None]).cpu().numpy()
    scores = cls_logits.float().sigmoid().cpu().numpy()
    k = scores.shape[-1]
    out = []
    for i in range(len(boxes)):
        flat = scores[i].reshape(-1)
        cand = np.flatnonzero(flat >= conf)
        if len(cand) > pre_nms:
            cand = cand[np.argpartition(-flat[cand], pre_nms - 1)[:pre_nms]]
        anchor, cls = cand // k, cand % k
        keep = nms(boxes[i][anchor], flat[cand], cls, iou, max_det)
        out.append({"boxes": boxes[i][anchor[keep]], "classes": np.asarray(CLASSES)[cls[keep]], "scores": flat[cand][keep]})
    return out

"""Experiment 2's data: the scenes chosen per split, the camera frames of those scenes, images at a fog level with
their ground-truth boxes, the detectors' training set (flips and colour jitter) and the evaluation sets.

Scenes are subsampled uniformly per split (paper 15 / 20 / 20 % of train / val / test); every ``every``-th sample
of a chosen scene is used, from each camera. Dehazers work on the full-resolution frame; then every image is
resized to the detector's input size, where detection runs and PSNR / SSIM against the paired clean frame are
measured.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import cv2
import numpy as np
import torch

from fog_gym.dataset.access import FogDrive
from fog_gym.dataset.decode import load_channel
from fog_gym.experiments.defog.model import STRIDE, make_targets

CAMERAS = ("CAM_FRONT", "CAM_LEFT")
LEVELS = ("light", "moderate", "dense")
FOV = 100.0  # the FogDrive cameras' horizontal field of view [deg] (supplementary D5)


@dataclass(frozen=True)
class Frame:
    """One camera image of one sample, and the first sample of its scene (the airlight's frame)."""

    scene: str
    sample: str
    first: str
    camera: str


def choose_scenes(names: Sequence[str], fraction: float, seed: int) -> list[str]:
    """A uniform random ``fraction`` of the scenes (at least one), sorted.

    >>> choose_scenes([f"s{i}" for i in range(10)], 0.2, 0)
    ['s4', 's6']
    """
    names = sorted(names)
    if not names:
        raise ValueError("the split has no scenes")
    k = max(1, int(round(len(names) * fraction)))
    return sorted(names[i] for i in np.random.default_rng(seed).permutation(len(names))[:k])


def frames(ds: FogDrive, scenes: Sequence[str], every: int, cameras: Sequence[str]) -> list[Frame]:
    out = []
    for name in scenes:
        samples = ds.get_samples_for_scene(ds.get_scene_by_name(name)["token"])
        out += [Frame(name, s["token"], samples[0]["token"], cam) for s in samples[::every] for cam in cameras]
    return out


def channel(camera: str, level: str) -> str:
    """The image channel of a camera at a fog level ("clean" or a level name)."""
    return camera if level == "clean" else f"{camera}_FOG_{level.upper()}"


def load_image(ds: FogDrive, f: Frame, level: str) -> np.ndarray:
    ch = channel(f.camera, level)
    return load_channel(ch, ds.get_sample_paths(f.sample, [ch])[ch])


def load_boxes(ds: FogDrive, f: Frame) -> tuple[np.ndarray, np.ndarray]:
    """Ground-truth boxes ``(N, 4)`` ``[x0, y0, x1, y1]`` in pixels (edges; the file's corners are inclusive pixel
    indices) and their classes."""
    ch = f"{f.camera}_BBOX"
    b = load_channel(ch, ds.get_sample_paths(f.sample, [ch])[ch])
    corners = b["bboxes"].reshape(-1, 4).astype(np.float64)
    return corners + np.array([0.0, 0.0, 1.0, 1.0]), b["vehicle_class"]


def resize(image: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    return image if image.shape[1::-1] == tuple(size) else cv2.resize(image, size, interpolation=cv2.INTER_AREA)


def intrinsic(width: int, height: int) -> np.ndarray:
    """K of a FogDrive camera of this size (square pixels, principal point at the centre)."""
    f = width / (2.0 * math.tan(math.radians(FOV) / 2.0))
    return np.array([[f, 0.0, width / 2.0], [0.0, f, height / 2.0], [0.0, 0.0, 1.0]])


def augment_hsv(image: np.ndarray, gains: Sequence[float], rng: np.random.Generator) -> np.ndarray:
    """Ultralytics-style colour jitter of a uint8 RGB image: hue, saturation and value multiplied by random gains
    in ``1 ± gains`` (hue wraps around), through lookup tables.

    >>> img = np.full((2, 2, 3), 128, np.uint8)  # grey has no hue or saturation to change
    >>> out = augment_hsv(img, (0.5, 0.5, 0.0), np.random.default_rng(0))
    >>> bool((out == img).all())
    True
    """
    r = rng.uniform(-1.0, 1.0, 3) * np.asarray(gains, np.float64) + 1.0
    hue, sat, val = cv2.split(cv2.cvtColor(image, cv2.COLOR_RGB2HSV))
    x = np.arange(256, dtype=np.float64)
    lut_h = ((x * r[0]) % 180).astype(np.uint8)
    lut_s = np.clip(x * r[1], 0, 255).astype(np.uint8)
    lut_v = np.clip(x * r[2], 0, 255).astype(np.uint8)
    hsv = cv2.merge((cv2.LUT(hue, lut_h), cv2.LUT(sat, lut_s), cv2.LUT(val, lut_v)))
    return cv2.cvtColor(hsv, cv2.COLOR_HSV2RGB)


class ImageSet(torch.utils.data.Dataset):
    """Frames at a fog level, resized to the input size, with CenterNet targets; horizontal flips and the ``hsv``
    colour jitter (:func:`augment_hsv`) when ``augment``."""

    def __init__(self, ds: FogDrive, items: Sequence[Frame], level: str, size: tuple[int, int], augment: bool = False,
                 seed: int = 0, hsv: Sequence[float] = (0.0, 0.0, 0.0)) -> None:  # fmt: skip
        self.ds, self.items, self.level, self.size, self.augment = ds, list(items), level, tuple(size), augment
        self.hsv = tuple(hsv)
        self.rng = np.random.default_rng(seed)

    def __len__(self) -> int:
        return len(self.items)

    def __getitem__(self, i: int):
        f = self.items[i]
        img = load_image(self.ds, f, self.level)
        boxes, classes = load_boxes(self.ds, f)
        h0, w0 = img.shape[:2]
        w, h = self.size
        img = resize(img, self.size)
        boxes = boxes * np.array([w / w0, h / h0, w / w0, h / h0])
        if self.augment and any(self.hsv):
            img = augment_hsv(img, self.hsv, self.rng)
        if self.augment and self.rng.random() < 0.5:
            img = np.ascontiguousarray(img[:, ::-1])
            boxes = np.stack([w - boxes[:, 2], boxes[:, 1], w - boxes[:, 0], boxes[:, 3]], 1)
        return img, make_targets(boxes, classes, (h // STRIDE, w // STRIDE))


def collate(batch):
    """Images ``(B, 3, H, W)`` in [0, 1], heatmaps, and the flat indices and regression targets of every centre."""
    imgs = torch.from_numpy(np.stack([b[0] for b in batch]).transpose(0, 3, 1, 2).copy()).float() / 255.0
    heat = torch.from_numpy(np.stack([b[1]["heatmap"] for b in batch]))
    bidx = torch.cat([torch.full((len(b[1]["index"]),), i, dtype=torch.long) for i, b in enumerate(batch)])
    cidx = torch.from_numpy(np.concatenate([b[1]["index"] for b in batch]).astype(np.int64))
    wh = torch.from_numpy(np.concatenate([b[1]["wh"] for b in batch]).reshape(-1, 2))
    off = torch.from_numpy(np.concatenate([b[1]["offset"] for b in batch]).reshape(-1, 2))
    return imgs, heat, bidx, cidx, wh, off


def eval_set(ds: FogDrive, items: list[Frame], level: str, size: tuple[int, int],
              transform: Callable[[np.ndarray, Frame], np.ndarray] | None = None, desc: str | None = None,
              progress: bool = False, min_height: float = 0.0) -> tuple[list, list, list]:  # fmt: skip
    """Input-size images (optionally transformed at full resolution first), ground truth (boxes lower than
    ``min_height`` input pixels marked ``ignore``) and scales."""
    from tqdm import tqdm

    images, gts, scales = [], [], []
    for f in tqdm(items, desc=desc, disable=not (progress and desc)):
        img = load_image(ds, f, level)
        if transform is not None:
            img = transform(img, f)
        h0, w0 = img.shape[:2]
        boxes, classes = load_boxes(ds, f)
        images.append(resize(img, size))
        gts.append({"boxes": boxes, "classes": classes, "ignore": (boxes[:, 3] - boxes[:, 1]) * size[1] / h0 < min_height})
        scales.append((w0 / size[0], h0 / size[1]))
    return images, gts, scales

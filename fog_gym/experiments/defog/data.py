"""Experiment 2's data: the scenes chosen per split, the camera frames of those scenes, images at a fog level with
their ground-truth boxes, and the evaluation sets (the detectors' training set is in :mod:`~.train`).

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

from fog_gym.dataset.access import FogDrive
from fog_gym.dataset.decode import load_channel

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


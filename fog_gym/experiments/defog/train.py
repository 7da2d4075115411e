"""Training in Experiment 2: the training set (horizontal flips and Ultralytics-style colour jitter), a CenterNet
detector on frames at one fog level (one architecture and one set of hyper-parameters for every pipeline; each keeps
its best-mAP@0.5 epoch on its own validation input, early stopping's selection), and AOD-Net on the train split's
(clean, fog) pairs."""

from __future__ import annotations

import copy
import math
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import torch

from fog_gym.dataset.access import FogDrive
from fog_gym.experiments.defog.data import LEVELS, Frame, load_boxes, load_image, resize
from fog_gym.experiments.defog.evaluate import detect
from fog_gym.experiments.defog.model import STRIDE, CenterNet2D, loss_fn, make_targets
from fog_gym.experiments.detection3d.model import optimizer_step


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


def train_detector(train: ImageSet, val_images: list[np.ndarray], val_gt: list[dict], val_scale: list,
                   config: Any, seed: int, device: torch.device, name: str, tb_dir: Path | None = None,
                   progress: bool = True) -> tuple[CenterNet2D, dict[str, Any]]:  # fmt: skip
    """Train on ``train`` (weights and shuffling from ``seed``); keep the epoch with the best validation mAP@0.5.
    Returns the model and a summary."""
    from tqdm import tqdm

    from fog_gym.metrics.detection2d import evaluate_coco

    torch.manual_seed(seed)
    model = CenterNet2D(width=config.width).to(device)
    loader = torch.utils.data.DataLoader(train, config.batch_size, shuffle=True, collate_fn=collate,
                                         generator=torch.Generator().manual_seed(seed))  # fmt: skip
    opt = torch.optim.AdamW(model.parameters(), lr=config.lr, weight_decay=config.weight_decay)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, config.lr, total_steps=config.epochs * len(loader))
    tb = None
    if tb_dir is not None:
        from torch.utils.tensorboard import SummaryWriter

        tb = SummaryWriter(str(tb_dir))
    best, best_state, history, step, t0 = -1.0, None, [], 0, time.perf_counter()
    bar = tqdm(total=config.epochs * len(loader), desc=f"train {name} ({len(train)} images)", unit="batch",
               disable=not progress)  # fmt: skip
    for epoch in range(config.epochs):
        model.train()
        for imgs, heat, bidx, cidx, wh, off in loader:
            o = model(imgs.to(device))
            loss, _ = loss_fn(o, heat.to(device), bidx.to(device), cidx.to(device), wh.to(device), off.to(device))
            value = optimizer_step(loss, opt, sched, bar)
            step += 1
            if tb is not None:
                tb.add_scalar("loss", value, step)
        if (epoch + 1) % config.eval_every and epoch + 1 != config.epochs:
            continue
        r = evaluate_coco(val_gt, detect(model, val_images, val_scale, device, config.threshold))
        score = r["mAP50"] if not math.isnan(r["mAP50"]) else -1.0
        history.append({"epoch": epoch + 1, "val_mAP50": score})
        if tb is not None:
            tb.add_scalar("val/mAP50", score, epoch + 1)
        if score > best:
            best, best_state = score, copy.deepcopy(model.state_dict())
    bar.close()
    if tb is not None:
        tb.close()
    model.load_state_dict(best_state)
    best_epoch = max(history, key=lambda h: h["val_mAP50"])["epoch"]
    return model, {"images": len(train), "seconds": time.perf_counter() - t0, "best_epoch": best_epoch,
                   "val_mAP50": best, "history": history}  # fmt: skip


def train_aodnet_pairs(ds: FogDrive, train_f: list[Frame], config: Any, seed: int, device: torch.device,
                       progress: bool = True) -> tuple[Any, dict[str, Any]]:  # fmt: skip
    """AOD-Net trained on ``config.aod_pairs`` random full-resolution crops (detector-input sized) of the train
    frames' (clean, fog) pairs over every level, each (frame, level) pair once at most; returns the model and a
    summary (pairs, losses, seconds)."""
    from tqdm import tqdm

    from fog_gym.perception.aodnet import train_aodnet

    size = tuple(config.input_size)
    rng = np.random.default_rng(seed)
    n_all = len(train_f) * len(LEVELS)
    clean, foggy = [], []
    for i in tqdm(rng.choice(n_all, min(config.aod_pairs, n_all), replace=False), desc="AOD-Net pairs",
                  disable=not progress):  # fmt: skip
        f, lv = train_f[i % len(train_f)], LEVELS[i // len(train_f)]
        c, g = load_image(ds, f, "clean"), load_image(ds, f, lv)
        ch, cw = min(c.shape[0], size[1]), min(c.shape[1], size[0])
        y, x = rng.integers(0, c.shape[0] - ch + 1), rng.integers(0, c.shape[1] - cw + 1)
        clean.append(c[y : y + ch, x : x + cw])
        foggy.append(g[y : y + ch, x : x + cw])
    t0 = time.perf_counter()
    aod, losses = train_aodnet(np.stack(clean), np.stack(foggy), epochs=config.aod_epochs, batch_size=config.batch_size,
                               seed=seed, device=str(device), progress=progress)  # fmt: skip
    return aod, {"pairs": len(clean), "losses": losses, "seconds": time.perf_counter() - t0}

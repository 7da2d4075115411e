"""Training in Experiment 2: Ultralytics-style colour jitter, the YOLO-style detector on frames at one fog level (one
architecture and one set of hyper-parameters for every pipeline; each keeps its best-mAP@0.5 epoch on its own
validation input, early stopping's selection), and the learned dehazers — AOD-Net and DehazeFormer — on the train
split's (clean, fog) pairs."""

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
from fog_gym.experiments.detection3d.model import optimizer_step
from fog_gym.experiments.runner import EpochCheckpoint


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


class DetectionSet:
    """A detector's training set (a ``torch`` ``Dataset``): the frames at one fog level, resized to the input size
    ``(W, H)``, with their boxes; with ``augment``, a horizontal flip (probability ½) and Ultralytics-style colour
    jitter (``hsv`` gains, :func:`augment_hsv`), drawn from (``seed``, epoch,
    item) so that an epoch is reproducible. Items: ``(image (H, W, 3) uint8, boxes (N, 4) input pixels, class
    channel indices (N,))``."""

    def __init__(self, ds: FogDrive, items: Sequence[Frame], level: str, size: tuple[int, int], augment: bool = False,
                 seed: int = 0, hsv: Sequence[float] = (0.0, 0.0, 0.0)) -> None:  # fmt: skip
        if not items:
            raise ValueError("the training split has no frames")
        self.ds, self.items, self.level, self.size = ds, list(items), level, tuple(size)
        self.augment, self.seed, self.hsv, self.epoch = augment, seed, tuple(hsv), 0

    def __len__(self) -> int:
        return len(self.items)

    def __getitem__(self, i: int):
        from fog_gym.experiments.defog.yolo import CLASSES

        f = self.items[i]
        img = load_image(self.ds, f, self.level)
        boxes, classes = load_boxes(self.ds, f)
        h0, w0 = img.shape[:2]
        w, h = self.size
        img = resize(img, self.size)
        boxes = boxes * np.array([w / w0, h / h0, w / w0, h / h0])
        if self.augment:
            rng = np.random.default_rng([self.seed, self.epoch, i])
            if any(self.hsv):
                img = augment_hsv(img, self.hsv, rng)
            if rng.random() < 0.5:
                img = np.ascontiguousarray(img[:, ::-1])
                boxes = np.stack([w - boxes[:, 2], boxes[:, 1], w - boxes[:, 0], boxes[:, 3]], 1)
        channel = np.array([CLASSES.index(int(c)) for c in classes], np.int64)
        return img, boxes.astype(np.float32), channel


def collate_detection(batch):
    """Images ``(B, 3, H, W)`` float in [0, 1] (channels-last memory), boxes padded to ``(B, G, 4)``, class channels
    ``(B, G)`` and the mask of real boxes."""
    g = max(1, max(len(b[1]) for b in batch))
    boxes = np.zeros((len(batch), g, 4), np.float32)
    classes = np.zeros((len(batch), g), np.int64)
    mask = np.zeros((len(batch), g), bool)
    for k, (_, b, c) in enumerate(batch):
        boxes[k, : len(b)], classes[k, : len(c)], mask[k, : len(c)] = b, c, True
    imgs = torch.from_numpy(np.stack([b[0] for b in batch])).permute(0, 3, 1, 2).float().div_(255.0)
    return imgs.contiguous(memory_format=torch.channels_last), torch.from_numpy(boxes), torch.from_numpy(classes), torch.from_numpy(mask)


class EMA:
    """An exponential moving average of a model's weights (and buffers), as YOLO trains with: decay ramped as
    ``decay · (1 − exp(−updates / 2000))`` so that early weights are forgotten fast."""

    def __init__(self, model: torch.nn.Module, decay: float = 0.9999, tau: float = 2000.0) -> None:
        self.model = copy.deepcopy(model).eval()
        for p in self.model.parameters():
            p.requires_grad_(False)
        self.decay, self.tau, self.updates = decay, tau, 0

    @torch.no_grad()
    def update(self, model: torch.nn.Module) -> None:
        self.updates += 1
        d = self.decay * (1 - math.exp(-self.updates / self.tau))
        msd = model.state_dict()
        for k, v in self.model.state_dict().items():
            if v.dtype.is_floating_point:
                v.mul_(d).add_(msd[k].detach(), alpha=1 - d)
            else:
                v.copy_(msd[k])


def train_detector(train: Any, val_images: list[np.ndarray], val_gt: list[dict], val_scale: list, config: Any,
                   seed: int, device: torch.device, name: str, tb_dir: Path | None = None,
                   progress: bool = True, checkpoint: Path | None = None) -> tuple[torch.nn.Module, dict[str, Any]]:  # fmt: skip
    """Train the YOLO-style detector on ``train`` (a :class:`~fog_gym.experiments.defog.data.DetectionSet`;
    weights, shuffling and augmentation from ``seed``) with AdamW and a one-cycle learning rate, keeping an EMA of
    the weights; evaluate the EMA on the validation set every ``eval_every`` epochs and keep the epoch with the
    best validation mAP@0.5 (early stopping's selection). Returns the model and a summary with the validation
    history (the learning curve). With ``checkpoint`` the state after every epoch is kept there and a later call
    continues from it (:class:`~fog_gym.experiments.runner.EpochCheckpoint`)."""
    from tqdm import tqdm

    from fog_gym.experiments.defog.yolo import YoloDetector
    from fog_gym.experiments.defog.yolo_loss import detection_loss
    from fog_gym.experiments.detection3d.train import autocast, resolve_precision
    from fog_gym.metrics.detection2d import evaluate_coco

    precision = resolve_precision(config.precision, device)
    torch.manual_seed(seed)
    model = YoloDetector(config.yolo).to(device).to(memory_format=torch.channels_last)
    ema = EMA(model)
    order = torch.Generator().manual_seed(seed)
    loader = torch.utils.data.DataLoader(train, config.batch_size, shuffle=True, collate_fn=collate_detection,
                                         drop_last=len(train) > config.batch_size, num_workers=config.workers,
                                         generator=order)  # fmt: skip
    opt = torch.optim.AdamW(model.parameters(), lr=config.lr, weight_decay=config.weight_decay)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, config.lr, total_steps=config.epochs * len(loader), pct_start=0.15)
    tb = None
    if tb_dir is not None:
        from torch.utils.tensorboard import SummaryWriter

        tb = SummaryWriter(str(tb_dir))
    best, best_state, history, step, t0, start, before = -1.0, None, [], 0, time.perf_counter(), 0, 0.0
    keep = EpochCheckpoint(checkpoint, {"config": config.settings(), "seed": seed, "images": len(train),
                                        "batches": len(loader)})  # fmt: skip
    if (state := keep.resume(model, opt, sched, order)) is not None:
        ema.model.load_state_dict(state["ema"])
        ema.updates = state["ema_updates"]
        best, best_state, history = state["best"], state["best_state"], state["history"]
        step, start, before = state["step"], state["epoch"], state["seconds"]
    bar = tqdm(total=config.epochs * len(loader), initial=step, desc=f"train {name} ({len(train)} images)",
               unit="batch", disable=not progress)  # fmt: skip
    for epoch in range(start, config.epochs):
        model.train()
        train.epoch = epoch
        for imgs, boxes, classes, mask in loader:
            with autocast(device, precision):
                out = model(imgs.to(device))
            loss, parts = detection_loss(out, boxes.to(device), classes.to(device), mask.to(device), config.yolo.reg_max)
            value = optimizer_step(loss, opt, sched, bar)
            ema.update(model)
            step += 1
            if not math.isfinite(value):
                raise FloatingPointError(f"{name}: the loss became {value} at step {step}")
            if tb is not None and step % 10 == 0:
                tb.add_scalar("loss/total", value, step)
                for k, v in parts.items():
                    tb.add_scalar(f"loss/{k}", v, step)
        if (epoch + 1) % config.eval_every == 0 or epoch + 1 == config.epochs:
            with autocast(device, precision):
                r = evaluate_coco(val_gt, detect(ema.model, val_images, val_scale, device, config.threshold))
            score = r["mAP50"] if not math.isnan(r["mAP50"]) else -1.0
            history.append({"epoch": epoch + 1, "images_seen": (epoch + 1) * len(loader) * config.batch_size,
                            "val_mAP50": score, "val_mAP50_95": r["mAP50_95"]})  # fmt: skip
            if tb is not None:
                tb.add_scalar("val/mAP50", score, epoch + 1)
            if score > best:
                best, best_state = score, copy.deepcopy(ema.model.state_dict())
        keep.save_epoch(model, opt, sched, order, ema=ema.model.state_dict(), ema_updates=ema.updates, best=best,
                        best_state=best_state, history=history, step=step, epoch=epoch + 1,
                        seconds=before + time.perf_counter() - t0)  # fmt: skip
    bar.close()
    if tb is not None:
        tb.close()
    model.load_state_dict(best_state)
    best_epoch = max(history, key=lambda h: h["val_mAP50"])["epoch"]
    summary = {"images": len(train), "seconds": before + time.perf_counter() - t0, "best_epoch": best_epoch,
               "val_mAP50": best, "history": history, "precision": precision, "steps": step}  # fmt: skip
    if start:
        summary["resumed_at_epoch"] = start
    return model.eval(), summary


def training_pairs(ds: FogDrive, train_f: list[Frame], n: int, crop: tuple[int, int], seed: int,
                   progress: bool = True) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """``n`` random (clean, fogged) crops of ``crop`` (W, H) pixels from the train frames' pairs over every fog
    level, each (frame, level) pair at most once: uint8 arrays ``(n, H, W, 3)``."""
    from tqdm import tqdm

    rng = np.random.default_rng([seed, 0xDE4A])
    n_all = len(train_f) * len(LEVELS)
    clean, foggy = [], []
    for i in tqdm(rng.choice(n_all, min(n, n_all), replace=False), desc="dehazer pairs", disable=not progress):
        f, lv = train_f[i % len(train_f)], LEVELS[i // len(train_f)]
        c, g = load_image(ds, f, "clean"), load_image(ds, f, lv)
        ch, cw = min(c.shape[0], crop[1]), min(c.shape[1], crop[0])
        y, x = rng.integers(0, c.shape[0] - ch + 1), rng.integers(0, c.shape[1] - cw + 1)
        clean.append(c[y : y + ch, x : x + cw])
        foggy.append(g[y : y + ch, x : x + cw])
    return np.stack(clean), np.stack(foggy)


def train_aodnet_pairs(ds: FogDrive, train_f: list[Frame], config: Any, seed: int, device: torch.device,
                       progress: bool = True) -> tuple[Any, dict[str, Any]]:  # fmt: skip
    """AOD-Net trained on ``config.aod_pairs`` random 256 × 256 crops of the train frames' (clean, fog) pairs;
    returns the model and a summary (pairs, losses, seconds)."""
    from fog_gym.dehaze.aodnet import train_aodnet

    clean, foggy = training_pairs(ds, train_f, config.aod_pairs, (256, 256), seed, progress)
    t0 = time.perf_counter()
    aod, losses = train_aodnet(clean, foggy, epochs=config.aod_epochs, batch_size=16, seed=seed, device=str(device),
                               progress=progress)  # fmt: skip
    return aod, {"pairs": len(clean), "losses": losses, "seconds": time.perf_counter() - t0}


def train_dehazeformer_pairs(ds: FogDrive, train_f: list[Frame], config: Any, seed: int, device: torch.device,
                             progress: bool = True) -> tuple[Any, dict[str, Any]]:  # fmt: skip
    """DehazeFormer (``config.dehazeformer`` size) trained for ``config.dehazeformer_steps`` steps of random
    ``config.dehazeformer_crop`` crops cut from ``config.aod_pairs`` (clean, fog) pairs (the same pairs AOD-Net
    sees); returns the model and a summary."""
    from fog_gym.dehaze.dehazeformer import train_dehazeformer
    from fog_gym.experiments.detection3d.train import resolve_precision

    clean, foggy = training_pairs(ds, train_f, config.aod_pairs, (256, 256), seed, progress)
    t0 = time.perf_counter()
    precision = resolve_precision(config.precision, device)
    crop = min(config.dehazeformer_crop, *clean.shape[1:3])  # small frames (a smoke run) give small pairs
    model, losses = train_dehazeformer(clean, foggy, config.dehazeformer, config.dehazeformer_steps, 8, crop, 4e-4,
                                       seed, str(device), precision, progress)  # fmt: skip
    return model, {"pairs": len(clean), "losses": losses, "seconds": time.perf_counter() - t0, "precision": precision}

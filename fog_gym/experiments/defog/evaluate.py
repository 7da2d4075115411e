"""Evaluation in Experiment 2: detections of a trained detector, their COCO scores, image quality against the paired
clean frames, and every pipeline of one seed on the test frames:

* **A** clean → clean: the clean-trained detector on clean frames (the upper bound);
* **B** clean → fog: the same detector on fogged frames (the degradation baseline);
* **C** clean → dehazer → detector: the same detector on dehazed fogged frames, for each dehazer
  (:mod:`~fog_gym.experiments.defog.dehazers`);
* **D** fog → fog: the detector trained on each fog level, tested on that level.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import torch

from fog_gym.dataset.access import FogDrive
from fog_gym.experiments.defog.data import LEVELS, Frame, eval_set
from fog_gym.experiments.defog.model import decode

#: The COCO scores of every cell (besides the counts and AP@0.5 per class, ``AP50/<class>``).
METRICS = ("mAP50", "mAP50_95", "precision", "recall")


@torch.no_grad()
def detect(model: torch.nn.Module, images: Sequence[np.ndarray], scale: Sequence[tuple[float, float]],
           device: torch.device, threshold: float, batch_size: int = 32) -> list[dict[str, np.ndarray]]:  # fmt: skip
    """Detections per input-size image; boxes multiplied by each image's ``scale`` (back to original pixels)."""
    model.eval()
    out: list[dict[str, np.ndarray]] = []
    for i in range(0, len(images), batch_size):
        chunk = np.stack(images[i : i + batch_size])
        x = torch.from_numpy(chunk.transpose(0, 3, 1, 2).copy()).float().div(255.0).to(device)
        o = model(x)
        for k, d in enumerate(decode(o, threshold)):
            sx, sy = scale[i + k]
            d["boxes"] = d["boxes"] * np.array([sx, sy, sx, sy])
            out.append(d)
    return out


def score(model: torch.nn.Module, images: list, gts: list, scales: list, device: torch.device,
          threshold: float) -> dict[str, float]:  # fmt: skip
    """COCO scores of ``model`` on an evaluation set: :data:`METRICS`, ``n_gt``, ``n_pred`` and ``AP50/<class>``."""
    from fog_gym.metrics.detection2d import evaluate_coco

    r = evaluate_coco(gts, detect(model, images, scales, device, threshold))
    return {k: r[k] for k in (*METRICS, "n_gt", "n_pred")} | {f"AP50/{c}": v for c, v in r["AP50"].items()}


def quality(images: list[np.ndarray], reference: list[np.ndarray]) -> dict[str, float]:
    """Mean PSNR (finite values; identical pairs are left out) and SSIM against the paired clean frames."""
    from fog_gym.metrics.image_quality import psnr, ssim

    p = [psnr(a, b) for a, b in zip(images, reference, strict=True)]
    finite = [v for v in p if math.isfinite(v)]
    return {"PSNR": float(np.mean(finite)) if finite else float("inf"),
            "SSIM": float(np.mean([ssim(a, b) for a, b in zip(images, reference, strict=True)]))}  # fmt: skip


def evaluate_pipelines(ds: FogDrive, test_f: list[Frame], clean_model: torch.nn.Module,
                       fog_models: dict[str, torch.nn.Module],
                       dehazers: dict[str, Callable[[np.ndarray, Frame, str], np.ndarray]], config: Any,
                       device: torch.device, progress: bool = True) -> dict[str, Any]:  # fmt: skip
    """Pipelines A–D on the test frames: ``{"detection": {pipeline: {level: scores}}, "image_quality": {level:
    {"foggy" or dehazer: {PSNR, SSIM, [seconds_per_image]}}}}``."""
    size, h, thr = tuple(config.input_size), config.min_height, config.threshold
    clean_set = eval_set(ds, test_f, "clean", size, min_height=h)
    det: dict[str, dict[str, Any]] = {"A": {"clean": score(clean_model, *clean_set, device, thr)}, "B": {},
                                      **{f"C-{d}": {} for d in dehazers}, "D": {}}  # fmt: skip
    iq: dict[str, Any] = {}
    for lv in LEVELS:
        fog_set = eval_set(ds, test_f, lv, size, min_height=h)
        det["B"][lv] = score(clean_model, *fog_set, device, thr)
        iq[lv] = {"foggy": quality(fog_set[0], clean_set[0])}
        for name, fn in dehazers.items():
            t0 = time.perf_counter()
            deh = eval_set(ds, test_f, lv, size, transform=lambda img, f, fn=fn, lv=lv: fn(img, f, lv),
                           desc=f"{name} on {lv}", progress=progress, min_height=h)  # fmt: skip
            iq[lv][name] = quality(deh[0], clean_set[0]) | {"seconds_per_image": (time.perf_counter() - t0) / max(1, len(test_f))}
            det[f"C-{name}"][lv] = score(clean_model, *deh, device, thr)
        det["D"][lv] = score(fog_models[lv], *fog_set, device, thr)
    return {"detection": det, "image_quality": iq}

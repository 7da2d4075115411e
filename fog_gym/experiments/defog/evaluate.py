"""Evaluation in Experiment 2: detections of a trained detector, their COCO scores, image quality against the paired
clean frames, and every pipeline of one seed on the test frames:

* **A** clean → clean: the clean-trained detector on clean frames (the upper bound);
* **B** clean → fog: the same detector on fogged frames (the degradation baseline);
* **C** clean → dehazer → detector: the same detector on dehazed fogged frames, for each dehazer
  (:mod:`~fog_gym.experiments.defog.dehazers`);
* **D** fog → fog: the detector trained on each fog level, tested on that level.

Every pipeline sees the same test images; :func:`evaluate_pipelines` keeps each image's detections (and its PSNR
and SSIM for every dehazed or fogged version), so the report can compare pipelines on the same images
(paired bootstrap) and not only through their means.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch

from fog_gym.dataset.access import FogDrive
from fog_gym.experiments.defog.data import LEVELS, Frame, eval_set

#: The COCO scores of every cell (besides the counts and AP@0.5 per class, ``AP50/<class>``).
METRICS = ("mAP50", "mAP50_95", "precision", "recall")


@torch.no_grad()
def detect(model: torch.nn.Module, images: Sequence[np.ndarray], scale: Sequence[tuple[float, float]],
           device: torch.device, threshold: float, batch_size: int = 16) -> list[dict[str, np.ndarray]]:  # fmt: skip
    """Detections per input-size image (the paper's validation settings: confidence ``threshold``, NMS IoU 0.6);
    boxes multiplied by each image's ``scale`` (back to the frame's pixels)."""
    from fog_gym.experiments.defog.yolo import decode

    model.eval()
    out: list[dict[str, np.ndarray]] = []
    for i in range(0, len(images), batch_size):
        chunk = np.stack(images[i : i + batch_size])
        x = torch.from_numpy(chunk).permute(0, 3, 1, 2).float().div_(255.0).contiguous(memory_format=torch.channels_last)
        for k, d in enumerate(decode(model(x.to(device)), model.config.reg_max, conf=threshold)):
            sx, sy = scale[i + k]
            d["boxes"] = d["boxes"] * np.array([sx, sy, sx, sy])
            out.append(d)
    return out


def scores_of(gts: list, preds: list) -> dict[str, float]:
    """COCO scores of detections: :data:`METRICS`, ``n_gt``, ``n_pred`` and ``AP50/<class>``."""
    from fog_gym.metrics.detection2d import evaluate_coco

    r = evaluate_coco(gts, preds)
    return {k: r[k] for k in (*METRICS, "n_gt", "n_pred")} | {f"AP50/{c}": v for c, v in r["AP50"].items()}


def per_image_quality(images: list[np.ndarray], reference: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """PSNR (inf for identical pairs) and SSIM of every image against its clean pair."""
    from fog_gym.metrics.image_quality import psnr, ssim

    return (np.array([psnr(a, b) for a, b in zip(images, reference, strict=True)]),
            np.array([ssim(a, b) for a, b in zip(images, reference, strict=True)]))  # fmt: skip


def mean_quality(p: np.ndarray, s: np.ndarray) -> dict[str, float]:
    """Mean PSNR (finite values; identical pairs are left out) and SSIM."""
    finite = p[np.isfinite(p)]
    return {"PSNR": float(finite.mean()) if len(finite) else float("inf"), "SSIM": float(np.mean(s))}


def evaluate_pipelines(ds: FogDrive, test_f: list[Frame], clean_model: torch.nn.Module,
                       fog_models: dict[str, torch.nn.Module],
                       dehazers: dict[str, Callable[[np.ndarray, Frame, str], np.ndarray]], config: Any,
                       device: torch.device, progress: bool = True,
                       keep: Path | None = None) -> dict[str, Any]:  # fmt: skip
    """Pipelines A–D on the test frames: ``{"detection": {pipeline: {level: scores}}, "image_quality": {level:
    {"foggy" or dehazer: {PSNR, SSIM, seconds_per_image}}}}``. With ``keep``, every image's detections per
    pipeline and level, the ground truth, scenes and per-image PSNR / SSIM go to that ``.npz``
    (:func:`save_records`)."""
    from fog_gym.experiments.detection3d.train import autocast, resolve_precision

    precision = resolve_precision(config.precision, device)
    size, h, thr = tuple(config.input_size), config.min_height, config.threshold

    def run(model: torch.nn.Module, images: list, scales: list) -> list:
        with autocast(device, precision):
            return detect(model, images, scales, device, thr)

    clean_set = eval_set(ds, test_f, "clean", size, min_height=h)
    gts = clean_set[1]
    preds: dict[str, dict[str, list]] = {"A": {"clean": run(clean_model, clean_set[0], clean_set[2])}, "B": {},
                                         **{f"C-{d}": {} for d in dehazers}, "D": {}}  # fmt: skip
    quality: dict[str, dict[str, tuple[np.ndarray, np.ndarray]]] = {}
    seconds: dict[str, dict[str, float]] = {}
    for lv in LEVELS:
        fog_set = eval_set(ds, test_f, lv, size, min_height=h)
        preds["B"][lv] = run(clean_model, fog_set[0], fog_set[2])
        quality[lv] = {"foggy": per_image_quality(fog_set[0], clean_set[0])}
        seconds[lv] = {}
        for name, fn in dehazers.items():
            t0 = time.perf_counter()
            deh = eval_set(ds, test_f, lv, size, transform=lambda img, f, fn=fn, lv=lv: fn(img, f, lv),
                           desc=f"{name} on {lv}", progress=progress, min_height=h)  # fmt: skip
            seconds[lv][name] = (time.perf_counter() - t0) / max(1, len(test_f))
            quality[lv][name] = per_image_quality(deh[0], clean_set[0])
            preds[f"C-{name}"][lv] = run(clean_model, deh[0], deh[2])
        preds["D"][lv] = run(fog_models[lv], fog_set[0], fog_set[2])
    if keep is not None:
        save_records(keep, gts, preds, quality, [f.scene for f in test_f])
    det = {p: {lv: scores_of(gts, v) for lv, v in levels.items()} for p, levels in preds.items()}
    iq = {lv: {m: mean_quality(*pq) | ({"seconds_per_image": seconds[lv][m]} if m in seconds[lv] else {})
               for m, pq in methods.items()} for lv, methods in quality.items()}  # fmt: skip
    return {"detection": det, "image_quality": iq, "precision": precision}


def save_records(path: Path, gts: list, preds: dict[str, dict[str, list]], quality: dict, scenes: list[str]) -> None:
    """Per-image records of one seed's evaluation as one ``.npz`` (flat arrays with image offsets)."""
    arrays: dict[str, np.ndarray] = {"scenes": np.asarray(scenes)}

    def flat(prefix: str, frames: list, with_scores: bool) -> None:
        arrays[f"{prefix}/boxes"] = np.concatenate([np.asarray(f["boxes"], np.float64).reshape(-1, 4) for f in frames])
        arrays[f"{prefix}/classes"] = np.concatenate([np.asarray(f["classes"]).reshape(-1) for f in frames]).astype(np.int64)
        arrays[f"{prefix}/offsets"] = np.cumsum([0] + [len(f["classes"]) for f in frames])
        if with_scores:
            arrays[f"{prefix}/scores"] = np.concatenate([np.asarray(f["scores"]).reshape(-1) for f in frames])
        else:
            arrays[f"{prefix}/ignore"] = np.concatenate([np.asarray(f["ignore"]).reshape(-1) for f in frames]).astype(bool)

    flat("gt", gts, False)
    for p, levels in preds.items():
        for lv, frames in levels.items():
            flat(f"pred/{p}/{lv}", frames, True)
    for lv, methods in quality.items():
        for m, (ps, ss) in methods.items():
            arrays[f"iq/{lv}/{m}/PSNR"], arrays[f"iq/{lv}/{m}/SSIM"] = ps, ss
    from fog_gym.experiments.runner import atomic_path

    with atomic_path(Path(path)) as tmp:
        np.savez_compressed(tmp, **arrays)


def load_records(path: Path) -> dict[str, Any]:
    """The inverse of :func:`save_records`: ``{"scenes", "gt": [frames], "pred": {pipeline: {level: [frames]}},
    "iq": {level: {method: {"PSNR", "SSIM"}}}}``."""
    out: dict[str, Any] = {"pred": {}, "iq": {}}
    with np.load(path) as z:
        out["scenes"] = z["scenes"].tolist()

        def frames(prefix: str, with_scores: bool) -> list:
            o, b, c = z[f"{prefix}/offsets"], z[f"{prefix}/boxes"], z[f"{prefix}/classes"]
            extra = z[f"{prefix}/scores"] if with_scores else z[f"{prefix}/ignore"]
            key = "scores" if with_scores else "ignore"
            return [{"boxes": b[o[i]:o[i + 1]], "classes": c[o[i]:o[i + 1]], key: extra[o[i]:o[i + 1]]} for i in range(len(o) - 1)]

        out["gt"] = frames("gt", False)
        for name in z.files:
            parts = name.split("/")
            if parts[0] == "pred" and parts[-1] == "offsets":
                out["pred"].setdefault(parts[1], {})[parts[2]] = frames("/".join(parts[:3]), True)
            elif parts[0] == "iq":
                out["iq"].setdefault(parts[1], {}).setdefault(parts[2], {})[parts[3]] = z[name]
    return out


def finite_mean(x: np.ndarray) -> float:
    x = np.asarray(x, np.float64)
    x = x[np.isfinite(x)]
    return float(x.mean()) if len(x) else math.nan

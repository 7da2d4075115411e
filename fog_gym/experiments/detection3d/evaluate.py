"""Evaluate Experiment 1's detectors on the test subsets: predictions over a loader, and the nuScenes-style metrics
of :mod:`fog_gym.metrics.detection3d` per test fog level, with per-class AP and AP per distance band."""

from __future__ import annotations

import math
from typing import Any

import torch

from fog_gym.experiments.detection3d.bev import BEVGrid
from fog_gym.experiments.detection3d.data import to_device
from fog_gym.experiments.detection3d.model import decode
from fog_gym.metrics.detection3d import DISTANCE_BANDS, evaluate, evaluate_bands

#: Metrics kept per (train, test) cell: mAP@0.5, Mean TP, the TP scores, FDS = 0.5 mAP + 0.5 Mean TP, ATE in metres.
METRICS = ("mAP", "mean_TP", "ATE", "ASE", "AOE", "FDS", "ATE_m")


def predict(model: torch.nn.Module, loader, device: torch.device, grid: BEVGrid, threshold: float):
    """Ground truth and predictions (lists of per-frame dicts) over a loader."""
    model.eval()
    gts, preds = [], []
    with torch.no_grad():
        for batch in loader:
            out = model(**to_device(batch["inputs"], device))
            preds += decode(out, grid, threshold)
            gts += batch["gt"]
    return gts, preds


def evaluate_levels(model: torch.nn.Module, loaders: dict[str, Any], device: torch.device, grid: BEVGrid,
                    threshold: float) -> dict[str, tuple[dict[str, Any], list]]:  # fmt: skip
    """Per test level: every metric (with the match counts, per-class AP and ``bands``: mAP per distance band of
    :data:`~fog_gym.metrics.detection3d.DISTANCE_BANDS`) and the predictions."""
    out = {}
    for lv, loader in loaders.items():
        gts, preds = predict(model, loader, device, grid, threshold)
        r = evaluate(gts, preds)
        r["bands"] = {name: b["mAP"] for name, b in evaluate_bands(gts, preds, DISTANCE_BANDS).items()}
        out[lv] = (r, preds)
    return out


def fds(r: dict[str, Any]) -> float:
    """The FDS a checkpoint is selected by; -1 where it is undefined (no ground truth)."""
    return r["FDS"] if not math.isnan(r["FDS"]) else -1.0

"""Evaluate the BEV detector of Experiment 1 on the test subsets: predictions over a loader, and the nuScenes-style
metrics of :mod:`fog_gym.metrics.detection3d` per test fog level."""

from __future__ import annotations

import math
from typing import Any

import torch

from fog_gym.experiments.detection3d.bev import BEVGrid
from fog_gym.experiments.detection3d.model import decode
from fog_gym.metrics.detection3d import evaluate

#: Metrics kept per (train, test) cell: mAP@0.5, Mean TP, the TP scores, FDS = 0.5 mAP + 0.5 Mean TP, ATE in metres.
METRICS = ("mAP", "mean_TP", "ATE", "ASE", "AOE", "FDS", "ATE_m")


def predict(model: torch.nn.Module, loader, device: torch.device, grid: BEVGrid, threshold: float):
    """Ground truth and predictions (lists of per-frame dicts) over a loader."""
    model.eval()
    gts, preds = [], []
    with torch.no_grad():
        for feats, *_, gt in loader:
            out = model(feats.to(device))
            preds += decode(out, grid, threshold)
            gts += gt
    return gts, preds


def evaluate_levels(model: torch.nn.Module, loaders: dict[str, Any], device: torch.device, grid: BEVGrid,
                    threshold: float) -> dict[str, dict[str, Any]]:  # fmt: skip
    """Every metric (and the match counts) on every test level's loader."""
    return {lv: evaluate(*predict(model, loader, device, grid, threshold)) for lv, loader in loaders.items()}


def fds(r: dict[str, Any]) -> float:
    """The FDS a checkpoint is selected by; -1 where it is undefined (no ground truth)."""
    return r["FDS"] if not math.isnan(r["FDS"]) else -1.0

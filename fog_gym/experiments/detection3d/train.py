"""Train one unit of Experiment 1 (a detector, a training subset, one seed) from scratch with AdamW and a one-cycle
learning rate, evaluated on every test subset after every ``eval_every`` epochs; each (train, test) cell keeps the
epoch of best FDS, as the paper does, with that epoch's per-class AP, AP per distance band and its predictions
(for the paired comparisons of the report). The evaluations also give the learning curve (mAP against the
training sweeps seen).

Precision: ``bf16`` runs the forward pass under ``torch.autocast`` with bfloat16 (weights, optimiser and losses
stay float32); on a CPU with AVX-512 BF16 it trains 3–4× faster than float32. ``auto`` takes it where the
hardware has it (CUDA with bf16, or a CPU flagging ``avx512_bf16`` or ``amx_bf16``), else float32.
"""

from __future__ import annotations

import contextlib
import math
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch

from fog_gym.experiments.detection3d.data import SweepDataset, collate, to_device
from fog_gym.experiments.detection3d.evaluate import METRICS, evaluate_levels, fds
from fog_gym.experiments.detection3d.model import BEVCenterNet, detection_loss, optimizer_step
from fog_gym.experiments.runner import EpochCheckpoint

#: The L1 regression weight of each detector's loss: CenterPoint's 0.25 for the pillar detector, 2 for the BEV one.
REG_WEIGHT = {"pillars": 0.25, "bev": 2.0}


def cpu_has_bf16() -> bool:
    """Whether this CPU computes bfloat16 natively (AVX-512 BF16 or AMX)."""
    try:
        flags = Path("/proc/cpuinfo").read_text()
    except OSError:
        return False
    return " avx512_bf16" in flags or " amx_bf16" in flags


def resolve_precision(name: str, device: torch.device) -> str:
    """``auto`` → ``bf16`` where the device computes it natively, else ``fp32``; other names pass through."""
    if name not in ("auto", "bf16", "fp32"):
        raise ValueError(f"precision must be auto, bf16 or fp32, got {name!r}")
    if name != "auto":
        return name
    if device.type == "cuda":
        return "bf16" if torch.cuda.is_bf16_supported() else "fp32"
    return "bf16" if cpu_has_bf16() else "fp32"


def autocast(device: torch.device, precision: str):
    """The forward pass's autocast context for ``precision`` (a no-op for fp32)."""
    if precision == "bf16":
        return torch.autocast(device.type, dtype=torch.bfloat16)
    return contextlib.nullcontext()


def build_model(detector: str, config: Any) -> torch.nn.Module:
    """A fresh network of ``detector`` as ``config`` (the study's) sizes it, in channels-last memory layout."""
    if detector == "pillars":
        from fog_gym.experiments.detection3d.pillar_model import PillarCenterPoint

        model = PillarCenterPoint(config.pillar_config)
    elif detector == "bev":
        model = BEVCenterNet(width=config.width)
    else:
        raise ValueError(f"detector must be pillars or bev, got {detector!r}")
    return model.to(memory_format=torch.channels_last)


def train_row(data: SweepDataset, test_sets: dict[str, SweepDataset], config: Any, detector: str, seed: int,
              device: torch.device, tb_dir: Path, progress: bool = True,
              checkpoint: Path | None = None) -> tuple[torch.nn.Module, dict[str, Any], dict[str, list]]:  # fmt: skip
    """Train ``detector`` on ``data`` (a training :class:`~.data.SweepDataset`) with ``seed`` (weights, shuffling,
    augmentation: ``data.seed`` should be ``seed``); returns the last model, the unit's record (sweeps, seconds,
    the best-FDS epoch's metrics per test level, the learning curve) and the best epoch's predictions per level.
    With ``checkpoint`` the state after every epoch is kept there and a later call continues from it
    (:class:`~fog_gym.experiments.runner.EpochCheckpoint`): the same weights as a run that was never stopped."""
    from torch.utils.tensorboard import SummaryWriter
    from tqdm import tqdm

    precision = resolve_precision(config.precision, device)
    grid = config.grid(detector)
    torch.manual_seed(seed)  # each unit from its seed: a unit never depends on which units ran before
    order = torch.Generator().manual_seed(seed)
    loader = torch.utils.data.DataLoader(data, config.batch_size, shuffle=True, collate_fn=collate,
                                         drop_last=len(data) > config.batch_size, num_workers=config.workers,
                                         generator=order)  # fmt: skip
    loaders = {lv: torch.utils.data.DataLoader(d, config.batch_size, collate_fn=collate, num_workers=config.workers)
               for lv, d in test_sets.items()}  # fmt: skip
    model = build_model(detector, config).to(device)
    opt = torch.optim.AdamW(model.parameters(), lr=config.lr, weight_decay=config.weight_decay)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, config.lr, total_steps=config.epochs * len(loader))
    tb = SummaryWriter(str(tb_dir))
    best: dict[str, dict[str, Any]] = {}
    best_preds: dict[str, list] = {}
    curve: list[dict[str, Any]] = []
    t0, step, start, before = time.perf_counter(), 0, 0, 0.0
    keep = EpochCheckpoint(checkpoint, {"config": config.settings(), "detector": detector, "seed": seed,
                                        "sweeps": len(data), "batches": len(loader)})  # fmt: skip
    if (state := keep.resume(model, opt, sched, order)) is not None:
        best, best_preds, curve = state["best"], state["best_preds"], state["curve"]
        step, start, before = state["step"], state["epoch"], state["seconds"]
    bar = tqdm(total=config.epochs * len(loader), initial=step, desc=f"train {tb_dir.name} ({len(data)} sweeps)",
               unit="batch", disable=not progress)  # fmt: skip
    for epoch in range(start, config.epochs):
        model.train()
        data.epoch = epoch
        for batch in loader:
            with autocast(device, precision):
                out = model(**to_device(batch["inputs"], device))
            loss, parts = detection_loss(out, batch["heatmap"].to(device), batch["batch_index"].to(device),
                                         batch["cell_index"].to(device), batch["regression"].to(device),
                                         REG_WEIGHT[detector])  # fmt: skip
            value = optimizer_step(loss, opt, sched, bar)
            step += 1
            if not math.isfinite(value):
                raise FloatingPointError(f"{tb_dir.name}: the loss became {value} at step {step}")
            if step % 10 == 0:
                tb.add_scalar("loss/total", value, step)
                for k, v in parts.items():
                    tb.add_scalar(f"loss/{k}", v, step)
        if (epoch + 1) % config.eval_every == 0 or epoch + 1 == config.epochs:
            _evaluate_epoch(model, loaders, device, grid, config, precision, epoch, len(loader), tb, best, best_preds,
                            curve)  # fmt: skip
        keep.save_epoch(model, opt, sched, order, best=best, best_preds=best_preds, curve=curve, step=step,
                        epoch=epoch + 1, seconds=before + time.perf_counter() - t0)  # fmt: skip
    bar.close()
    tb.close()
    record = {"detector": detector, "train_sweeps": len(data), "seconds": before + time.perf_counter() - t0,
              "precision": precision, "steps": step, "best": best, "curve": curve}  # fmt: skip
    if start:
        record["resumed_at_epoch"] = start
    return model, record, best_preds


def _evaluate_epoch(model: torch.nn.Module, loaders: dict, device: torch.device, grid: Any, config: Any,
                    precision: str, epoch: int, batches: int, tb: Any, best: dict, best_preds: dict,
                    curve: list) -> None:  # fmt: skip
    """Evaluate after ``epoch`` on every test level; update the best-FDS epoch's metrics and predictions per level
    and the learning curve in place."""
    with autocast(device, precision):
        results = evaluate_levels(model, loaders, device, grid, config.threshold)
    point = {"epoch": epoch + 1, "sweeps_seen": (epoch + 1) * batches * config.batch_size}
    for lv, (r, preds) in results.items():
        point[lv] = {k: float(r[k]) for k in METRICS}
        for k in METRICS:
            if not math.isnan(r[k]):
                tb.add_scalar(f"{lv}/{k}", r[k], epoch + 1)
        if lv not in best or fds(r) > best[lv]["FDS"]:
            best[lv] = {k: float(r[k]) for k in METRICS} | {
                "epoch": epoch + 1, "n_gt": r["n_gt"], "n_tp": r["n_tp"], "n_pred": r["n_pred"],
                "AP": {str(c): float(v) for c, v in r["AP"].items()}, "bands": r["bands"]}  # fmt: skip
            best_preds[lv] = preds
    curve.append(point)


def save_predictions(path: Path, preds: dict[str, list], gts: dict[str, list], scenes: dict[str, list]) -> None:
    """Per test level, every frame's predictions and ground truth (flat arrays with frame offsets) and scene."""
    arrays: dict[str, np.ndarray] = {}
    for lv in preds:
        for name, frames in (("pred", preds[lv]), ("gt", gts[lv])):
            arrays[f"{lv}/{name}_boxes"] = np.concatenate([np.asarray(f["boxes"]).reshape(-1, 7) for f in frames])
            arrays[f"{lv}/{name}_classes"] = np.concatenate([np.asarray(f["classes"]).reshape(-1) for f in frames])
            arrays[f"{lv}/{name}_offsets"] = np.cumsum([0] + [len(f["classes"]) for f in frames])
            if name == "pred":
                arrays[f"{lv}/pred_scores"] = np.concatenate([np.asarray(f["scores"]).reshape(-1) for f in frames])
        arrays[f"{lv}/scenes"] = np.asarray(scenes[lv])
    np.savez_compressed(path, **arrays)


def load_predictions(path: Path) -> dict[str, dict[str, Any]]:
    """The inverse of :func:`save_predictions`: per level ``{"pred": [frames], "gt": [frames], "scenes": [...]}``."""
    out: dict[str, dict[str, Any]] = {}
    with np.load(path) as z:
        levels = sorted({k.split("/")[0] for k in z.files})
        for lv in levels:
            entry: dict[str, Any] = {"scenes": z[f"{lv}/scenes"].tolist()}
            for name in ("pred", "gt"):
                o = z[f"{lv}/{name}_offsets"]
                b, c = z[f"{lv}/{name}_boxes"], z[f"{lv}/{name}_classes"]
                s = z[f"{lv}/pred_scores"] if name == "pred" else None
                entry[name] = [{"boxes": b[o[i]:o[i + 1]], "classes": c[o[i]:o[i + 1]],
                                **({"scores": s[o[i]:o[i + 1]]} if s is not None else {})} for i in range(len(o) - 1)]  # fmt: skip
            out[lv] = entry
    return out

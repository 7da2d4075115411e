"""Train one row of Experiment 1 (a training subset, one seed): the BEV detector from scratch with AdamW and a
one-cycle learning rate, evaluated on every test subset after every ``eval_every`` epochs; each (train, test) cell
keeps the epoch of best FDS, as the paper does."""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

import torch

from fog_gym.dataset.access import FogDrive
from fog_gym.experiments.detection3d.bev import BEVGrid
from fog_gym.experiments.detection3d.data import SweepDataset, collate
from fog_gym.experiments.detection3d.evaluate import METRICS, evaluate_levels, fds
from fog_gym.experiments.detection3d.model import BEVCenterNet, detection_loss, optimizer_step


def train_row(ds: FogDrive, pairs: list[tuple[str, str]], loaders: dict[str, Any], config: Any, seed: int,
              device: torch.device, tb_dir: Path, progress: bool = True) -> tuple[BEVCenterNet, dict[str, Any]]:  # fmt: skip
    """Train on the (scene, level) ``pairs`` with ``seed`` (weights, shuffling, augmentation); returns the last
    model and the row's record: sweeps, scenes, seconds and the best-FDS epoch's metrics per test level."""
    from torch.utils.tensorboard import SummaryWriter
    from tqdm import tqdm

    grid = BEVGrid()
    torch.manual_seed(seed)  # each row from its seed: a row never depends on which rows ran before
    data = SweepDataset(ds, pairs, grid, config.every, augment=True, seed=seed)
    loader = torch.utils.data.DataLoader(data, config.batch_size, shuffle=True, collate_fn=collate,
                                         num_workers=config.workers, generator=torch.Generator().manual_seed(seed))  # fmt: skip
    model = BEVCenterNet(width=config.width).to(device)
    opt = torch.optim.AdamW(model.parameters(), lr=config.lr, weight_decay=config.weight_decay)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, config.lr, total_steps=config.epochs * len(loader))
    tb = SummaryWriter(str(tb_dir))
    best: dict[str, dict[str, float]] = {}
    t0, step = time.perf_counter(), 0
    bar = tqdm(total=config.epochs * len(loader), desc=f"train {tb_dir.name} ({len(data)} sweeps)", unit="batch",
               disable=not progress)  # fmt: skip
    for epoch in range(config.epochs):
        model.train()
        data.epoch = epoch
        for feats, heat, bidx, cidx, reg, _ in loader:
            o = model(feats.to(device))
            loss, parts = detection_loss(o, heat.to(device), bidx.to(device), cidx.to(device), reg.to(device))
            value = optimizer_step(loss, opt, sched, bar)
            step += 1
            tb.add_scalar("loss/total", value, step)
            for k, v in parts.items():
                tb.add_scalar(f"loss/{k}", v, step)
        if (epoch + 1) % config.eval_every and epoch + 1 != config.epochs:
            continue
        for lv, r in evaluate_levels(model, loaders, device, grid, config.threshold).items():
            for k in METRICS:
                if not math.isnan(r[k]):
                    tb.add_scalar(f"{lv}/{k}", r[k], epoch + 1)
            if lv not in best or fds(r) > best[lv]["FDS"]:
                best[lv] = {k: float(r[k]) for k in METRICS} | {"epoch": epoch + 1, "n_gt": r["n_gt"],
                                                                "n_tp": r["n_tp"], "n_pred": r["n_pred"]}  # fmt: skip
    bar.close()
    tb.close()
    return model, {"train_sweeps": len(data), "train_scenes": len({n for n, _ in pairs}),
                   "seconds": time.perf_counter() - t0, "best": best}  # fmt: skip

"""Experiment 1 end to end: train the BEV detector on each training subset, evaluate every epoch on every test
subset, keep the best-FDS checkpoint per (train, test) cell as the paper does, write matrices and heatmaps.

Used by ``examples/exp1_detection3d.py`` (see its ``--help``); the ``torch`` extra, matplotlib for the figure.
"""

from __future__ import annotations

import json
import math
import os
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from fog_gym.dataset.access import FogDrive
from fog_gym.experiments.detection3d.bev import BEVGrid
from fog_gym.experiments.detection3d.data import SweepDataset, collate
from fog_gym.experiments.detection3d.model import BEVCenterNet, decode, detection_loss, optimizer_step, parameter_count
from fog_gym.experiments.detection3d.protocol import TEST_COLUMNS, TRAIN_ROWS, evaluation_subsets, training_subsets
from fog_gym.metrics.detection3d import evaluate

METRICS = ("mAP", "mean_TP", "ATE", "ASE", "AOE", "FDS", "ATE_m")


@dataclass(frozen=True)
class Exp1Config:
    """Budget and optimisation settings (AdamW, one-cycle learning rate as the paper's TransFusion runs)."""

    epochs: int = 20
    batch_size: int = 16
    lr: float = 1e-3
    weight_decay: float = 0.01
    every: int = 2  # use every n-th sample of a scene (samples are 0.1 s apart)
    test_every: int = 2
    eval_every: int = 1  # evaluate after every n-th epoch (and after the last)
    width: int = 32
    rows: tuple[str, ...] = TRAIN_ROWS
    fraction: float = 0.2
    mixed_fraction: float = 0.08
    test_fraction: float = 0.2
    seed: int = 0
    device: str = "auto"
    workers: int = 0
    threshold: float = 0.1

    def __post_init__(self) -> None:
        for name in ("epochs", "batch_size", "every", "test_every", "eval_every", "width"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ValueError(f"{name} must be a positive integer, got {v!r}")
        unknown = [r for r in self.rows if r not in TRAIN_ROWS]
        if unknown or not self.rows:
            raise ValueError(f"rows must be a non-empty subset of {TRAIN_ROWS}, got {list(self.rows)}")
        if not self.lr > 0:
            raise ValueError(f"lr must be > 0, got {self.lr}")
        if not 0 < self.test_fraction <= 1:
            raise ValueError(f"test_fraction must lie in (0, 1], got {self.test_fraction}")


def _device(name: str) -> torch.device:
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    return torch.device(name)


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


def run_experiment1(root: str | Path, out: str | Path, config: Exp1Config = Exp1Config(), progress: bool = True,
                    log=print) -> dict[str, Any]:  # fmt: skip
    """Run the protocol on the dataset at ``root``; writes ``results.json``, ``exp1.md``, ``exp1.png``, TensorBoard
    logs under ``out/tb``; returns the results.

    Each finished row is kept in ``out/rows/<row>.json`` with its checkpoint ``out/model_<row>.pt``; running again
    into the same ``out`` with the same dataset and settings skips those rows (a long run survives interruption).
    A row file written under other settings is an error, never silently mixed in."""
    from torch.utils.tensorboard import SummaryWriter
    from tqdm import tqdm

    out = Path(out)
    ds = FogDrive(root)
    if ds.splits is None or not ds.splits.get("train") or not ds.splits.get("test"):
        raise ValueError(f"{root}: Experiment 1 needs a dataset with train and test scenes in index/splits.json")
    grid = BEVGrid()
    device = _device(config.device)
    trains = training_subsets(ds.splits["train"], config.seed, config.fraction, config.mixed_fraction)
    tests = evaluation_subsets(ds.splits["test"], config.seed, config.test_fraction)
    loaders = {
        lv: torch.utils.data.DataLoader(SweepDataset(ds, pairs, grid, config.test_every), config.batch_size,
                                        collate_fn=collate, num_workers=config.workers)  # fmt: skip
        for lv, pairs in tests.items()
    }
    out.mkdir(parents=True, exist_ok=True)
    results: dict[str, Any] = {"config": asdict(config), "device": str(device), "rows": {},
                               "test_scenes": sorted({n for p in tests.values() for n, _ in p}),
                               "test_samples": {lv: len(l.dataset) for lv, l in loaders.items()}}  # fmt: skip
    (out / "rows").mkdir(exist_ok=True)
    for row in config.rows:
        done = out / "rows" / f"{row}.json"
        if done.exists():
            kept = json.loads(done.read_text())
            if kept.get("config") != _settings(config) or kept.get("test_scenes") != results["test_scenes"]:
                raise ValueError(f"{done} was written with other settings or test scenes; use another --out")
            results["rows"][row] = kept["row"]
            log(f"{row}: kept from {done}")
            continue
        torch.manual_seed(config.seed)  # each row from the same seed: a row never depends on which rows ran before
        data = SweepDataset(ds, trains[row], grid, config.every, augment=True, seed=config.seed)
        loader = torch.utils.data.DataLoader(data, config.batch_size, shuffle=True, collate_fn=collate,
                                             num_workers=config.workers,
                                             generator=torch.Generator().manual_seed(config.seed))  # fmt: skip
        model = BEVCenterNet(width=config.width).to(device)
        opt = torch.optim.AdamW(model.parameters(), lr=config.lr, weight_decay=config.weight_decay)
        sched = torch.optim.lr_scheduler.OneCycleLR(opt, config.lr, total_steps=config.epochs * len(loader))
        tb = SummaryWriter(str(out / "tb" / row))
        best: dict[str, dict[str, float]] = {}
        t0, step = time.perf_counter(), 0
        bar = tqdm(total=config.epochs * len(loader), desc=f"train {row} ({len(data)} sweeps)", unit="batch",
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
            for lv, test_loader in loaders.items():
                r = evaluate(*predict(model, test_loader, device, grid, config.threshold))
                for k in METRICS:
                    if not math.isnan(r[k]):
                        tb.add_scalar(f"{lv}/{k}", r[k], epoch + 1)
                fds = r["FDS"] if not math.isnan(r["FDS"]) else -1.0
                if lv not in best or fds > best[lv]["FDS"]:
                    best[lv] = {k: float(r[k]) for k in METRICS} | {"epoch": epoch + 1, "n_gt": r["n_gt"],
                                                                    "n_tp": r["n_tp"], "n_pred": r["n_pred"]}  # fmt: skip
        bar.close()
        tb.close()
        results["rows"][row] = {"train_sweeps": len(data), "train_scenes": len({n for n, _ in trains[row]}),
                                "seconds": time.perf_counter() - t0, "best": best}  # fmt: skip
        log(f"{row}: {len(data)} sweeps, {time.perf_counter() - t0:.0f} s; best-FDS mAP "
            + ", ".join(f"{lv} {best[lv]['mAP']:.3f}" for lv in TEST_COLUMNS))  # fmt: skip
        torch.save(model.state_dict(), out / f"model_{row}.pt")
        _write_atomic(done, json.dumps({"config": _settings(config), "test_scenes": results["test_scenes"],
                                        "row": results["rows"][row]}, indent=1))  # fmt: skip
    results["parameters"] = parameter_count(BEVCenterNet(width=config.width))
    _write_atomic(out / "results.json", json.dumps(results, indent=1))
    _write_atomic(out / "exp1.md", markdown(results))
    figure(results, out / "exp1.png")
    return results


def _settings(config: Exp1Config) -> dict[str, Any]:
    """The settings a finished row depends on, as they read back from JSON (not which rows, device or workers)."""
    kept = {k: v for k, v in asdict(config).items() if k not in ("rows", "device", "workers")}
    return json.loads(json.dumps(kept))


def _write_atomic(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def markdown(results: dict[str, Any]) -> str:
    """The matrices (train rows × test columns) of mAP@0.5, Mean TP, ATE, ASE and AOE at the best-FDS epoch."""
    rows = results["rows"]
    lines = []
    for metric, title in (("mAP", "mAP@0.5 (3D IoU)"), ("mean_TP", "Mean TP"), ("ATE", "ATE (1 − error / 2 m)"),
                          ("ASE", "ASE (1 − scale error)"), ("AOE", "AOE (1 − orientation error / π)")):  # fmt: skip
        lines += [f"**{title}** — best-FDS epoch per cell; column-wise best in bold", "",
                  "| train ↓ / test → | " + " | ".join(TEST_COLUMNS) + " |", "|---|" + "---|" * len(TEST_COLUMNS)]  # fmt: skip
        best_col = {c: max((r["best"][c][metric] for r in rows.values()), default=0.0) for c in TEST_COLUMNS}
        for name, r in rows.items():
            cells = []
            for c in TEST_COLUMNS:
                v = r["best"][c][metric]
                cells.append(f"**{v:.4f}**" if v == best_col[c] and len(rows) > 1 else f"{v:.4f}")
            lines.append(f"| {name} | " + " | ".join(cells) + " |")
        lines.append("")
    return "\n".join(lines)


def figure(results: dict[str, Any], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = list(results["rows"])
    fig, axes = plt.subplots(1, 3, figsize=(12, 0.55 * len(rows) + 1.8))
    for ax, metric in zip(axes, ("mAP", "mean_TP", "ATE"), strict=True):
        m = np.array([[results["rows"][r]["best"][c][metric] for c in TEST_COLUMNS] for r in rows])
        im = ax.imshow(m, cmap="viridis", aspect="auto")
        ax.set_xticks(range(len(TEST_COLUMNS)), TEST_COLUMNS)
        ax.set_yticks(range(len(rows)), rows)
        for i in range(len(rows)):
            for j in range(len(TEST_COLUMNS)):
                ax.text(j, i, f"{m[i, j]:.3f}", ha="center", va="center", color="w" if m[i, j] < m.mean() else "k",
                        fontsize=8)  # fmt: skip
        ax.set_title({"mAP": "mAP@0.5", "mean_TP": "Mean TP", "ATE": "ATE"}[metric])
        ax.set_xlabel("test fog")
        fig.colorbar(im, ax=ax, fraction=0.046)
    axes[0].set_ylabel("training subset")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def threads_default() -> int:
    return max(1, os.cpu_count() or 1)

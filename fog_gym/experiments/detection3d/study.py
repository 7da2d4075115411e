"""Experiment 1 as a study of the runner: settings (:class:`Exp1Config`), data (the dataset, generated first on
request, and its subsets), one unit per (training subset, seed) — train and evaluate every epoch, keep the best-FDS
epoch per test column — and the report (matrices with 95 % CIs across seeds, heatmaps).

``--seeds K`` trains every row with seeds ``seed, seed + 1, …`` (weights, shuffling, augmentation); the scene
subsets come from ``--seed`` alone, so every seed sees the same data.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from fog_gym.experiments.detection3d.protocol import TEST_COLUMNS, TRAIN_ROWS, evaluation_subsets, training_subsets
from fog_gym.experiments.dataset_study import DatasetStudy
from fog_gym.experiments.runner import Report, Unit, aggregate, run, torch_device


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

    def settings(self) -> dict[str, Any]:
        """The settings a finished row depends on, as they read back from JSON (not which rows, device or workers)."""
        kept = {k: v for k, v in asdict(self).items() if k not in ("rows", "device", "workers")}
        return json.loads(json.dumps(kept))


class Exp1Study(DatasetStudy):
    """Experiment 1 on the dataset at ``root`` (generated first when ``generate`` scenes are asked for)."""

    name = "exp1"
    command = "fog-gym exp1"
    default_out = Path("out/exp1")
    smoke_help = ("a few-minute budget: generate 10 short scenes if --root holds no dataset, 2 epochs, rows Light and "
                  "Mixed-L")  # fmt: skip
    description = (
        "Experiment 1 of the FogDrive paper: does mixing fog densities at training time make a 3D detector more "
        "robust?\n\n"
        "Trains fog-gym's BEV detector on the Light, Dense, Mixed-S, Mixed-L (and Clear) subsets of a dataset's train "
        "split, evaluates every epoch on the light / moderate / dense (and clear) test subsets, keeps the best-FDS "
        "epoch per cell and writes exp1.md (mAP@0.5, Mean TP, ATE, ASE, AOE matrices), exp1.png, results.json, "
        "models/<row>_s<seed>.pt and TensorBoard logs. Run again into the same --out to resume.\n\n"
        "fog-gym exp1 --root out/lidar --out out/exp1                 # an existing dataset\n"
        "fog-gym exp1 --generate 40 --root out/lidar --out out/exp1   # generate a LiDAR-only set first\n"
        "fog-gym exp1 --smoke --root out/exp1_smoke --out out/exp1_smoke")

    def __init__(self, root: str | Path, config: Exp1Config | None = None, generate: int = 0, seconds: float = 10.0,
                 gen_workers: int = 1) -> None:  # fmt: skip
        super().__init__(root, config or Exp1Config(), generate, seconds, gen_workers, modality="lidar")
        self.test_samples: dict[str, int] = {}

    def _subsets(self, ds: Any) -> tuple[dict[str, list], dict[str, list]]:
        c = self.config
        return (training_subsets(ds.splits["train"], c.seed, c.fraction, c.mixed_fraction),
                evaluation_subsets(ds.splits["test"], c.seed, c.test_fraction))  # fmt: skip

    def _test_loaders(self, ds: Any, tests: dict[str, list]) -> dict[str, Any]:
        import torch

        from fog_gym.experiments.detection3d.bev import BEVGrid
        from fog_gym.experiments.detection3d.data import SweepDataset, collate

        c = self.config
        return {lv: torch.utils.data.DataLoader(SweepDataset(ds, pairs, BEVGrid(), c.test_every), c.batch_size,
                                                collate_fn=collate, num_workers=c.workers)
                for lv, pairs in tests.items()}  # fmt: skip

    def prepare(self, log: Callable[[str], None], progress: bool) -> dict[str, Any]:
        ds = self.open_dataset(log, progress)
        if ds.splits is None or not ds.splits.get("train") or not ds.splits.get("test"):
            raise ValueError(f"{self.root}: Experiment 1 needs a dataset with train and test scenes in index/splits.json")
        trains, tests = self._subsets(ds)
        self.test_samples = {lv: len(loader.dataset) for lv, loader in self._test_loaders(ds, tests).items()}
        return {"test_scenes": sorted({n for p in tests.values() for n, _ in p}),
                "train_scenes": sorted({n for p in trains.values() for n, _ in p})}  # fmt: skip

    def units(self, seeds: Sequence[int]) -> list[Unit]:
        return [Unit("rows", f"{row}_s{seed}", seed, {"row": row}) for seed in seeds for row in self.config.rows]

    def artefacts(self, unit: Unit) -> list[str]:
        return [f"models/{unit.key}.pt"]

    def run_unit(self, unit: Unit, out: Path, progress: bool) -> dict[str, Any]:
        import torch

        from fog_gym.dataset.access import FogDrive
        from fog_gym.experiments.detection3d.train import train_row
        from fog_gym.experiments.runner import atomic_path

        ds = FogDrive(self.root)
        trains, tests = self._subsets(ds)
        device = torch_device(self.config.device)
        model, record = train_row(ds, trains[unit.params["row"]], self._test_loaders(ds, tests), self.config, unit.seed,
                                  device, out / "tb" / unit.key, progress)  # fmt: skip
        with atomic_path(out / "models" / f"{unit.key}.pt") as tmp:
            torch.save(model.state_dict(), tmp)
        return record

    def describe(self, unit: Unit, result: dict[str, Any]) -> str:
        best = result["best"]
        return f"{result['train_sweeps']} sweeps; best-FDS mAP " + ", ".join(f"{lv} {best[lv]['mAP']:.3f}" for lv in TEST_COLUMNS)

    def report(self, records: dict[str, dict[str, Any]], out: Path, seeds: Sequence[int]) -> Report:
        from fog_gym.experiments.detection3d import report
        from fog_gym.experiments.detection3d.model import BEVCenterNet, parameter_count

        cells: dict[str, Any] = {}
        rows: dict[str, Any] = {}
        for r in records.values():
            row, res = r["params"]["row"], r["result"]
            for col in TEST_COLUMNS:
                cells.setdefault(row, {}).setdefault(col, {})[r["seed"]] = res["best"][col]
            rows.setdefault(row, {"train_sweeps": res["train_sweeps"], "train_scenes": res["train_scenes"], "seeds": {}})
            rows[row]["seeds"][str(r["seed"])] = res
        table = aggregate({row: cells[row] for row in self.config.rows})
        manifest = json.loads((out / "study.json").read_text())
        data = {"config": asdict(self.config), "device": str(torch_device(self.config.device)), "seeds": list(seeds),
                "test_scenes": manifest["data"]["test_scenes"], "test_samples": self.test_samples, "table": table,
                "rows": rows, "parameters": parameter_count(BEVCenterNet(width=self.config.width))}  # fmt: skip
        return Report(report.markdown(table, len(seeds)), data, "exp1.md", "results.json",
                      {"exp1.png": lambda p: report.figure(table, p)})

    @classmethod
    def add_arguments(cls, p: argparse.ArgumentParser) -> None:
        cls.add_common_arguments(p, "with train/test splits; LiDAR-only will do", "subset", 1e-3)
        p.add_argument("--fraction", type=float, default=0.2, help="share of train scenes per density subset (paper 0.2)")
        p.add_argument("--mixed-fraction", type=float, default=0.08, help="Mixed-S share per density (paper 0.08)")
        p.add_argument("--test-fraction", type=float, default=0.2, help="share of test scenes evaluated (paper 0.2)")
        p.add_argument("--rows", nargs="+", default=list(TRAIN_ROWS), help="training subsets to run (default all five)")
        p.add_argument("--workers", type=int, default=0, help="DataLoader worker processes (default 0)")

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> Exp1Study:
        if args.smoke:
            cls.smoke_dataset(args)
            args.seconds, args.epochs, args.rows, args.every, args.test_every = 2.0, 2, ["Light", "Mixed-L"], 2, 2
        config = Exp1Config(epochs=args.epochs, batch_size=args.batch_size, lr=args.lr, every=args.every,
                            test_every=args.test_every, eval_every=args.eval_every, rows=tuple(args.rows),
                            device=args.device, workers=args.workers, seed=args.seed, fraction=args.fraction,
                            mixed_fraction=args.mixed_fraction, test_fraction=args.test_fraction)  # fmt: skip
        return cls(args.root, config, args.generate, args.seconds, args.gen_workers)


def run_experiment1(root: str | Path, out: str | Path, config: Exp1Config | None = None, progress: bool = True,
                    log: Callable[[str], None] | None = None, seeds: int = 1) -> dict[str, Any]:  # fmt: skip
    """Run Experiment 1 on the dataset at ``root`` into ``out`` (see the module docstring); returns ``results.json``'s
    content. Finished rows are kept; other settings into the same ``out`` are refused before any work."""
    return run(Exp1Study(root, config), out, seeds=seeds, progress=progress, log=log).data

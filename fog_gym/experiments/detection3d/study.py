"""Experiment 1 as a study of the runner: settings (:class:`Exp1Config`), data (the dataset, generated first on
request, its subsets, and the cache of pillarised sweeps), one unit per (detector, training subset, seed) — train
and evaluate every epoch, keep the best-FDS epoch per test column and its predictions — an optional budget stage
(the pillar detector on Light for other epoch counts: the learning curve), and the report (matrices with 95 % CIs
across seeds, paired bootstrap comparisons and a verdict per claim, figures).

``--seeds K`` trains every unit with seeds ``seed, seed + 1, …`` (weights, shuffling, augmentation); the scene
subsets come from ``--seed`` alone, so every seed sees the same data. Units run seed by seed, so a run stopped
early has whole matrices for its first seeds.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

from fog_gym.dataset.digest import content_digest
from fog_gym.experiments.dataset_study import DatasetStudy
from fog_gym.experiments.detection3d.protocol import TEST_COLUMNS, TRAIN_ROWS, evaluation_subsets, training_subsets
from fog_gym.experiments.runner import Report, StudyError, Unit, run, torch_device

DETECTOR_NAMES = {"pillars": "PointPillars + CenterPoint heads", "bev": "small BEV CenterNet"}


@dataclass(frozen=True)
class Exp1Config:
    """Budget, data and network settings. The defaults are the CPU configuration; :meth:`gpu` the GPU one.

    Optimisation: AdamW with a one-cycle learning rate (CenterPoint's and the paper's TransFusion runs).
    ``every`` / ``test_every``: use every n-th sample of a scene (samples are 0.1 s apart). ``match_sweeps``: Mixed-S
    (8 % of the scenes per density, the paper's) is thinned at random to the Light row's sweep count, so that the
    comparison with the single-density rows is at equal data. ``budget_epochs``: extra runs of the pillar detector
    on the Light row (first seed) for these epoch counts — the learning curve of end-of-schedule mAP against the
    sweeps seen."""

    epochs: int = 10
    batch_size: int = 8
    lr: float = 2e-3
    weight_decay: float = 0.01
    every: int = 1
    test_every: int = 4
    eval_every: int = 2
    detectors: tuple[str, ...] = ("pillars", "bev")
    width: int = 32  # the BEV detector's
    range_m: float = 40.0
    pillar_m: float = 0.4
    z_min: float = -3.0
    z_max: float = 2.0
    stride: int = 2
    max_points: int = 32
    pfn: int = 32
    pillar_widths: tuple[int, int, int] = (32, 64, 128)
    pillar_layers: tuple[int, int, int] = (3, 5, 5)
    neck: int = 64
    head: int = 64
    rows: tuple[str, ...] = TRAIN_ROWS
    fraction: float = 0.2
    mixed_fraction: float = 0.08
    match_sweeps: bool = True
    test_fraction: float = 1.0
    budget_epochs: tuple[int, ...] = ()
    seed: int = 0
    device: str = "auto"
    precision: str = "auto"
    workers: int = 0
    threshold: float = 0.1
    profile: str = "cpu"

    def __post_init__(self) -> None:
        for name in ("epochs", "batch_size", "every", "test_every", "eval_every", "width"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ValueError(f"{name} must be a positive integer, got {v!r}")
        for name in ("detectors", "rows", "pillar_widths", "pillar_layers", "budget_epochs"):
            object.__setattr__(self, name, tuple(getattr(self, name)))
        for name in ("pillar_widths", "pillar_layers"):
            v = getattr(self, name)
            if len(v) != 3 or any(isinstance(x, bool) or not isinstance(x, int) or x < 1 for x in v):
                raise ValueError(f"{name} must be three positive integers, got {list(v)!r}")
        for name in ("pfn", "neck", "head", "max_points", "stride"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ValueError(f"{name} must be a positive integer, got {v!r}")
        from fog_gym.experiments.detection3d.data import DETECTORS

        if not self.detectors or any(d not in DETECTORS for d in self.detectors) or len(set(self.detectors)) < len(self.detectors):
            raise ValueError(f"detectors must be a non-empty subset of {DETECTORS}, got {list(self.detectors)}")
        unknown = [r for r in self.rows if r not in TRAIN_ROWS]
        if unknown or not self.rows:
            raise ValueError(f"rows must be a non-empty subset of {TRAIN_ROWS}, got {list(self.rows)}")
        if not self.lr > 0:
            raise ValueError(f"lr must be > 0, got {self.lr}")
        if not 0 < self.test_fraction <= 1:
            raise ValueError(f"test_fraction must lie in (0, 1], got {self.test_fraction}")
        if not 0 < self.mixed_fraction <= self.fraction <= 1 / 3:
            raise ValueError(f"need 0 < mixed_fraction <= fraction <= 1/3, got {self.mixed_fraction} and {self.fraction}")
        if any(isinstance(e, bool) or not isinstance(e, int) or e < 1 for e in self.budget_epochs):
            raise ValueError(f"budget_epochs must be positive integers, got {list(self.budget_epochs)}")
        if self.precision not in ("auto", "bf16", "fp32"):
            raise ValueError(f"precision must be auto, bf16 or fp32, got {self.precision!r}")
        if self.profile not in ("cpu", "gpu"):
            raise ValueError(f"profile must be cpu or gpu, got {self.profile!r}")
        self.pillar_config  # noqa: B018  (checks the pillar grid, caps and widths)
        self.grid("bev")  # noqa: B018

    @classmethod
    def gpu(cls, **overrides: Any) -> Exp1Config:
        """The GPU configuration: 0.2 m pillars, PointPillars' widths, a wider BEV network, batch 16, 20 epochs."""
        from fog_gym.experiments.detection3d.pillar_model import GPU_PILLARS as g

        base = {"epochs": 20, "batch_size": 16, "width": 64, "pillar_m": g.cell_m, "pfn": g.pfn, "pillar_widths": g.widths,
                "neck": g.up, "head": g.head, "profile": "gpu"}  # fmt: skip
        return cls(**{**base, **overrides})

    @property
    def pillar_config(self) -> Any:
        from fog_gym.experiments.detection3d.pillar_model import PillarConfig

        return PillarConfig(self.range_m, self.pillar_m, self.z_min, self.z_max, self.stride, self.max_points, self.pfn,
                            self.pillar_widths, self.pillar_layers, self.neck, self.head)  # fmt: skip

    def grid(self, detector: str) -> Any:
        """The detector's grid: the pillar grid, or the BEV detector's 0.5 m grid (outputs at 1 m) over the same range."""
        from fog_gym.experiments.detection3d.bev import BEVGrid

        if detector == "pillars":
            return self.pillar_config.grid
        return BEVGrid(self.range_m, 0.5, self.z_min, self.z_max, 2)

    def settings(self) -> dict[str, Any]:
        """The settings a finished unit depends on, as they read back from JSON (not which detectors, rows or
        budget runs, nor device or workers)."""
        skip = ("detectors", "rows", "budget_epochs", "device", "workers")
        return json.loads(json.dumps({k: v for k, v in asdict(self).items() if k not in skip}))


class Exp1Study(DatasetStudy):
    """Experiment 1 on the dataset at ``root`` (generated first when ``generate`` scenes are asked for)."""

    name = "exp1"
    command = "fog-gym exp1"
    default_out = Path("out/exp1")
    smoke_help = ("a one-minute budget: generate 10 short scenes if --root holds no dataset; 1 epoch, rows Light and "
                  "Mixed-L, both detectors at toy widths")  # fmt: skip
    description = (
        "Experiment 1 of the FogDrive paper: does mixing fog densities at training time make a 3D detector more "
        "robust?\n\n"
        "Trains two detectors — a PointPillars encoder with CenterPoint heads (--detectors pillars) and a small BEV "
        "CenterNet on hand-made pillar features (bev) — on the Light, Dense, Mixed-S, Mixed-L (and Clear) subsets of "
        "a dataset's train split, evaluates every epoch on the light / moderate / dense (and clear) test subsets, "
        "keeps the best-FDS epoch per cell and writes exp1.md (a verdict per claim from paired bootstrap "
        "comparisons, matrices of mAP@0.5, Mean TP, ATE, ASE, AOE and FDS with 95 % CIs across seeds, per-class AP, "
        "AP per distance band, learning curves), figures, results.json, models/, preds/ and TensorBoard logs. "
        "Pillarised sweeps are cached under <out>/cache. Run again into the same --out to resume.\n\n"
        "fog-gym exp1 --root out/lidar --out out/exp1 --seeds 3         # an existing dataset, CPU configuration\n"
        "fog-gym exp1 --root out/lidar --out out/exp1_gpu --gpu --seeds 3   # the GPU configuration\n"
        "fog-gym exp1 --generate 40 --root out/lidar --out out/exp1     # generate a LiDAR-only set first\n"
        "fog-gym exp1 --smoke --root out/exp1_smoke --out out/exp1_smoke")

    def __init__(self, root: str | Path, config: Exp1Config | None = None, generate: int = 0, seconds: float = 10.0,
                 gen_workers: int = 1) -> None:  # fmt: skip
        super().__init__(root, config or Exp1Config(), generate, seconds, gen_workers, modality="lidar")
        self.test_samples: dict[str, int] = {}

    # -- data --------------------------------------------------------------------------------------------------
    def _subsets(self, ds: Any) -> tuple[dict[str, list], dict[str, list]]:
        c = self.config
        return (training_subsets(ds.splits["train"], c.seed, c.fraction, c.mixed_fraction),
                evaluation_subsets(ds.splits["test"], c.seed, c.test_fraction))  # fmt: skip

    def _cache(self, out: Path) -> Any:
        from fog_gym.experiments.detection3d.data import SweepCache

        return SweepCache(Path(out) / "cache", self.config.pillar_config.grid)

    def _train_set(self, ds: Any, trains: dict[str, list], row: str, cache: Any, detector: str, seed: int,
                   augment: bool = True) -> Any:  # fmt: skip
        from fog_gym.experiments.detection3d.data import SweepDataset

        c = self.config
        data = SweepDataset(ds, trains[row], cache, detector, c.grid(detector), c.every, augment=augment, seed=seed,
                            max_points=c.max_points)  # fmt: skip
        if row == "Mixed-S" and c.match_sweeps:
            light = len(SweepDataset(ds, trains["Light"], cache, detector, c.grid(detector), c.every).items)
            data.thin(light, c.seed)
        return data

    def _test_sets(self, ds: Any, tests: dict[str, list], cache: Any, detector: str) -> dict[str, Any]:
        from fog_gym.experiments.detection3d.data import SweepDataset

        c = self.config
        return {lv: SweepDataset(ds, pairs, cache, detector, c.grid(detector), c.test_every) for lv, pairs in tests.items()}

    def prepare(self, log: Callable[[str], None], progress: bool) -> dict[str, Any]:
        ds = self.open_dataset(log, progress)
        if ds.splits is None or not ds.splits.get("train") or not ds.splits.get("test"):
            raise ValueError(f"{self.root}: Experiment 1 needs a dataset with train and test scenes in index/splits.json")
        trains, tests = self._subsets(ds)
        cache = self._cache(self.output)
        sets = {row: self._train_set(ds, trains, row, cache, "pillars", 0, augment=False) for row in TRAIN_ROWS}
        tsets = self._test_sets(ds, tests, cache, "pillars")
        self.test_samples = {lv: len(t) for lv, t in tsets.items()}
        chosen = [sets[row] for row in self.config.rows]
        todo = list(dict.fromkeys(it for d in (*chosen, *tsets.values()) for it in d.items))
        from tqdm import tqdm

        for it in tqdm(todo, desc="exp1: pillarise sweeps (cached)", unit="sweep", disable=not progress):
            cache.get(*it[:3])
        test_scenes = sorted({n for p in tests.values() for n, _ in p})
        train_scenes = sorted({n for p in trains.values() for n, _ in p})
        return {"test_scenes": test_scenes, "train_scenes": train_scenes,
                "train_sweeps": {row: len(d) for row, d in sets.items()}, "test_sweeps": self.test_samples,
                "digest": content_digest(ds, train_scenes + test_scenes)}  # fmt: skip

    # -- units -------------------------------------------------------------------------------------------------
    def units(self, seeds: Sequence[int]) -> list[Unit]:
        c = self.config
        units = [Unit("rows", f"{det}_{row}_s{seed}", seed, {"row": row, "detector": det})
                 for seed in seeds for det in c.detectors for row in c.rows]  # fmt: skip
        units += [Unit("budget", f"pillars_Light_e{e}_s{seeds[0]}", seeds[0], {"row": "Light", "detector": "pillars", "epochs": e})
                  for e in c.budget_epochs if e != c.epochs]  # fmt: skip
        return units

    def artefacts(self, unit: Unit) -> list[str]:
        return [f"preds/{unit.key}.npz"]  # what the report reads; models/<key>.pt is written too, not required

    def run_unit(self, unit: Unit, out: Path, progress: bool) -> dict[str, Any]:
        import torch

        from fog_gym.dataset.access import FogDrive
        from fog_gym.experiments.detection3d.train import save_predictions, train_row
        from fog_gym.experiments.runner import EpochCheckpoint, atomic_path

        ds = FogDrive(self.root)
        trains, tests = self._subsets(ds)
        det, row = unit.params["detector"], unit.params["row"]
        config = replace(self.config, epochs=unit.params.get("epochs", self.config.epochs))
        cache = self._cache(out)
        data = self._train_set(ds, trains, row, cache, det, unit.seed)
        test_sets = self._test_sets(ds, tests, cache, det)
        checkpoint = out / "checkpoints" / f"{unit.key}.pt"
        model, record, preds = train_row(data, test_sets, config, det, unit.seed, torch_device(config.device),
                                         out / "tb" / unit.key, progress, checkpoint)  # fmt: skip
        record["train_scenes"] = len({n for n, _ in trains[row]})
        with atomic_path(out / "models" / f"{unit.key}.pt") as tmp:
            torch.save(model.state_dict(), tmp)
        gts = {lv: [t.cache.get(*it[:3])[1] for it in t.items] for lv, t in test_sets.items()}
        scenes = {lv: [it[3] for it in t.items] for lv, t in test_sets.items()}
        with atomic_path(out / "preds" / f"{unit.key}.npz") as tmp:
            save_predictions(tmp, preds, gts, scenes)
        EpochCheckpoint(checkpoint, {}).clear()
        return record

    def describe(self, unit: Unit, result: dict[str, Any]) -> str:
        best = result["best"]
        return f"{result['train_sweeps']} sweeps; best-FDS mAP " + ", ".join(f"{lv} {best[lv]['mAP']:.3f}" for lv in best)

    def report(self, records: dict[str, dict[str, Any]], out: Path, seeds: Sequence[int]) -> Report:
        from fog_gym.experiments.detection3d import report

        manifest = json.loads((out / "study.json").read_text())
        return report.build(records, out, list(seeds), self.config, manifest["data"], str(torch_device(self.config.device)),
                            self.root)

    # -- command line ------------------------------------------------------------------------------------------
    @classmethod
    def add_arguments(cls, p: argparse.ArgumentParser) -> None:
        cls.add_common_arguments(p, "with train/test splits; LiDAR-only will do", "unit", 2e-3)
        for action in p._actions:  # the configuration decides these defaults (CPU or GPU)
            if action.dest in ("epochs", "batch_size", "every", "test_every", "eval_every"):
                action.default = None
                action.help = {"epochs": "training epochs per unit (CPU configuration 10, GPU 20)",
                               "batch_size": "batch size (CPU 8, GPU 16)",
                               "every": "use every n-th training sample of a scene (default 1: 10 Hz)",
                               "test_every": "use every n-th test sample (default 4)",
                               "eval_every": "evaluate after every n-th epoch and the last (default 2)"}[action.dest]  # fmt: skip
        p.add_argument("--detectors", nargs="+", default=["pillars", "bev"], choices=("pillars", "bev"),
                       help="detectors to train (default both; --detector is the same option)")
        p.add_argument("--detector", dest="detectors", nargs="+", choices=("pillars", "bev"), help=argparse.SUPPRESS)
        p.add_argument("--gpu", action="store_true",
                       help="the GPU configuration: 0.2 m pillars, widths 64/128/256, BEV width 64, batch 16, 20 epochs "
                            "(explicit options still win)")
        p.add_argument("--fraction", type=float, default=0.2, help="share of train scenes per density subset (paper 0.2)")
        p.add_argument("--mixed-fraction", type=float, default=0.08, help="Mixed-S share per density (paper 0.08)")
        p.add_argument("--no-match-sweeps", action="store_true",
                       help="keep all of Mixed-S's sweeps (default: thinned to the Light row's count)")
        p.add_argument("--test-fraction", type=float, default=1.0,
                       help="share of test scenes evaluated (default 1.0: every test scene, every 4th sample; paper 0.2)")
        p.add_argument("--rows", nargs="+", default=list(TRAIN_ROWS), help="training subsets to run (default all five)")
        p.add_argument("--budget-epochs", type=int, nargs="*", default=[],
                       help="learning curve: also train the pillar detector on Light for these epoch counts")
        net = p.add_argument_group("grid and networks")
        net.add_argument("--range", dest="range_m", type=float, default=40.0, help="grid half-width [m] (default 40)")
        net.add_argument("--pillar-size", dest="pillar_m", type=float, default=None, help="pillar size [m] (CPU 0.4, GPU 0.2)")
        net.add_argument("--pillar-widths", type=int, nargs=3, default=None, metavar=("W1", "W2", "W3"),
                         help="backbone block widths (CPU 32 64 128, GPU 64 128 256)")
        net.add_argument("--pillar-layers", type=int, nargs=3, default=[3, 5, 5], metavar=("L1", "L2", "L3"),
                         help="convolutions per backbone block (default 3 5 5)")
        net.add_argument("--pfn", type=int, default=None, help="pillar feature net channels (CPU 32, GPU 64)")
        net.add_argument("--neck", type=int, default=None, help="channels per upsampled scale (CPU 64, GPU 128)")
        net.add_argument("--head", type=int, default=None, help="head channels (default 64)")
        net.add_argument("--max-points", type=int, default=32, help="points kept per pillar (default 32)")
        net.add_argument("--width", type=int, default=None, help="the BEV detector's width (CPU 32, GPU 64)")
        net.add_argument("--precision", choices=("auto", "bf16", "fp32"), default="auto",
                         help="bf16 autocast where the device computes it natively (auto), or force one")
        p.add_argument("--workers", type=int, default=0, help="DataLoader worker processes (default 0)")

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> Exp1Study:
        if args.smoke:
            cls.smoke_dataset(args)
            args.seconds, args.epochs, args.rows, args.every, args.test_every = 2.0, 1, ["Light", "Mixed-L"], 2, 2
            args.pillar_widths, args.pillar_layers, args.pfn, args.neck, args.head, args.width = [8, 8, 8], [1, 1, 1], 8, 8, 8, 8
            args.test_fraction = 1.0
        options = {"epochs": args.epochs, "batch_size": args.batch_size, "lr": args.lr, "every": args.every,
                   "test_every": args.test_every, "eval_every": args.eval_every, "rows": tuple(args.rows),
                   "detectors": tuple(dict.fromkeys(args.detectors)), "device": args.device, "workers": args.workers,
                   "seed": args.seed, "fraction": args.fraction, "mixed_fraction": args.mixed_fraction,
                   "match_sweeps": not args.no_match_sweeps, "test_fraction": args.test_fraction,
                   "budget_epochs": tuple(args.budget_epochs), "range_m": args.range_m, "max_points": args.max_points,
                   "pillar_layers": tuple(args.pillar_layers), "precision": args.precision, "pillar_m": args.pillar_m,
                   "pillar_widths": args.pillar_widths, "pfn": args.pfn, "neck": args.neck, "head": args.head,
                   "width": args.width}  # fmt: skip
        options = {k: tuple(v) if isinstance(v, list) else v for k, v in options.items() if v is not None}
        config = Exp1Config.gpu(**options) if args.gpu else Exp1Config(**options)
        return cls(args.root, config, args.generate, args.seconds, args.gen_workers)


def run_experiment1(root: str | Path, out: str | Path, config: Exp1Config | None = None, progress: bool = True,
                    log: Callable[[str], None] | None = None, seeds: int = 1) -> dict[str, Any]:  # fmt: skip
    """Run Experiment 1 on the dataset at ``root`` into ``out`` (see the module docstring); returns ``results.json``'s
    content. Finished units are kept; other settings into the same ``out`` are refused before any work."""
    return run(Exp1Study(root, config), out, seeds=seeds, progress=progress, log=log).data


__all__ = ["Exp1Config", "Exp1Study", "StudyError", "run_experiment1"]

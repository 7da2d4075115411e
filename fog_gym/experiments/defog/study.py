"""Experiment 2 as a study of the runner: settings (:class:`Exp2Config`), data (the dataset, generated first on
request, and its chosen scenes), units — per seed, a detector trained on clean frames and one on each fog level,
AOD-Net, then one evaluation of every pipeline — and the report (both tables with 95 % CIs across seeds, the figure).

``--seeds K`` trains every model with seeds ``seed, seed + 1, …`` (weights, shuffling, augmentation, AOD-Net's
crops); the scenes come from ``--seed`` alone, so every seed sees the same frames.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from fog_gym.experiments.defog.data import CAMERAS, LEVELS, channel, choose_scenes
from fog_gym.experiments.dataset_study import DatasetStudy
from fog_gym.experiments.runner import Report, Unit, aggregate, run, size_arg, torch_device


@dataclass(frozen=True)
class Exp2Config:
    """Budget and optimisation settings (AdamW with a one-cycle learning rate)."""

    epochs: int = 20
    batch_size: int = 16
    lr: float = 2e-3
    weight_decay: float = 1e-4
    every: int = 2  # every n-th sample of a train / val scene (samples are 0.1 s apart)
    test_every: int = 2
    eval_every: int = 1
    input_size: tuple[int, int] = (320, 240)  # detector input (W, H)
    width: int = 24
    train_fraction: float = 0.15
    val_fraction: float = 0.2
    test_fraction: float = 0.2
    aod_epochs: int = 10
    aod_pairs: int = 600  # (clean, fog) training pairs for AOD-Net, random crops of the full frame
    cameras: tuple[str, ...] = CAMERAS
    seed: int = 0
    device: str = "auto"
    threshold: float = 0.001  # detections kept for COCO evaluation (the paper's validation confidence)
    #: Ground-truth boxes lower than this many pixels *at the detector input* are ignore regions in evaluation
    #: (COCO crowd: neither hit nor miss); 0 evaluates every box, as the paper does at 1280 × 960.
    min_height: float = 0.0
    #: Photometric augmentation of the detectors' training images: random hue, saturation and value gains within
    #: ±(h, s, v) — Ultralytics' defaults (0.015, 0.7, 0.4), part of the paper's "default augmentations"; zeros
    #: switch it off (horizontal flips always apply).
    hsv: tuple[float, float, float] = (0.015, 0.7, 0.4)

    def __post_init__(self) -> None:
        for name in ("epochs", "batch_size", "every", "test_every", "eval_every", "width", "aod_epochs", "aod_pairs"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ValueError(f"{name} must be a positive integer, got {v!r}")
        from fog_gym.experiments.defog.model import STRIDE

        w, h = self.input_size
        if w % (4 * STRIDE) or h % (4 * STRIDE) or w < 32 or h < 32:
            raise ValueError(f"input_size must be (W, H), both multiples of 16 and >= 32, got {self.input_size}")
        for name in ("train_fraction", "val_fraction", "test_fraction"):
            if not 0 < getattr(self, name) <= 1:
                raise ValueError(f"{name} must lie in (0, 1], got {getattr(self, name)}")
        if not self.lr > 0:
            raise ValueError(f"lr must be > 0, got {self.lr}")
        if len(self.hsv) != 3 or not all(isinstance(g, (int, float)) and 0 <= g <= 1 for g in self.hsv):
            raise ValueError(f"hsv must be three gains in [0, 1] (hue, saturation, value), got {self.hsv!r}")
        object.__setattr__(self, "hsv", tuple(float(g) for g in self.hsv))
        if not (isinstance(self.min_height, (int, float)) and 0 <= self.min_height < h):
            raise ValueError(f"min_height must lie in [0, input height {h}), got {self.min_height!r}")
        bad = [c for c in self.cameras if c not in ("CAM_FRONT", "CAM_BACK", "CAM_LEFT", "CAM_RIGHT")]
        if bad or not self.cameras:
            raise ValueError(f"cameras must name FogDrive cameras, got {list(self.cameras)}")

    def settings(self) -> dict[str, Any]:
        """What a trained model depends on, as it reads back from JSON (not the device)."""
        return json.loads(json.dumps({k: v for k, v in asdict(self).items() if k != "device"}))


class Exp2Study(DatasetStudy):
    """Experiment 2 on the dataset at ``root`` (generated first when ``generate`` scenes are asked for)."""

    name = "exp2"
    command = "fog-gym exp2"
    default_out = Path("out/exp2")
    smoke_help = ("a few-minute budget: 10 short 128x96 scenes if --root holds no dataset, 2 epochs, all scenes, "
                  "64x48 input")  # fmt: skip
    description = (
        "Experiment 2 of the FogDrive paper: does defogging before detection beat training on fog?\n\n"
        "Trains fog-gym's 2D detector (CenterNet, pure PyTorch) on clean frames and on each fog level of the front and "
        "left cameras, trains AOD-Net on (clean, fog) pairs, and compares pipelines A (clean→clean), B (clean→fog), "
        "C (dehazer → clean-trained detector: DCP, AOD-Net, the Koschmieder oracle) and D (fog→fog, one detector per "
        "level). Writes exp2.md (detection and image-quality tables), exp2.png, results.json, models/ and "
        "TensorBoard logs. Run again into the same --out to resume.\n\n"
        "fog-gym exp2 --root out/fogdrive --out out/exp2                 # an existing dataset\n"
        "fog-gym exp2 --generate 40 --root out/fogdrive --out out/exp2   # generate one first\n"
        "fog-gym exp2 --smoke --root out/exp2_smoke --out out/exp2_smoke")

    def __init__(self, root: str | Path, config: Exp2Config | None = None, generate: int = 0, seconds: float = 10.0,
                 resolution: tuple[int, int] = (640, 480), gen_workers: int = 1) -> None:  # fmt: skip
        super().__init__(root, config or Exp2Config(), generate, seconds, gen_workers, resolution=tuple(resolution))
        self.scenes: dict[str, list[str]] | None = None
        self.images: dict[str, int] = {}

    def _chosen(self, ds: Any) -> dict[str, list[str]]:
        c = self.config
        return {s: choose_scenes(ds.splits[s], getattr(c, f"{s}_fraction"), c.seed + i)
                for i, s in enumerate(("train", "val", "test"))}  # fmt: skip

    def _frames(self, ds: Any, split: str) -> list:
        from fog_gym.experiments.defog.data import frames

        chosen = self.scenes or self._chosen(ds)
        every = self.config.test_every if split == "test" else self.config.every
        return frames(ds, chosen[split], every, self.config.cameras)

    def prepare(self, log: Callable[[str], None], progress: bool) -> dict[str, Any]:
        ds = self.open_dataset(log, progress)
        splits = ds.splits or {}
        if not all(splits.get(s) for s in ("train", "val", "test")):
            raise ValueError(f"{self.root}: Experiment 2 needs train, val and test scenes in index/splits.json")
        missing = [c for cam in self.config.cameras
                   for c in (cam, f"{cam}_BBOX", f"{cam}_DEPTH", *(channel(cam, lv) for lv in LEVELS))
                   if c not in ds.list_channels()]  # fmt: skip
        if missing:
            raise ValueError(f"{self.root}: Experiment 2 needs the camera channels {missing} (generate with --modality full)")
        self.scenes = self._chosen(ds)
        self.images = {s: len(self._frames(ds, s)) for s in ("train", "val", "test")}
        return {"scenes": self.scenes}

    def units(self, seeds: Sequence[int]) -> list[Unit]:
        train = [Unit("train", f"detector_{lv}_s{s}", s, {"model": "detector", "level": lv})
                 for s in seeds for lv in ("clean", *LEVELS)]  # fmt: skip
        train += [Unit("train", f"aodnet_s{s}", s, {"model": "aodnet"}) for s in seeds]
        return train + [Unit("evaluate", f"pipelines_s{s}", s) for s in seeds]

    def artefacts(self, unit: Unit) -> list[str]:
        return [f"models/{unit.key}.pt"] if unit.stage == "train" else []

    def run_unit(self, unit: Unit, out: Path, progress: bool) -> dict[str, Any]:
        import torch

        from fog_gym.dataset.access import FogDrive
        from fog_gym.experiments.runner import atomic_path

        ds, c, device = FogDrive(self.root), self.config, torch_device(self.config.device)
        if unit.stage == "evaluate":
            return self._evaluate(ds, unit.seed, out, device, progress)
        train_f = self._frames(ds, "train")
        if unit.params["model"] == "aodnet":
            from fog_gym.experiments.defog.train import train_aodnet_pairs

            model, summary = train_aodnet_pairs(ds, train_f, c, unit.seed, device, progress)
        else:
            from fog_gym.experiments.defog.data import eval_set
            from fog_gym.experiments.defog.train import ImageSet, train_detector

            level, size = unit.params["level"], tuple(c.input_size)
            val = eval_set(ds, self._frames(ds, "val"), level, size, min_height=c.min_height)
            data = ImageSet(ds, train_f, level, size, augment=True, seed=unit.seed, hsv=c.hsv)
            model, summary = train_detector(data, *val, c, unit.seed, device, unit.key, out / "tb" / unit.key, progress)
        with atomic_path(out / "models" / f"{unit.key}.pt") as tmp:
            torch.save(model.state_dict(), tmp)
        return summary

    def _evaluate(self, ds: Any, seed: int, out: Path, device: Any, progress: bool) -> dict[str, Any]:
        import torch

        from fog_gym.experiments.defog.dehazers import dehazers
        from fog_gym.experiments.defog.evaluate import evaluate_pipelines
        from fog_gym.experiments.defog.model import CenterNet2D
        from fog_gym.perception.aodnet import AODNet

        def load(model: torch.nn.Module, key: str) -> torch.nn.Module:
            model.load_state_dict(torch.load(out / "models" / f"{key}.pt", map_location=device))
            return model.to(device)

        width = self.config.width
        models = {lv: load(CenterNet2D(width=width), f"detector_{lv}_s{seed}") for lv in ("clean", *LEVELS)}
        aod = load(AODNet(), f"aodnet_s{seed}")
        clean = models.pop("clean")
        return evaluate_pipelines(ds, self._frames(ds, "test"), clean, models, dehazers(ds, aod), self.config, device,
                                  progress)  # fmt: skip

    def describe(self, unit: Unit, result: dict[str, Any]) -> str:
        if unit.stage == "evaluate":
            det = result["detection"]
            return "mAP@0.5 at dense fog: " + ", ".join(f"{k} {det[k]['dense']['mAP50']:.3f}" for k in det if k != "A")
        if unit.params["model"] == "aodnet":
            return f"AOD-Net: {result['pairs']} pairs, final loss {result['losses'][-1]:.4f}"
        return f"{result['images']} images, val mAP@0.5 {result['val_mAP50']:.3f} at epoch {result['best_epoch']}"

    def report(self, records: dict[str, dict[str, Any]], out: Path, seeds: Sequence[int]) -> Report:
        from fog_gym.experiments.defog import report

        det_cells: dict[str, Any] = {}
        iq_cells: dict[str, Any] = {}
        for r in records.values():
            if r["stage"] != "evaluate":
                continue
            for p, levels in r["result"]["detection"].items():
                for lv, cell in levels.items():
                    det_cells.setdefault(p, {}).setdefault(lv, {})[r["seed"]] = cell
            for lv, methods in r["result"]["image_quality"].items():
                for m, cell in methods.items():
                    iq_cells.setdefault(lv, {}).setdefault(m, {})[r["seed"]] = cell
        detection, image_quality = aggregate(det_cells), aggregate(iq_cells)
        manifest = json.loads((out / "study.json").read_text())
        data = {"config": self.config.settings(), "device": str(torch_device(self.config.device)), "seeds": list(seeds),
                "scenes": manifest["data"]["scenes"], "images": self.images,
                "detectors": {k: r["result"] for k, r in records.items() if r["stage"] == "train"},
                "detection": detection, "image_quality": image_quality}  # fmt: skip
        return Report(report.markdown(detection, image_quality, len(seeds)), data, "exp2.md", "results.json",
                      {"exp2.png": lambda p: report.figure(detection, image_quality, p)})

    @classmethod
    def add_arguments(cls, p: argparse.ArgumentParser) -> None:
        cls.add_common_arguments(p, "with cameras and train/val/test splits", "detector", 2e-3)
        p.add_argument("--resolution", type=size_arg, default=(640, 480),
                       help="camera resolution WxH when generating (default 640x480)")
        p.add_argument("--input-size", type=size_arg, default=(320, 240),
                       help="detector input WxH, multiples of 16 (default 320x240)")
        p.add_argument("--train-fraction", type=float, default=0.15, help="share of train scenes used (paper 0.15)")
        p.add_argument("--val-fraction", type=float, default=0.2, help="share of val scenes used (paper 0.2)")
        p.add_argument("--test-fraction", type=float, default=0.2, help="share of test scenes used (paper 0.2)")
        p.add_argument("--aod-epochs", type=int, default=10, help="AOD-Net training epochs (default 10)")
        p.add_argument("--aod-pairs", type=int, default=600, help="AOD-Net (clean, fog) training crops (default 600)")
        p.add_argument("--cameras", nargs="+", default=list(CAMERAS), help="cameras (default front and left)")
        p.add_argument("--min-height", type=float, default=0.0,
                       help="evaluate only boxes at least this many pixels high at the detector input; lower ones are "
                            "ignore regions (default 0: every box, as the paper)")
        p.add_argument("--hsv", type=float, nargs=3, default=[0.015, 0.7, 0.4], metavar=("H", "S", "V"),
                       help="colour jitter of the detectors' training images, gains of hue, saturation, value "
                            "(default Ultralytics' 0.015 0.7 0.4; 0 0 0 = flips only)")

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> Exp2Study:
        if args.smoke:
            cls.smoke_dataset(args)
            args.seconds, args.resolution, args.input_size, args.epochs = 0.6, (128, 96), (64, 48), 2
            args.train_fraction = args.val_fraction = args.test_fraction = 1.0
            args.aod_epochs, args.aod_pairs, args.every, args.test_every = 1, 32, 1, 1
        config = Exp2Config(epochs=args.epochs, batch_size=args.batch_size, lr=args.lr, every=args.every,
                            test_every=args.test_every, eval_every=args.eval_every, input_size=args.input_size,
                            train_fraction=args.train_fraction, val_fraction=args.val_fraction,
                            test_fraction=args.test_fraction, aod_epochs=args.aod_epochs, aod_pairs=args.aod_pairs,
                            cameras=tuple(args.cameras), seed=args.seed, device=args.device,
                            min_height=args.min_height, hsv=tuple(args.hsv))  # fmt: skip
        return cls(args.root, config, args.generate, args.seconds, args.resolution, args.gen_workers)


def run_experiment2(root: str | Path, out: str | Path, config: Exp2Config | None = None, progress: bool = True,
                    log: Callable[[str], None] | None = None, seeds: int = 1) -> dict[str, Any]:  # fmt: skip
    """Run pipelines A–D on the dataset at ``root`` into ``out`` (see the module docstring); returns
    ``results.json``'s content. Trained models are kept; other settings into the same ``out`` are refused."""
    return run(Exp2Study(root, config), out, seeds=seeds, progress=progress, log=log).data

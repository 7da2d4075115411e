"""Experiment 2 as a study of the runner: settings (:class:`Exp2Config`), data (the dataset, generated first on
request, and its chosen scenes), units — per seed, the YOLO-style detector trained on clean frames and one on each
fog level, AOD-Net and DehazeFormer on (clean, fog) pairs, then one evaluation of every pipeline with every image's
detections kept — and the report (tables with 95 % CIs across seeds, paired bootstrap comparisons, a verdict per
claim, the rank correlation of image quality with detection, figures).

``--seeds K`` trains every model with seeds ``seed, seed + 1, …`` (weights, shuffling, augmentation, the dehazers'
crops); the scenes come from ``--seed`` alone, so every seed sees the same frames.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from fog_gym.dataset.digest import content_digest
from fog_gym.experiments.dataset_study import DatasetStudy
from fog_gym.experiments.defog.data import CAMERAS, LEVELS, channel, choose_scenes
from fog_gym.experiments.runner import Report, Unit, run, size_arg, torch_device


@dataclass(frozen=True)
class Exp2Config:
    """Budget, data and network settings; the defaults are the CPU configuration, :meth:`gpu` the GPU one.

    The detector (:mod:`~fog_gym.experiments.defog.yolo`) trains with AdamW, a one-cycle learning rate and an EMA
    of its weights, keeping its best validation epoch. ``every`` / ``test_every``: every n-th sample of a scene
    (samples are 0.1 s apart). The dehazers train on ``aod_pairs`` random 256 × 256 (clean, fog) crops of the train
    frames: AOD-Net for ``aod_epochs`` epochs, DehazeFormer (``dehazeformer`` size) for ``dehazeformer_steps``
    steps of ``dehazeformer_crop`` crops."""

    #: 4: the three-seed study within its 8-hour budget on two cores (5 epochs took 8.4 h: docs/experiments/exp2.md)
    epochs: int = 4
    batch_size: int = 8
    lr: float = 2e-3
    weight_decay: float = 0.01
    every: int = 2
    test_every: int = 8
    eval_every: int = 1
    input_size: tuple[int, int] = (640, 480)  # detector input (W, H)
    width: int = 16
    depth: int = 1
    train_fraction: float = 0.5
    val_fraction: float = 0.2
    test_fraction: float = 1.0
    aod_epochs: int = 10
    aod_pairs: int = 800
    dehazeformer: str = "T"
    dehazeformer_steps: int = 600
    dehazeformer_crop: int = 128
    cameras: tuple[str, ...] = CAMERAS
    seed: int = 0
    device: str = "auto"
    precision: str = "auto"
    workers: int = 0
    threshold: float = 0.001  # detections kept for COCO evaluation (the paper's validation confidence)
    #: Ground-truth boxes lower than this many pixels *at the detector input* are ignore regions in evaluation
    #: (COCO crowd: neither hit nor miss); 0 evaluates every box, as the paper does.
    min_height: float = 0.0
    #: Photometric augmentation of the detectors' training images: random hue, saturation and value gains within
    #: ±(h, s, v) — Ultralytics' defaults (0.015, 0.7, 0.4), part of the paper's "default augmentations"; zeros
    #: switch it off (horizontal flips always apply).
    hsv: tuple[float, float, float] = (0.015, 0.7, 0.4)
    profile: str = "cpu"

    def __post_init__(self) -> None:
        for name in ("epochs", "batch_size", "every", "test_every", "eval_every", "width", "depth", "aod_epochs",
                     "aod_pairs", "dehazeformer_steps", "dehazeformer_crop"):  # fmt: skip
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ValueError(f"{name} must be a positive integer, got {v!r}")
        object.__setattr__(self, "input_size", tuple(self.input_size))
        object.__setattr__(self, "cameras", tuple(self.cameras))
        w, h = self.input_size
        if w % 32 or h % 32 or w < 32 or h < 32:
            raise ValueError(f"input_size must be (W, H), both multiples of 32 and >= 32, got {self.input_size}")
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
        from fog_gym.dehaze.dehazeformer import SIZES

        if self.dehazeformer not in SIZES:
            raise ValueError(f"dehazeformer must be one of {tuple(SIZES)}, got {self.dehazeformer!r}")
        if self.precision not in ("auto", "bf16", "fp32"):
            raise ValueError(f"precision must be auto, bf16 or fp32, got {self.precision!r}")
        if self.profile not in ("cpu", "gpu"):
            raise ValueError(f"profile must be cpu or gpu, got {self.profile!r}")

    @classmethod
    def gpu(cls, **overrides: Any) -> Exp2Config:
        """The GPU configuration: the detector twice as wide and deep, 60 epochs, batch 16, DehazeFormer-S trained
        5× longer on twice the pairs."""
        base = {"epochs": 60, "batch_size": 16, "width": 32, "depth": 2, "dehazeformer": "S", "dehazeformer_steps": 6000,
                "dehazeformer_crop": 256, "aod_pairs": 1600, "eval_every": 5, "profile": "gpu"}  # fmt: skip
        return cls(**{**base, **overrides})

    @property
    def yolo(self) -> Any:
        from fog_gym.experiments.defog.yolo import YoloConfig

        return YoloConfig(width=self.width, depth=self.depth)

    def settings(self) -> dict[str, Any]:
        """What a trained model depends on, as it reads back from JSON (not the device or workers)."""
        return json.loads(json.dumps({k: v for k, v in asdict(self).items() if k not in ("device", "workers")}))


class Exp2Study(DatasetStudy):
    """Experiment 2 on the dataset at ``root`` (generated first when ``generate`` scenes are asked for)."""

    name = "exp2"
    command = "fog-gym exp2"
    default_out = Path("out/exp2")
    smoke_help = ("a one-minute budget: 10 short 128x96 scenes if --root holds no dataset, 1 epoch, toy widths, "
                  "all scenes, 64x64 input")  # fmt: skip
    description = (
        "Experiment 2 of the FogDrive paper: does defogging before detection beat training on fog?\n\n"
        "Trains fog-gym's YOLO-style detector (pure PyTorch: CSP backbone, PAN neck, anchor-free decoupled head, "
        "task-aligned assignment, CIoU + DFL) on clean frames and on each fog level of the front and left cameras, "
        "trains AOD-Net and DehazeFormer-T on (clean, fog) pairs, and compares pipelines A (clean→clean), B "
        "(clean→fog), C (dehazer → clean-trained detector: DCP, AOD-Net, DehazeFormer, the Koschmieder oracle) and "
        "D (fog→fog, one detector per level) on the same test images. Writes exp2.md (a verdict per claim from "
        "paired bootstrap comparisons, detection and image-quality tables with 95 % CIs across seeds, the rank "
        "correlation of PSNR / SSIM with mAP), figures, results.json, models/, records/ and TensorBoard logs. Run "
        "again into the same --out to resume.\n\n"
        "fog-gym generate --root out/cams --scenes 160 --seconds 10 --resolution 640x480 --modality cameras \\\n"
        "    --cameras CAM_FRONT CAM_LEFT --workers 2\n"
        "fog-gym exp2 --root out/cams --out out/exp2 --seeds 3          # CPU configuration\n"
        "fog-gym exp2 --root out/cams --out out/exp2_gpu --gpu --seeds 3   # GPU configuration\n"
        "fog-gym exp2 --smoke --root out/exp2_smoke --out out/exp2_smoke")

    def __init__(self, root: str | Path, config: Exp2Config | None = None, generate: int = 0, seconds: float = 10.0,
                 resolution: tuple[int, int] = (640, 480), gen_workers: int = 1) -> None:  # fmt: skip
        config = config or Exp2Config()
        super().__init__(root, config, generate, seconds, gen_workers, resolution=tuple(resolution),
                         modality="cameras", cameras=tuple(config.cameras))  # fmt: skip
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
            raise ValueError(f"{self.root}: Experiment 2 needs the camera channels {missing} (generate with --modality "
                             "cameras or full)")  # fmt: skip
        self.scenes = self._chosen(ds)
        self.images = {s: len(self._frames(ds, s)) for s in ("train", "val", "test")}
        empty = [s for s, n in self.images.items() if n == 0]
        if empty:
            raise ValueError(f"the {', '.join(empty)} split has no frames")
        return {"scenes": self.scenes, "images": self.images,
                "digest": content_digest(ds, [n for names in self.scenes.values() for n in names])}

    def units(self, seeds: Sequence[int]) -> list[Unit]:
        """The dehazers (minutes) before the detectors (half an hour each): a run cut short by its
        machine's end loses the long unit it was in, not the short ones queued behind it. Every unit seeds its own
        generators, so the order changes no result."""
        train = [Unit("train", f"{m}_s{s}", s, {"model": m}) for s in seeds for m in ("aodnet", "dehazeformer")]
        train += [Unit("train", f"detector_{lv}_s{s}", s, {"model": "detector", "level": lv})
                  for s in seeds for lv in ("clean", *LEVELS)]  # fmt: skip
        return train + [Unit("evaluate", f"pipelines_s{s}", s) for s in seeds]

    def artefacts(self, unit: Unit) -> list[str]:
        return [f"models/{unit.key}.pt"] if unit.stage == "train" else [f"records/{unit.key}.npz"]

    def run_unit(self, unit: Unit, out: Path, progress: bool) -> dict[str, Any]:
        import torch

        from fog_gym.dataset.access import FogDrive
        from fog_gym.experiments.runner import EpochCheckpoint, atomic_path

        ds, c, device = FogDrive(self.root), self.config, torch_device(self.config.device)
        if unit.stage == "evaluate":
            return self._evaluate(ds, unit, out, device, progress)
        train_f = self._frames(ds, "train")
        model_kind = unit.params["model"]
        if model_kind == "aodnet":
            from fog_gym.experiments.defog.train import train_aodnet_pairs

            model, summary = train_aodnet_pairs(ds, train_f, c, unit.seed, device, progress)
        elif model_kind == "dehazeformer":
            from fog_gym.experiments.defog.train import train_dehazeformer_pairs

            model, summary = train_dehazeformer_pairs(ds, train_f, c, unit.seed, device, progress)
        else:
            from fog_gym.experiments.defog.data import eval_set
            from fog_gym.experiments.defog.train import DetectionSet, train_detector

            level, size = unit.params["level"], tuple(c.input_size)
            val = eval_set(ds, self._frames(ds, "val"), level, size, min_height=c.min_height)
            data = DetectionSet(ds, train_f, level, size, augment=True, seed=unit.seed, hsv=c.hsv)
            model, summary = train_detector(data, *val, c, unit.seed, device, unit.key, out / "tb" / unit.key, progress,
                                            checkpoint=out / "checkpoints" / f"{unit.key}.pt")  # fmt: skip
        with atomic_path(out / "models" / f"{unit.key}.pt") as tmp:
            torch.save(model.state_dict(), tmp)
        EpochCheckpoint(out / "checkpoints" / f"{unit.key}.pt", {}).clear()
        return summary

    def load_models(self, out: Path, seed: int, device: Any) -> tuple[Any, dict[str, Any], Any, Any]:
        """The seed's clean detector, fog detectors per level, AOD-Net and DehazeFormer, from ``out/models``."""
        import torch

        from fog_gym.dehaze.aodnet import AODNet
        from fog_gym.dehaze.dehazeformer import DehazeFormer
        from fog_gym.experiments.defog.yolo import YoloDetector

        def load(model: torch.nn.Module, key: str) -> torch.nn.Module:
            model.load_state_dict(torch.load(out / "models" / f"{key}.pt", map_location=device))
            return model.to(device).to(memory_format=torch.channels_last).eval()

        dets = {lv: load(YoloDetector(self.config.yolo), f"detector_{lv}_s{seed}") for lv in ("clean", *LEVELS)}
        aod = load(AODNet(), f"aodnet_s{seed}")
        df = load(DehazeFormer(self.config.dehazeformer), f"dehazeformer_s{seed}")
        return dets.pop("clean"), dets, aod, df

    def _evaluate(self, ds: Any, unit: Unit, out: Path, device: Any, progress: bool) -> dict[str, Any]:
        from fog_gym.experiments.defog.dehazers import dehazers
        from fog_gym.experiments.defog.evaluate import evaluate_pipelines
        from fog_gym.experiments.detection3d.train import resolve_precision

        clean, fog, aod, df = self.load_models(out, unit.seed, device)
        fns = dehazers(ds, aod, df, resolve_precision(self.config.precision, device))
        return evaluate_pipelines(ds, self._frames(ds, "test"), clean, fog, fns, self.config, device, progress,
                                  keep=out / "records" / f"{unit.key}.npz")  # fmt: skip

    def describe(self, unit: Unit, result: dict[str, Any]) -> str:
        if unit.stage == "evaluate":
            det = result["detection"]
            return (f"A {det['A']['clean']['mAP50']:.3f}; mAP@0.5 at dense fog: "
                    + ", ".join(f"{k} {det[k]['dense']['mAP50']:.3f}" for k in det if k != "A"))  # fmt: skip
        if unit.params["model"] in ("aodnet", "dehazeformer"):
            return f"{unit.params['model']}: {result['pairs']} pairs, final loss {result['losses'][-1]:.4f}"
        return f"{result['images']} images, val mAP@0.5 {result['val_mAP50']:.3f} at epoch {result['best_epoch']}"

    def report(self, records: dict[str, dict[str, Any]], out: Path, seeds: Sequence[int]) -> Report:
        from fog_gym.experiments.defog import report

        manifest = json.loads((out / "study.json").read_text())
        return report.build(self, records, out, list(seeds), manifest["data"], str(torch_device(self.config.device)))

    @classmethod
    def add_arguments(cls, p: argparse.ArgumentParser) -> None:
        cls.add_common_arguments(p, "with cameras and train/val/test splits", "detector", 2e-3)
        cpu, gpu = Exp2Config(), Exp2Config.gpu()
        for action in p._actions:  # the configuration decides these defaults (CPU or GPU)
            if action.dest in ("epochs", "batch_size", "every", "test_every", "eval_every"):
                action.default = None
                action.help = {"epochs": f"training epochs per detector (CPU {cpu.epochs}, GPU {gpu.epochs})",
                               "batch_size": f"batch size (CPU {cpu.batch_size}, GPU {gpu.batch_size})",
                               "every": "use every n-th training / validation sample of a scene (default 2)",
                               "test_every": "use every n-th test sample (default 8)",
                               "eval_every": "evaluate on the validation set every n-th epoch and the last (CPU 1, "
                                             "GPU 5)"}[action.dest]  # fmt: skip
        p.add_argument("--gpu", action="store_true",
                       help="the GPU configuration: detector width 32 and depth 2, 60 epochs, batch 16, DehazeFormer-S "
                            "trained longer (explicit options still win)")
        p.add_argument("--resolution", type=size_arg, default=(640, 480),
                       help="camera resolution WxH when generating (default 640x480)")
        p.add_argument("--input-size", type=size_arg, default=None,
                       help="detector input WxH, multiples of 32 (default 640x480: the frames themselves)")
        p.add_argument("--width", type=int, default=None, help="detector base width (CPU 16, GPU 32)")
        p.add_argument("--depth", type=int, default=None, help="bottlenecks per CSP block (CPU 1, GPU 2)")
        p.add_argument("--train-fraction", type=float, default=0.5, help="share of train scenes used (paper 0.15)")
        p.add_argument("--val-fraction", type=float, default=0.2, help="share of val scenes used (paper 0.2)")
        p.add_argument("--test-fraction", type=float, default=1.0, help="share of test scenes used (paper 0.2)")
        p.add_argument("--aod-epochs", type=int, default=10, help="AOD-Net training epochs (default 10)")
        p.add_argument("--aod-pairs", type=int, default=None, help="(clean, fog) training crops of the dehazers (CPU 800)")
        p.add_argument("--dehazeformer", choices=("T", "S"), default=None, help="DehazeFormer size (CPU T, GPU S)")
        p.add_argument("--dehazeformer-steps", type=int, default=None, help="DehazeFormer training steps (CPU 600, GPU 6000)")
        p.add_argument("--cameras", nargs="+", default=list(CAMERAS), help="cameras (default front and left)")
        p.add_argument("--min-height", type=float, default=0.0,
                       help="evaluate only boxes at least this many pixels high at the detector input; lower ones are "
                            "ignore regions (default 0: every box, as the paper)")
        p.add_argument("--hsv", type=float, nargs=3, default=[0.015, 0.7, 0.4], metavar=("H", "S", "V"),
                       help="colour jitter of the detectors' training images, gains of hue, saturation, value "
                            "(default Ultralytics' 0.015 0.7 0.4; 0 0 0 = flips only)")
        p.add_argument("--precision", choices=("auto", "bf16", "fp32"), default="auto",
                       help="bf16 autocast where the device computes it natively (auto), or force one")
        p.add_argument("--workers", type=int, default=0, help="DataLoader worker processes (default 0)")

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> Exp2Study:
        if args.smoke:
            cls.smoke_dataset(args)
            args.seconds, args.resolution, args.input_size, args.epochs = 0.6, (128, 96), (64, 64), 1
            args.train_fraction = args.val_fraction = args.test_fraction = 1.0
            args.aod_epochs, args.aod_pairs, args.every, args.test_every = 1, 16, 1, 1
            args.width, args.depth, args.dehazeformer_steps = 8, 1, 2
        options = {"epochs": args.epochs, "batch_size": args.batch_size, "lr": args.lr, "every": args.every,
                   "test_every": args.test_every, "eval_every": args.eval_every, "input_size": args.input_size,
                   "train_fraction": args.train_fraction, "val_fraction": args.val_fraction,
                   "test_fraction": args.test_fraction, "aod_epochs": args.aod_epochs, "aod_pairs": args.aod_pairs,
                   "dehazeformer": args.dehazeformer, "dehazeformer_steps": args.dehazeformer_steps,
                   "cameras": tuple(args.cameras), "seed": args.seed, "device": args.device, "min_height": args.min_height,
                   "hsv": tuple(args.hsv), "width": args.width, "depth": args.depth, "precision": args.precision,
                   "workers": args.workers}  # fmt: skip
        options = {k: v for k, v in options.items() if v is not None}
        config = Exp2Config.gpu(**options) if args.gpu else Exp2Config(**options)
        return cls(args.root, config, args.generate, args.seconds, args.resolution, args.gen_workers)


def run_experiment2(root: str | Path, out: str | Path, config: Exp2Config | None = None, progress: bool = True,
                    log: Callable[[str], None] | None = None, seeds: int = 1) -> dict[str, Any]:  # fmt: skip
    """Run pipelines A–D on the dataset at ``root`` into ``out`` (see the module docstring); returns
    ``results.json``'s content. Trained models are kept; other settings into the same ``out`` are refused."""
    return run(Exp2Study(root, config), out, seeds=seeds, progress=progress, log=log).data

"""Seed noise of Experiment 2's clean detector: retrain it with another seed on a finished run's scenes.

Reads ``results.json`` of a finished ``examples/exp2_defog_vs_fog.py`` run (its settings and its train / val / test
scenes), trains the clean detector again with ``--seed`` (weights, shuffling and augmentation; same scenes and
settings otherwise) and evaluates pipelines A (clean test frames) and B (each fog level), printing one Markdown row
per input and writing them as JSON. No timing, no assertion: a measurement of training noise.

    python scripts/exp2_seed_check.py --root out/set60 --run out/exp2 --seed 1 --json out/exp2/seed1.json
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], epilog=__doc__.split("\n\n", 1)[1],
                                formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip
    p.add_argument("--root", type=Path, required=True, help="the dataset root the run used")
    p.add_argument("--run", type=Path, required=True, help="output folder of the finished run (its results.json)")
    p.add_argument("--seed", type=int, required=True, help="training seed of the retrained clean detector")
    p.add_argument("--json", type=Path, default=None, help="write the metrics here")
    args = p.parse_args(argv)
    results_path = args.run / "results.json"
    if not results_path.is_file():
        p.error(f"{results_path} not found: run examples/exp2_defog_vs_fog.py first")

    import torch

    from fog_gym.dataset.access import FogDrive
    from fog_gym.experiments.defog.experiment import LEVELS, Exp2Config, ImageSet, _device, _eval_set, detect, frames, train_detector
    from fog_gym.metrics.detection2d import evaluate_coco

    run = json.loads(results_path.read_text())
    settings = {k: tuple(v) if isinstance(v, list) else v for k, v in run["config"].items()}
    config = Exp2Config(**{**settings, "seed": args.seed})
    ds, size, device = FogDrive(args.root), config.input_size, _device(config.device)
    train_f, val_f, test_f = (frames(ds, run["scenes"][s], e, config.cameras)
                              for s, e in (("train", config.every), ("val", config.every), ("test", config.test_every)))  # fmt: skip
    torch.manual_seed(args.seed)
    vi, vg, vs = _eval_set(ds, val_f, "clean", size, min_height=config.min_height)
    model, summary = train_detector(ImageSet(ds, train_f, "clean", size, augment=True, seed=args.seed, hsv=config.hsv),
                                    vi, vg, vs, config, device, f"clean-seed{args.seed}")  # fmt: skip
    out = {"seed": args.seed, "summary": summary}
    print("| input | mAP@0.5 | mAP@.5:.95 | P | R | car AP@0.5 |\n|---|---|---|---|---|---|")
    for level in ("clean", *LEVELS):
        imgs, gts, scales = _eval_set(ds, test_f, level, size, min_height=config.min_height)
        r = evaluate_coco(gts, detect(model, imgs, scales, device, config.threshold))
        out[level] = {k: r[k] for k in ("mAP50", "mAP50_95", "precision", "recall")} | {"car": r["AP50"].get(0)}
        m = out[level]
        print(f"| {level} | {m['mAP50']:.3f} | {m['mAP50_95']:.3f} | {m['precision']:.3f} | {m['recall']:.3f} | {m['car']:.3f} |")
    if args.json:
        args.json.write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()

"""Experiment 2 of the FogDrive paper from Python, at a smoke budget: a small 128x96 set, every pipeline (clean,
fogged, dehazed by DCP / AOD-Net / DehazeFormer / the oracle, trained on fog), one seed (a few minutes on 2 cores). Writes exp2.md,
exp2.png and results.json to --out. The full command, with every option: ``fog-gym exp2 --help``.
"""

import argparse
from pathlib import Path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("out/exp2_example"), help="output folder (default out/exp2_example)")
    parser.add_argument("--seeds", type=int, default=1, help="training seeds per pipeline (default 1)")
    args = parser.parse_args()

    from fog_gym.experiments.runner import run

    print(run(study(args.out), args.out, seeds=args.seeds).markdown)


def study(out: Path):
    """The study at the example's budget, its data under ``out/cameras`` (generated on first use)."""
    from fog_gym.experiments.defog.study import Exp2Config, Exp2Study

    data = out / "cameras"
    config = Exp2Config(epochs=2, input_size=(128, 96), every=1, test_every=1, train_fraction=1.0, val_fraction=1.0,
                        test_fraction=1.0, aod_epochs=1, aod_pairs=32, width=8, dehazeformer_steps=20,
                        dehazeformer_crop=64)  # fmt: skip
    return Exp2Study(data, config, generate=0 if (data / "index").exists() else 10, seconds=0.6, resolution=(128, 96))


if __name__ == "__main__":
    main()

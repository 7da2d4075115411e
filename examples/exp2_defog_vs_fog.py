"""Experiment 2 of the FogDrive paper: does defogging before detection beat training on fog?

Trains fog-gym's 2D detector (CenterNet, pure PyTorch) on clean frames and on each fog level of the front and left
cameras, trains AOD-Net on (clean, fog) pairs, and compares pipelines A (clean→clean), B (clean→fog), C (dehazer →
clean-trained detector: DCP, AOD-Net, the Koschmieder oracle) and D (fog→fog, one detector per level). Writes
``exp2.md`` (detection and image-quality tables), ``exp2.png``, ``results.json`` and TensorBoard logs.

    python examples/exp2_defog_vs_fog.py --root out/fogdrive --out out/exp2                 # an existing dataset
    python examples/exp2_defog_vs_fog.py --generate 40 --root out/fogdrive --out out/exp2   # generate one first
    python examples/exp2_defog_vs_fog.py --smoke --root out/exp2_smoke --out out/exp2_smoke
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(prog="exp2_defog_vs_fog.py", description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__.split("\n\n", 2)[2])  # fmt: skip
    p.add_argument("--root", type=Path, required=True, help="FogDrive dataset root with cameras and train/val/test splits")
    p.add_argument("--out", type=Path, default=Path("out/exp2"), help="output folder (default out/exp2)")
    p.add_argument("--generate", type=int, default=0, metavar="SCENES",
                   help="first generate a dataset of this many scenes into --root (must be empty)")
    p.add_argument("--seconds", type=float, default=10.0, help="scene length when generating (default 10 s)")
    p.add_argument("--resolution", default="640x480", help="camera resolution when generating (default 640x480)")
    p.add_argument("--gen-workers", type=int, default=1, help="worker processes when generating (default 1)")
    p.add_argument("--epochs", type=int, default=20, help="training epochs per detector (default 20)")
    p.add_argument("--batch-size", type=int, default=16, help="batch size (default 16)")
    p.add_argument("--lr", type=float, default=2e-3, help="peak learning rate of the one-cycle schedule (default 2e-3)")
    p.add_argument("--input-size", default="320x240", help="detector input WxH, multiples of 16 (default 320x240)")
    p.add_argument("--every", type=int, default=2, help="use every n-th train/val sample of a scene (default 2)")
    p.add_argument("--test-every", type=int, default=2, help="use every n-th test sample (default 2)")
    p.add_argument("--eval-every", type=int, default=1, help="validate after every n-th epoch and the last (default 1)")
    p.add_argument("--train-fraction", type=float, default=0.15, help="share of train scenes used (paper 0.15)")
    p.add_argument("--val-fraction", type=float, default=0.2, help="share of val scenes used (paper 0.2)")
    p.add_argument("--test-fraction", type=float, default=0.2, help="share of test scenes used (paper 0.2)")
    p.add_argument("--aod-epochs", type=int, default=10, help="AOD-Net training epochs (default 10)")
    p.add_argument("--aod-pairs", type=int, default=600, help="AOD-Net (clean, fog) training crops (default 600)")
    p.add_argument("--cameras", nargs="+", default=["CAM_FRONT", "CAM_LEFT"], help="cameras (default front and left)")
    p.add_argument("--min-height", type=float, default=0.0,
                   help="evaluate only boxes at least this many pixels high at the detector input; lower ones are "
                        "ignore regions (default 0: every box, as the paper)")
    p.add_argument("--hsv", type=float, nargs=3, default=[0.015, 0.7, 0.4], metavar=("H", "S", "V"),
                   help="colour jitter of the detectors' training images, gains of hue, saturation, value "
                        "(default Ultralytics' 0.015 0.7 0.4; 0 0 0 = flips only)")
    p.add_argument("--device", default="auto", help="torch device: auto (GPU when present), cpu, cuda")
    p.add_argument("--seed", type=int, default=0, help="seed of scene choice, weights and augmentation (default 0)")
    p.add_argument("--smoke", action="store_true",
                   help="a few-minute budget: 10 short 128x96 scenes if --root is empty, 2 epochs, all scenes, 64x48 input")
    args = p.parse_args(argv)

    from fog_gym.cli import _resolution
    from fog_gym.experiments.defog.experiment import Exp2Config, run_experiment2

    def size(text: str, name: str) -> tuple[int, int]:
        try:
            return _resolution(text)
        except (argparse.ArgumentTypeError, ValueError) as e:
            p.error(f"{name}: {e}")

    if args.smoke:
        args.generate = args.generate or (0 if (args.root / "index").exists() else 10)
        args.seconds, args.resolution, args.input_size, args.epochs = 0.6, "128x96", "64x48", 2
        args.train_fraction = args.val_fraction = args.test_fraction = 1.0
        args.aod_epochs, args.aod_pairs, args.every, args.test_every = 1, 32, 1, 1
    try:
        config = Exp2Config(epochs=args.epochs, batch_size=args.batch_size, lr=args.lr, every=args.every,
                            test_every=args.test_every, eval_every=args.eval_every,
                            input_size=size(args.input_size, "--input-size"), train_fraction=args.train_fraction,
                            val_fraction=args.val_fraction, test_fraction=args.test_fraction,
                            aod_epochs=args.aod_epochs, aod_pairs=args.aod_pairs, cameras=tuple(args.cameras),
                            seed=args.seed, device=args.device, min_height=args.min_height,
                            hsv=tuple(args.hsv))  # fmt: skip
    except ValueError as e:
        p.error(str(e))
    if args.generate:
        from fog_gym.generate import generate, plan_scenes

        t0 = time.perf_counter()
        generate(args.root, plan_scenes(args.generate, seed=args.seed, seconds=args.seconds,
                                        resolution=size(args.resolution, "--resolution")), workers=args.gen_workers)  # fmt: skip
        print(f"generated {args.generate} scenes in {time.perf_counter() - t0:.0f} s")
    t0 = time.perf_counter()
    results = run_experiment2(args.root, args.out, config)
    print(f"\n{(args.out / 'exp2.md').read_text()}\nwrote {args.out}/exp2.md, exp2.png, results.json in "
          f"{time.perf_counter() - t0:.0f} s")  # fmt: skip
    return results


if __name__ == "__main__":
    main()

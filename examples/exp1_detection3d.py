"""Experiment 1 of the FogDrive paper: does mixing fog densities at training time make a 3D detector more robust?

Trains fog-gym's BEV detector on the Light, Dense, Mixed-S, Mixed-L (and Clear) subsets of a dataset's train split,
evaluates every epoch on the light / moderate / dense (and clear) test subsets, keeps the best-FDS epoch per cell and
writes ``exp1.md`` (mAP@0.5, Mean TP, ATE, ASE, AOE matrices), ``exp1.png``, ``results.json`` and TensorBoard logs.

    python examples/exp1_detection3d.py --root out/lidar --out out/exp1                # an existing dataset
    python examples/exp1_detection3d.py --generate 40 --root out/lidar --out out/exp1  # generate a LiDAR-only set first
    python examples/exp1_detection3d.py --smoke --root out/exp1_smoke --out out/exp1_smoke
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(prog="exp1_detection3d.py", description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__.split("\n\n", 2)[2])  # fmt: skip
    p.add_argument("--root", type=Path, required=True, help="FogDrive dataset root (with train/test splits)")
    p.add_argument("--out", type=Path, default=Path("out/exp1"), help="output folder (default out/exp1)")
    p.add_argument("--generate", type=int, default=0, metavar="SCENES",
                   help="first generate a LiDAR-only dataset of this many scenes into --root (must be empty)")
    p.add_argument("--seconds", type=float, default=10.0, help="scene length when generating (default 10 s)")
    p.add_argument("--gen-workers", type=int, default=1, help="worker processes when generating (default 1)")
    p.add_argument("--epochs", type=int, default=20, help="training epochs per subset (default 20)")
    p.add_argument("--batch-size", type=int, default=16, help="batch size (default 16)")
    p.add_argument("--lr", type=float, default=1e-3, help="peak learning rate of the one-cycle schedule (default 1e-3)")
    p.add_argument("--every", type=int, default=2, help="use every n-th training sample of a scene (default 2: 5 Hz)")
    p.add_argument("--test-every", type=int, default=2, help="use every n-th test sample (default 2)")
    p.add_argument("--eval-every", type=int, default=1, help="evaluate after every n-th epoch and the last (default 1)")
    p.add_argument("--fraction", type=float, default=0.2, help="share of train scenes per density subset (paper 0.2)")
    p.add_argument("--mixed-fraction", type=float, default=0.08, help="Mixed-S share per density (paper 0.08)")
    p.add_argument("--test-fraction", type=float, default=0.2, help="share of test scenes evaluated (paper 0.2)")
    p.add_argument("--rows", nargs="+", default=["Light", "Dense", "Mixed-S", "Mixed-L", "Clear"],
                   help="training subsets to run (default all five)")
    p.add_argument("--device", default="auto", help="torch device: auto (GPU when present), cpu, cuda")
    p.add_argument("--workers", type=int, default=0, help="DataLoader worker processes (default 0)")
    p.add_argument("--seed", type=int, default=0, help="seed of subsets, weights and augmentation (default 0)")
    p.add_argument("--smoke", action="store_true",
                   help="a few-minute budget: generate 10 short scenes if --root is empty, 2 epochs, rows Light and Mixed-L")
    args = p.parse_args(argv)

    from fog_gym.experiments.detection3d.experiment import Exp1Config, run_experiment1

    if args.smoke:
        args.generate = args.generate or (0 if (args.root / "index").exists() else 10)
        args.seconds, args.epochs, args.rows, args.every, args.test_every = 2.0, 2, ["Light", "Mixed-L"], 2, 2
    try:
        config = Exp1Config(epochs=args.epochs, batch_size=args.batch_size, lr=args.lr, every=args.every,
                            test_every=args.test_every, eval_every=args.eval_every, rows=tuple(args.rows),
                            device=args.device, workers=args.workers, seed=args.seed, fraction=args.fraction,
                            mixed_fraction=args.mixed_fraction, test_fraction=args.test_fraction)  # fmt: skip
    except ValueError as e:
        p.error(str(e))
    if args.generate:
        from fog_gym.generate import generate, plan_scenes

        t0 = time.perf_counter()
        generate(args.root, plan_scenes(args.generate, seed=args.seed, seconds=args.seconds, modality="lidar"),
                 workers=args.gen_workers)  # fmt: skip
        print(f"generated {args.generate} LiDAR-only scenes in {time.perf_counter() - t0:.0f} s")
    t0 = time.perf_counter()
    results = run_experiment1(args.root, args.out, config)
    print(f"\n{(args.out / 'exp1.md').read_text()}\nwrote {args.out}/exp1.md, exp1.png, results.json in "
          f"{time.perf_counter() - t0:.0f} s")  # fmt: skip
    return results


if __name__ == "__main__":
    main()

"""Experiment 1 of the FogDrive paper from Python, at a smoke budget: a small LiDAR-only set, two training subsets,
two seeds (a few minutes on 2 cores). Writes exp1.md, exp1.png and results.json to --out; run it again and it keeps
what is done. The full command, with every option: ``fog-gym exp1 --help``.
"""

import argparse
from pathlib import Path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("out/exp1_example"), help="output folder (default out/exp1_example)")
    parser.add_argument("--seeds", type=int, default=2, help="training seeds per row (default 2)")
    args = parser.parse_args()

    from fog_gym.experiments.runner import run

    print(run(study(args.out), args.out, seeds=args.seeds).markdown)


def study(out: Path):
    """The study at the example's budget, its data under ``out/lidar`` (generated on first use)."""
    from fog_gym.experiments.detection3d.study import Exp1Config, Exp1Study

    data = out / "lidar"
    config = Exp1Config(epochs=2, rows=("Light", "Mixed-L"))
    return Exp1Study(data, config, generate=0 if (data / "index").exists() else 10, seconds=2.0)


if __name__ == "__main__":
    main()

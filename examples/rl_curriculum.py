"""Does a fog curriculum help an RL driver? PPO on FogDriveRL-v0 trained in clear air, in dense fog and along the
step curriculum (clear → 160 → 100 → 50 m), two seeds each, every agent tested on clear / light / moderate / dense
fog — the RL benchmark at a small budget from Python (about 15 minutes on 2 cores; a smoke run, not a finding).
Writes matrix.md, heatmap.png, fog_effect.png and the learning curves to --out. The full command, with every
option: ``fog-gym rl-bench --help``.
"""

import argparse
from pathlib import Path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("out/rl_example"), help="output folder (default out/rl_example)")
    parser.add_argument("--seeds", type=int, default=2, help="training seeds per condition (default 2)")
    args = parser.parse_args()

    from fog_gym.experiments.rl_bench import RLConfig, RLStudy
    from fog_gym.experiments.runner import run

    config = RLConfig(conditions=("clear", "dense", "curriculum"), steps=2048, episodes=4, envs=2)
    print(run(RLStudy(config), args.out, seeds=args.seeds).markdown)


if __name__ == "__main__":
    main()

"""``python -m fog_gym.experiments.rl_bench`` = ``fog-gym rl-bench``."""

from fog_gym.experiments.rl_bench.study import RLStudy
from fog_gym.experiments.runner import main

if __name__ == "__main__":
    raise SystemExit(main(RLStudy))

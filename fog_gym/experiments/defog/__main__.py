"""``python -m fog_gym.experiments.defog`` = ``fog-gym exp2``."""

from fog_gym.experiments.defog.study import Exp2Study
from fog_gym.experiments.runner import main

if __name__ == "__main__":
    raise SystemExit(main(Exp2Study))

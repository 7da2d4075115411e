"""``python -m fog_gym.experiments.detection3d`` = ``fog-gym exp1``."""

from fog_gym.experiments.detection3d.study import Exp1Study
from fog_gym.experiments.runner import main

if __name__ == "__main__":
    raise SystemExit(main(Exp1Study))

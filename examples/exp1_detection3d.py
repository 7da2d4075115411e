"""Experiment 1 of the FogDrive paper from Python, at a smoke budget: a small LiDAR-only set, two training subsets,
two seeds (a few minutes on 2 cores). Writes exp1.md, exp1.png and results.json to out/exp1_example; run it again
and it keeps what is done. The full command, with every option: ``fog-gym exp1 --help``.
"""

from pathlib import Path

from fog_gym.experiments.detection3d.study import Exp1Config, Exp1Study
from fog_gym.experiments.runner import run

if __name__ == "__main__":
    data = Path("out/exp1_example/lidar")
    config = Exp1Config(epochs=2, rows=("Light", "Mixed-L"))
    study = Exp1Study(data, config, generate=0 if (data / "index").exists() else 10, seconds=2.0)
    print(run(study, "out/exp1_example", seeds=2).markdown)

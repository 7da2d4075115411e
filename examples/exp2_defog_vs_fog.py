"""Experiment 2 of the FogDrive paper from Python, at a smoke budget: a small 128x96 set, every pipeline (clean,
fogged, dehazed by DCP / AOD-Net / the oracle, trained on fog), one seed (a few minutes on 2 cores). Writes exp2.md,
exp2.png and results.json to out/exp2_example. The full command, with every option: ``fog-gym exp2 --help``.
"""

from pathlib import Path

from fog_gym.experiments.defog.study import Exp2Config, Exp2Study
from fog_gym.experiments.runner import run

if __name__ == "__main__":
    data = Path("out/exp2_example/cameras")
    config = Exp2Config(epochs=2, input_size=(64, 48), every=1, test_every=1, train_fraction=1.0, val_fraction=1.0,
                        test_fraction=1.0, aod_epochs=1, aod_pairs=32)  # fmt: skip
    study = Exp2Study(data, config, generate=0 if (data / "index").exists() else 10, seconds=0.6, resolution=(128, 96))
    print(run(study, "out/exp2_example").markdown)

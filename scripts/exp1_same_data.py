"""Whether a regenerated Experiment 1 dataset is the one the kept units were trained and tested on.

A dataset regenerated on another machine can differ in bytes (numpy's SIMD kernels differ in the last bit between
CPUs; ``docs/experiments/runner.md``), which changes its content digest, and ``fog-gym exp1 --keep`` refuses it.
This compares what can be compared without the old files: the ground truth of every test sweep at every level that
a kept unit's predictions hold (``<keep>/preds/<key>.npz``) against the same sweeps of the regenerated set — the
sweeps, scenes, classes and boxes. Same data: exit status 0 and the digest to pass to ``--accept-data``.

    python scripts/exp1_same_data.py --root out/lidar168 --keep results/exp1
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import tempfile
from pathlib import Path

import numpy as np


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--root", type=Path, required=True, help="the regenerated dataset")
    p.add_argument("--keep", type=Path, default=Path("results/exp1"), help="the kept study (default results/exp1)")
    p.add_argument("--tolerance", type=float, default=1e-9, help="largest box difference in metres (default 1e-9)")
    args = p.parse_args()
    record = args.keep / "study.json"
    if not record.is_file():
        p.error(f"{record} does not exist: --keep must be a kept Experiment 1 study")
    units = sorted((args.keep / "preds").glob("*.npz"))
    if not units:
        p.error(f"{args.keep / 'preds'} holds no unit's predictions to compare with")

    from fog_gym.dataset.access import FogDrive
    from fog_gym.dataset.digest import content_digest
    from fog_gym.experiments.detection3d.data import SweepCache, SweepDataset
    from fog_gym.experiments.detection3d.protocol import evaluation_subsets
    from fog_gym.experiments.detection3d.study import Exp1Config

    study = json.loads(record.read_text())
    names = {f.name for f in dataclasses.fields(Exp1Config)}
    config = Exp1Config(**{k: tuple(v) if isinstance(v, list) else v for k, v in study["settings"].items() if k in names})
    ds = FogDrive(args.root)
    tests = evaluation_subsets(ds.splits["test"], config.seed, config.test_fraction)
    same, worst = True, 0.0
    with tempfile.TemporaryDirectory() as tmp:
        for detector in sorted({u.name.split("_")[0] for u in units}):
            kept = np.load(next(u for u in units if u.name.startswith(detector + "_")))
            cache = SweepCache(Path(tmp) / detector, config.grid(detector))
            for level, pairs in tests.items():
                sweeps = SweepDataset(ds, pairs, cache, detector, config.grid(detector), config.test_every)
                gts = [sweeps.cache.get(*it[:3])[1] for it in sweeps.items]
                boxes = np.concatenate([g["boxes"] for g in gts])
                classes = np.concatenate([g["classes"] for g in gts])
                scenes = np.array([it[3] for it in sweeps.items])
                old = kept[f"{level}/gt_boxes"]
                ok = (np.array_equal(scenes, kept[f"{level}/scenes"]) and boxes.shape == old.shape
                      and np.array_equal(classes, kept[f"{level}/gt_classes"]))  # fmt: skip
                diff = float(np.abs(boxes - old).max(initial=0.0)) if ok else float("inf")
                worst = max(worst, diff)
                same &= ok and diff <= args.tolerance
                print(f"{detector:8s} {level:9s} {len(gts)} sweeps, {len(boxes)} boxes: "
                      + (f"largest difference {diff:.2g} m" if ok else "other sweeps, scenes or classes"))
    digest = content_digest(ds, study["data"]["train_scenes"] + study["data"]["test_scenes"])
    known = [study["data"].get("digest"), *study["data"].get("equivalent_digests", [])]
    if not same:
        print(f"other data (largest difference {worst:.2g} m): do not pool it with the kept units")
        return 1
    print(f"the same data (largest difference {worst:.2g} m); its digest {digest}"
          + (" is already the record's" if digest in known else f": pass --accept-data {digest}"))
    return 0


if __name__ == "__main__":
    sys.exit(main())

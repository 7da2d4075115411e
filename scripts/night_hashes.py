"""Hash every channel of a few frames (day and night, several towns and seeds) to check which ones a change touches.

Usage: ``python scripts/night_hashes.py OUT.json`` then compare two files with ``--compare A.json B.json``.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys

import numpy as np
from tqdm import tqdm

CASES = [(town, tod, seed) for town in ("highway", "roundabout", "intersection") for tod in ("day", "night") for seed in (0, 3)]


def frame_hashes(town: str, time_of_day: str, seed: int, steps: int = 2) -> dict[str, str]:
    from fog_gym import FogDriveEnv
    from fog_gym.envs.config import FogDriveConfig
    from fog_gym.sensors.rig import RigConfig

    env = FogDriveEnv(config=FogDriveConfig(town=town, time_of_day=time_of_day, rig=RigConfig.fogdrive(resolution=(160, 120))))
    obs, _ = env.reset(seed=seed)
    space = env.action_space
    idle = np.zeros(space.shape, space.dtype) if getattr(space, "shape", ()) else 1
    for _ in range(steps):
        obs, *_ = env.step(idle)
    env.close()
    return {k: hashlib.sha256(np.ascontiguousarray(v).tobytes()).hexdigest()[:16] for k, v in sorted(obs.items())}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("out", nargs="?", help="JSON file to write")
    p.add_argument("--compare", nargs=2, metavar=("BEFORE", "AFTER"), help="compare two hash files")
    a = p.parse_args(argv)
    if a.compare:
        before, after = (json.load(open(f)) for f in a.compare)
        changed = sorted(f"{case} {ch}" for case in before for ch in before[case] if before[case][ch] != after[case].get(ch))
        print("\n".join(changed) if changed else "identical")
        return 0
    res = {f"{t}/{d}/{s}": frame_hashes(t, d, s) for t, d, s in tqdm(CASES, desc="frames")}
    json.dump(res, open(a.out, "w"), indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())

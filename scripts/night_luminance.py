"""Night/day luminance of the front camera over the six towns: road pixels within 30 m, vehicle pixels within 40 m.

Same seed, same steps, day and night; luminance is Rec. 709 ``Y`` of the 8-bit RGB on 0–1.

Usage: ``python scripts/night_luminance.py [--seed 5] [--steps 5] [--out night_luminance.json]``
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np
from tqdm import tqdm

from fog_gym.world.towns import TOWNS

ROAD_TAGS = (1, 24)


def front_luminance(town: str, time_of_day: str, seed: int, steps: int, resolution=(320, 240)) -> dict[str, float]:
    from fog_gym.envs.fogdrive import FogDriveEnv

    env = FogDriveEnv(town=town, time_of_day=time_of_day, resolution=resolution, cameras=["CAM_FRONT"], labels=None)
    env.reset(seed=seed)
    space = env.action_space
    idle = np.zeros(space.shape, space.dtype) if getattr(space, "shape", ()) else 1  # keep lane / no input
    for _ in range(steps):
        env.step(idle)
    f = env.frames["CAM_FRONT"]
    env.close()
    y = f.rgb.astype(np.float64) @ np.array([0.2126, 0.7152, 0.0722]) / 255.0
    road = np.isin(f.semantic, ROAD_TAGS) & (f.depth < 30.0)
    veh = (f.instance > 0) & (f.depth < 40.0)
    return {"road": float(y[road].mean()) if road.any() else float("nan"),
            "vehicle": float(y[veh].mean()) if veh.any() else float("nan"), "vehicle_pixels": int(veh.sum())}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seed", type=int, default=5)
    p.add_argument("--steps", type=int, default=5)
    p.add_argument("--out", default=None, help="write the numbers as JSON here")
    a = p.parse_args(argv)
    rows = {}
    for town in tqdm(TOWNS, desc="towns"):
        rows[town] = {tod: front_luminance(town, tod, a.seed, a.steps) for tod in ("day", "night")}
    tot = {k: [np.nanmean([rows[t][tod][k] for t in TOWNS]) for tod in ("day", "night")] for k in ("road", "vehicle")}
    print(f"{'town':14s} {'road day':>9s} {'night':>7s} {'veh day':>8s} {'night':>7s}")
    for t in TOWNS:
        d, n = rows[t]["day"], rows[t]["night"]
        print(f"{t:14s} {d['road']:9.3f} {n['road']:7.3f} {d['vehicle']:8.3f} {n['vehicle']:7.3f}")
    ratios = {k: tot[k][1] / tot[k][0] for k in tot}
    print(f"mean road day {tot['road'][0]:.3f} night {tot['road'][1]:.3f} ratio {ratios['road']:.3f}; "
          f"vehicles day {tot['vehicle'][0]:.3f} night {tot['vehicle'][1]:.3f} ratio {ratios['vehicle']:.3f}")
    if a.out:
        json.dump({"towns": rows, "mean": tot, "ratio": ratios}, open(a.out, "w"), indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())

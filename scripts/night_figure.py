"""Write the night fog-levels picture: the front camera by day and by night at clear/light/moderate/dense fog.

Usage: ``python scripts/night_figure.py [--town highway] [--seed 5] [--steps 5] [--out docs/images/night_fog_levels.png]``
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from tqdm import tqdm

from fog_gym.world.towns import TOWNS

LEVELS = ("light", "moderate", "dense")


def front_levels(town: str, time_of_day: str, seed: int, steps: int, resolution) -> dict[str, np.ndarray]:
    import gymnasium as gym

    import fog_gym  # noqa: F401  (registers FogDrive-v0)
    from fog_gym.fog import parse_fog

    env = gym.make("FogDrive-v0", town=town, time_of_day=time_of_day, resolution=resolution, cameras=["CAM_FRONT"],
                   labels=None, fog=list(LEVELS))  # paired: clean + every level from one render  # fmt: skip
    obs, _ = env.reset(seed=seed)
    space = env.action_space
    idle = np.zeros(space.shape, space.dtype) if getattr(space, "shape", ()) else 1
    for _ in range(steps):
        obs, *_ = env.step(idle)
    env.close()
    out = {"clear": obs["CAM_FRONT"]}
    for name in LEVELS:
        lv = parse_fog(name)
        out[f"{name} ({lv.visibility_m:g} m)"] = obs[f"CAM_FRONT_{lv.channel_suffix}"]
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--town", choices=TOWNS, default="highway")
    p.add_argument("--seed", type=int, default=5)
    p.add_argument("--steps", type=int, default=5)
    p.add_argument("--resolution", type=int, nargs=2, default=(480, 360), metavar=("W", "H"))
    p.add_argument("--out", type=Path, default=Path("docs/images/night_fog_levels.png"))
    a = p.parse_args(argv)
    from fog_gym.viz.figures import night_levels_figure, save

    frames = {tod: front_levels(a.town, tod, a.seed, a.steps, tuple(a.resolution))
              for tod in tqdm(("day", "night"), desc="rendering")}  # fmt: skip
    title = f"The front camera by day and by night at each fog level ({a.town}, seed {a.seed}, after {a.steps / 10:g} s)"
    print(f"wrote {save(night_levels_figure(frames['day'], frames['night'], title), a.out)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

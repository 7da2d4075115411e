"""The before/after figure of the world of meshes: the same seed with ``geometry="boxes"`` (before) and
``geometry="meshes"`` (after), the front camera and the LiDAR from above, in clear air and dense fog.

Usage: ``python scripts/mesh_figure.py [--seed 5] [--steps 10] [--out docs/images/meshes_before_after.png]``
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seed", type=int, default=5, help="episode seed (default 5)")
    p.add_argument("--steps", type=int, default=10, help="steps before the snapshot (default 10)")
    p.add_argument("--out", type=Path, default=Path("docs/images/meshes_before_after.png"), help="PNG to write")
    a = p.parse_args(argv)
    import gymnasium as gym
    import matplotlib.pyplot as plt
    from tqdm import tqdm

    import fog_gym  # noqa: F401
    from fog_gym.dataset.packing import unpack_points
    from fog_gym.viz import figures

    shots = {}
    for geometry in tqdm(("boxes", "meshes"), desc="rendering", unit="world"):
        env = gym.make("FogDrive-v0", geometry=geometry, fog=["dense"], labels=None)
        obs, _ = env.reset(seed=a.seed)
        for _ in range(a.steps):
            obs, *_ = env.step(1)
        shots[geometry] = obs
        env.close()
    fig, axes = plt.subplots(2, 4, figsize=(17, 7.6), layout="constrained",
                             gridspec_kw={"width_ratios": [4 / 3, 4 / 3, 1, 1]})  # fmt: skip
    for r, geometry in enumerate(("boxes", "meshes")):
        obs = shots[geometry]
        label = {"boxes": "before: boxes", "meshes": "after: meshes"}[geometry]
        figures._image(axes[r, 0], obs["CAM_FRONT"], "CAM_FRONT, clear" if r == 0 else None)
        figures._image(axes[r, 1], obs["CAM_FRONT_FOG_DENSE"], "CAM_FRONT, dense fog (50 m)" if r == 0 else None)
        axes[r, 0].set_ylabel(label, fontsize=11)
        for c, key in ((2, "LIDAR_TOP"), (3, "LIDAR_TOP_FOG_DENSE")):
            pts = unpack_points(obs, key)
            title = ("LIDAR_TOP, clear" if c == 2 else "LIDAR_TOP, dense fog") if r == 0 else None
            figures._bev(axes[r, c], pts, figures.intensity_colors(pts[:, 3]), 80.0, title)
    figures._intensity_bar(fig, axes[:, 3].tolist())
    fig.suptitle(f"The same seed ({a.seed}) before and after the world of meshes: camera and LiDAR, clear and dense fog",
                 fontsize=13)  # fmt: skip
    print(f"wrote {figures.save(fig, a.out)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

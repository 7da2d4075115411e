"""Write the fog-fields picture: the ego approaching a fog bank (front camera and LiDAR from above, side by side, at
150, 75 and 25 m before the bank) and ground fog seen from the rig.

Usage: ``python scripts/bank_figure.py [--town highway] [--seed 2] [--out docs/images/fog_bank.png]``
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
from tqdm import tqdm

from fog_gym.world.towns import TOWNS

DISTANCES = (150.0, 75.0, 25.0)


def approach(town: str, seed: int, resolution, bank_start: float, bank_visibility: float):
    """Front camera, clean and fogged LiDAR when the ego is 150, 75 and 25 m before a bank ``bank_start`` m ahead."""
    from fog_gym.dataset.packing import unpack_points
    from fog_gym.envs.fogdrive import FogDriveEnv
    from fog_gym.fog.fields import FogBank
    from fog_gym.wrappers import FogWrapper

    bank = FogBank(bank_visibility, start=bank_start, length=300.0, edge=10.0, name="bank")
    env = FogWrapper(FogDriveEnv(town=town, resolution=resolution, cameras=["CAM_FRONT"], labels=None), [bank])
    obs, _ = env.reset(seed=seed)
    x0, y0, heading = env.field_frame
    shots = []
    with tqdm(total=len(DISTANCES), desc="approaching the bank") as bar:
        for _ in range(2000):
            origin = env.unwrapped.sensor_to_world("LIDAR_TOP")[:3, 3]
            gap = bank_start - ((origin[0] - x0) * math.cos(heading) + (origin[1] - y0) * math.sin(heading))
            if gap <= DISTANCES[len(shots)]:
                shots.append((gap, np.concatenate([obs["CAM_FRONT"], obs["CAM_FRONT_FOG_BANK"]], axis=1),
                              unpack_points(obs, "LIDAR_TOP"),
                              unpack_points(obs, "LIDAR_TOP_FOG_BANK")))  # fmt: skip
                bar.update()
                if len(shots) == len(DISTANCES):
                    break
            obs, *_ = env.step(env.unwrapped.idle_action)
    env.close()
    return shots


def ground(town: str, seed: int, resolution) -> tuple[np.ndarray, np.ndarray]:
    from fog_gym.envs.fogdrive import FogDriveEnv
    from fog_gym.fog.fields import HeightFog
    from fog_gym.wrappers import FogWrapper

    env = FogWrapper(FogDriveEnv(town=town, resolution=resolution, cameras=["CAM_FRONT"], labels=None),
                     [HeightFog(25.0, 2.0, name="ground")])  # fmt: skip
    obs, _ = env.reset(seed=seed)
    env.close()
    return obs["CAM_FRONT"], obs["CAM_FRONT_FOG_GROUND"]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--town", choices=TOWNS, default="highway")
    p.add_argument("--seed", type=int, default=2)
    p.add_argument("--resolution", type=int, nargs=2, default=(480, 360), metavar=("W", "H"))
    p.add_argument("--bank-start", type=float, default=170.0, help="the bank's near face at reset [m ahead]")
    p.add_argument("--bank-visibility", type=float, default=40.0, help="the bank's visibility [m]")
    p.add_argument("--out", type=Path, default=Path("docs/images/fog_bank.png"))
    a = p.parse_args(argv)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    shots = approach(a.town, a.seed, tuple(a.resolution), a.bank_start, a.bank_visibility)
    clean, foggy = ground(a.town, a.seed, tuple(a.resolution))
    fig, axes = plt.subplots(len(shots) + 1, 2, figsize=(13, 3.3 * (len(shots) + 1)),
                             gridspec_kw={"width_ratios": [8, 3]})  # fmt: skip
    for row, (gap, image, cloud, fogged) in zip(axes, shots):
        row[0].imshow(image)
        row[0].set_title(f"front camera, clear | fogged, {gap:.0f} m before a {a.bank_visibility:g} m bank", fontsize=9)
        moved = np.any(fogged[:, :3] != cloud[:, :3], axis=1)
        ax = row[1]
        ax.scatter(cloud[~moved, 0], cloud[~moved, 1], s=0.3, c="0.35", label="returns as in clear air")
        ax.scatter(fogged[moved, 0], fogged[moved, 1], s=0.6, c="tab:red", label="fog returns (range noise ×½–2)")
        ax.axvline(gap, color="tab:blue", lw=0.8, ls="--", label="the bank's near face")
        ax.set_xlim(-10, 170)
        ax.set_ylim(-45, 45)
        ax.set_aspect("equal")
        ax.set_title("LiDAR from above (LiDAR frame, m)", fontsize=9)
        ax.legend(loc="lower right", fontsize=7, markerscale=8)
    axes[-1][0].imshow(np.concatenate([clean, foggy], axis=1))
    axes[-1][0].set_title("ground fog (25 m at the road, scale height 2 m): clear | fogged — the sky clears upwards",
                          fontsize=9)  # fmt: skip
    profile = foggy.astype(float).mean(axis=(1, 2)) - clean.astype(float).mean(axis=(1, 2))
    axes[-1][1].plot(profile, np.arange(len(profile)))
    axes[-1][1].invert_yaxis()
    axes[-1][1].set_xlabel("fogged − clear, mean grey per image row")
    axes[-1][1].set_ylabel("image row")
    for ax in np.ravel(axes)[::2]:
        ax.axis("off")
    fig.suptitle(f"Fog with a shape ({a.town}, seed {a.seed})", fontsize=11)
    fig.tight_layout()
    a.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(a.out, dpi=90)
    print(f"wrote {a.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

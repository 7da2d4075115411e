"""Fog on real data, checked by the simulator, and the figure of docs/augment.md.

Generates a clear fog-gym set (unless --root holds one), exports it to KITTI and nuScenes, runs ``fog-gym augment``
on each export and on the set itself at the three levels and in a fog bank, and compares with the simulator's own
fogged channels (fog_gym.augment.check): the LiDAR's keep / replace decisions point for point, the camera images
with the true depth and with depth completed from the scan (PSNR overall and per band of distance). Prints Markdown
tables; ``--figure`` writes one KITTI frame clear, at each level and in the bank (scan from above, image).

    python scripts/augment_check.py --root out/augment_check --figure docs/images/augment.png
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

LEVELS = ("light", "moderate", "dense")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--root", type=Path, default=Path("out/augment_check"), help="work folder (default out/augment_check)")
    p.add_argument("--scenes", type=int, default=6, help="scenes to generate (default 6)")
    p.add_argument("--seconds", type=float, default=2.0, help="scene length (default 2 s)")
    p.add_argument("--resolution", default="640x480", help="camera resolution (default 640x480)")
    p.add_argument("--figure", type=Path, default=None, help="write the figure here")
    args = p.parse_args()

    from fog_gym.augment.check import BANDS, camera_errors, lidar_decisions
    from fog_gym.augment.run import augment
    from fog_gym.dataset.export import export
    from fog_gym.fog.fields import FogBank
    from fog_gym.generate import generate, plan_scenes

    root = args.root
    src = root / "src"
    if not (src / "index").exists():
        w, h = (int(v) for v in args.resolution.split("x"))
        generate(src, plan_scenes(args.scenes, seed=11, resolution=(w, h), seconds=args.seconds), workers=2)
    for fmt in ("kitti", "nuscenes"):
        if not (root / fmt).exists():
            export(src, root / fmt, fmt, progress=False)
    bank = FogBank(50.0, start=30.0, length=100.0, edge=10.0, name="bank")
    times = {}
    for fmt in ("kitti", "nuscenes", "fogdrive"):
        out = root / f"{fmt}_fog"
        t0 = time.perf_counter()
        augment(src if fmt == "fogdrive" else root / fmt, out, fmt, [*LEVELS, bank], resume=out.exists(), workers=2)
        times[fmt] = time.perf_counter() - t0
    print("\n**LiDAR: the augmenter's keep / replace decisions against the simulator's, every point of every scan**\n")
    print("| layout | level | points | agree | replaced by fog | kept points equal |\n|---|---|---|---|---|---|")
    for fmt in ("kitti", "nuscenes", "fogdrive"):
        for lv in LEVELS:
            r = lidar_decisions(src, root / f"{fmt}_fog" / lv, fmt, lv)
            print(f"| {fmt} | {lv} | {r['points']:,} | {r['share'] * 100:.3f} % | {r['replaced_simulator']:,} | "
                  f"{'yes' if r['kept_points_equal'] else 'no'} |")  # fmt: skip
    print("\n**Camera (CAM_FRONT): the augmenter's images against the simulator's** (PSNR in dB; max |difference| in "
          "levels of 255)\n")  # fmt: skip
    print("| level | true depth: max abs | completed depth: PSNR | " + " | ".join(BANDS) + " |\n|---|---|---|" + "---|" * len(BANDS))
    print("(completed depth with the image's sky, sky='image'; in brackets the horizon rule, sky='horizon')\n")
    for lv in LEVELS:
        exact = camera_errors(src, lv, completed=False)
        r = camera_errors(src, lv, completed=True)
        hr = camera_errors(src, lv, completed=True, sky="horizon")
        print(f"| {lv} | {exact['max_abs']} | {r['psnr']:.1f} ({hr['psnr']:.1f}) | "
              + " | ".join(f"{r['bands'][b]:.1f} ({hr['bands'][b]:.1f})" for b in BANDS) + " |")  # fmt: skip
    share = {b: v for b, v in camera_errors(src, "dense", completed=True)["pixels"].items()}
    total = sum(share.values())
    print("\nPixels per band: " + ", ".join(f"{b} {v / total * 100:.0f} %" for b, v in share.items()))
    print("\nWall time of the four fogs per layout (2 workers): " + ", ".join(f"{k} {v:.1f} s" for k, v in times.items()))
    if args.figure:
        figure(root, args.figure)


def figure(root: Path, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from fog_gym.augment.run import read_image, read_points

    kitti = root / "kitti" / "training"
    frame = sorted((kitti / "velodyne").glob("*.bin"))[len(list((kitti / "velodyne").glob("*.bin"))) // 3].stem
    columns = [("clear", root / "kitti")] + [(lv, root / "kitti_fog" / lv) for lv in (*LEVELS, "bank")]
    fig, axes = plt.subplots(2, len(columns), figsize=(3.4 * len(columns), 6.2))
    for j, (name, base) in enumerate(columns):
        pts = read_points(base / "training" / "velodyne" / f"{frame}.bin", 4)
        ax = axes[0, j]
        ax.scatter(-pts[:, 1], pts[:, 0], s=0.15, c=pts[:, 3], cmap="viridis", vmin=0, vmax=1, rasterized=True)
        ax.set_xlim(-40, 40)
        ax.set_ylim(-20, 60)
        ax.set_aspect("equal")
        ax.set_xlabel("right [m]")
        if j == 0:
            ax.set_ylabel("forward [m]")
        title = {"clear": "clear", "light": "light (160 m)", "moderate": "moderate (100 m)", "dense": "dense (50 m)",
                 "bank": "bank: 50 m, 30–130 m ahead"}[name]  # fmt: skip
        ax.set_title(f"{title}\n{len(pts):,} points (colour: reflectance)", fontsize=8)
        img = read_image(base / "training" / "image_2" / f"{frame}.png")
        axes[1, j].imshow(img)
        axes[1, j].axis("off")
    fig.suptitle("fog-gym augment on a KITTI-layout frame (fog-gym's export): scan from above and image_2", fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()

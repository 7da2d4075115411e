"""Regenerate the docs' sensor figures with the demo's own code (fog_gym.viz.figures): fog_levels.png (README and
docs/index.md), cameras.png and lidar_sweep.png (docs/sensors.md), and night_fog_levels.png (scripts/night_figure.py).

Usage: ``python scripts/docs_figures.py [--seed 0] [--steps 20] [--out docs/images]``
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seed", type=int, default=0, help="demo seed (default 0)")
    p.add_argument("--steps", type=int, default=20, help="demo steps before the snapshot (default 20)")
    p.add_argument("--out", type=Path, default=Path("docs/images"), help="folder of the docs' images")
    a = p.parse_args(argv)
    from fog_gym.cli import main as cli

    with tempfile.TemporaryDirectory() as tmp:
        cli(["demo", "--seed", str(a.seed), "--steps", str(a.steps), "--out", tmp])
        stem = f"highway_day_seed{a.seed}"
        for src, dst in (("fog_levels", "fog_levels"), ("contact_sheet", "cameras"), ("lidar", "lidar_sweep")):
            shutil.copyfile(Path(tmp) / f"{src}_{stem}.png", a.out / f"{dst}.png")
            print(f"wrote {a.out / f'{dst}.png'}")
    here = Path(__file__).resolve().parent
    subprocess.run([sys.executable, str(here / "night_figure.py"), "--out", str(a.out / "night_fog_levels.png")], check=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

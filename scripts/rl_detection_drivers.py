"""What perception is worth on FogDriveRLHazard-v0: each sensor set's reach per fog level, and the return and
collision rate of the scripted driver that uses only that sensor set's perceived objects
(:mod:`fog_gym.perception.driver`). Writes a Markdown table and a JSON file (the bound an agent can reach).

Run: python scripts/rl_detection_drivers.py [--episodes 32] [--out docs/rl_detection_drivers]
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

from tqdm import tqdm

SETS = {"camera": ("camera",), "lidar": ("lidar",), "radar": ("radar",), "fused": ("camera", "lidar", "radar")}
FOGS = ("clear", "light", "moderate", "dense")


def main(argv: list[str] | None = None) -> int:
    from fog_gym.perception.driver import drive, sensor_reach

    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--episodes", type=int, default=32, help="evaluation episodes per cell (default 32)")
    p.add_argument("--reach-episodes", type=int, default=8, help="episodes measuring each reach (default 8)")
    p.add_argument("--out", type=Path, default=Path("out/rl_detection_drivers"), help="output path without suffix")
    args = p.parse_args(argv)
    if args.episodes < 1 or args.reach_episodes < 1:
        p.error("--episodes and --reach-episodes must be >= 1")
    result: dict = {}
    for name, sensors in tqdm(list(SETS.items()), desc="sensor sets"):
        for fog in FOGS:
            reach = sensor_reach(sensors, fog, episodes=args.reach_episodes)
            result.setdefault(name, {})[fog] = drive(sensors, fog, reach, episodes=args.episodes)
    lines = ["| sensors | " + " | ".join(FOGS) + " |", "|---|" + "---|" * len(FOGS)]
    for name in SETS:
        cells = [f"{r['return']:.1f} ({r['collisions']:.0%}) · {r['reach']:.0f} m"
                 for r in (result[name][f] for f in FOGS)]  # fmt: skip
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    text = "\n".join(lines) + "\n"
    args.out.parent.mkdir(parents=True, exist_ok=True)
    for suffix, data in ((".md", text), (".json", json.dumps(result, indent=1))):
        tmp = args.out.with_suffix(suffix + ".tmp")
        tmp.write_text(data)
        os.replace(tmp, args.out.with_suffix(suffix))
    print(f"return (collision rate) · 95th-percentile reach, {args.episodes} episodes per cell\n\n{text}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

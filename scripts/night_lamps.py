"""Street lamps per town: mounting height, nominal spacing, and the measured metres of lit road edge per lamp.

For each town one episode's static world (seed ``--seed``): the lamp heads (``scenery.lamp_heads``) and the outer
road edges the poles line (``scenery``'s placement rule); "m per lamp" is the edges' length divided by the lamps.

Usage: ``python scripts/night_lamps.py [--seed 0]``
"""

from __future__ import annotations

import argparse
import sys

import numpy as np


def town_lamps(town: str, seed: int) -> dict[str, float]:
    from fog_gym.envs import fogdrive as fog_env
    from fog_gym.world.scenery import STYLES, lamp_heads, lit_edge_length
    from fog_gym.world.towns import TOWN_SPECS

    env = fog_env.FogDriveEnv(town=town, time_of_day="night", resolution=(64, 48), cameras=["CAM_FRONT"], labels=None)
    env.reset(seed=seed)
    static = env.scene.static
    heads = lamp_heads(static.props, static.surface)
    lanes = env.world.lane_geometry(env.world.start_position, fog_env.MAX_SPEED * env.config.episode_seconds + 250.0)
    length = lit_edge_length(lanes, static.surface)
    env.close()
    style = TOWN_SPECS[town].scenery
    return {"style": style, "height": float(np.median(heads[:, 2])), "spacing": STYLES[style].pole_spacing,
            "lamps": len(heads), "edge_m": length, "m_per_lamp": length / max(len(heads), 1)}


def main(argv: list[str] | None = None) -> int:
    from fog_gym.world.towns import TOWNS

    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seed", type=int, default=0)
    a = p.parse_args(argv)
    print("| town | style | lamp height | pole spacing | lamps | lit road edge | m per lamp |")
    print("|------|-------|-------------|--------------|-------|---------------|------------|")
    for town in TOWNS:
        r = town_lamps(town, a.seed)
        print(f"| {town} | {r['style']} | {r['height']:.0f} m | {r['spacing']:.0f} m | {r['lamps']} | {r['edge_m']:.0f} m "
              f"| {r['m_per_lamp']:.1f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())

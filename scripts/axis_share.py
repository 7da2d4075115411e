"""How box-like the vehicles look: the share of the visible surface of vehicles within 30 m of ``CAM_FRONT`` whose
surface faces one of the vehicle's box axes within 10°, for ``geometry="boxes"`` and ``"meshes"``, over several seeds.

Usage: ``python scripts/axis_share.py [--seeds 10] [--steps 10]``
"""

from __future__ import annotations

import argparse
import sys

import numpy as np


def share(geometry: str, seed: int, steps: int) -> tuple[int, int]:
    """(pixels facing a box axis within 10°, vehicle pixels) of ``CAM_FRONT`` for vehicles within 30 m."""
    import gymnasium as gym

    import fog_gym  # noqa: F401
    from fog_gym.render.raster import render
    from fog_gym.render.surface import ground_lut, tiled_surface
    from fog_gym.world.scenery import SURFACE_TAGS

    env = gym.make("FogDrive-v0", geometry=geometry, cameras=["CAM_FRONT"], labels=None)
    env.reset(seed=seed)
    for _ in range(steps):
        env.step(1)
    base = env.unwrapped
    scene, rig = base.scene, base.cameras
    prims = rig.primitives(scene)
    cam = base.config.rig.cameras[0]
    m = rig.world_to_camera(scene, cam.name)
    k = rig.intrinsics[cam.name]
    light = scene.lighting
    out = render(m[None, :3, :3], m[None, :3, 3], np.array([[k[0, 0], k[1, 1], k[0, 2], k[1, 2]]]), cam.width,
                 cam.height, rig.far, prims, tiled_surface(scene.static), ground_lut(light), SURFACE_TAGS,
                 light.sky_horizon, light.sky_zenith, light.sun_dir, light.ambient, light.sun_intensity,
                 face_ids=True)  # fmt: skip
    face, inst, depth = out["face"][0], out["inst"][0], out["depth"][0]
    v = scene.vehicles
    aligned = total = 0
    for vid, yaw, center in zip(v.ids, v.yaws, v.centers):
        pix = (inst == vid) & (face >= 0)
        if vid == scene.ego_id or not pix.any() or np.hypot(*(center[:2] - scene.ego_pose[:2])) > 30.0:
            continue
        n = out["face_normal"][0][face[pix]]
        c, s = np.cos(yaw), np.sin(yaw)
        local = np.c_[n[:, 0] * c + n[:, 1] * s, -n[:, 0] * s + n[:, 1] * c, n[:, 2]]
        aligned += int((np.abs(local).max(axis=1) >= np.cos(np.radians(10.0))).sum())
        total += int(pix.sum())
    env.close()
    assert depth is not None
    return aligned, total


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seeds", type=int, default=10, help="episodes (seeds 0..N-1, default 10)")
    p.add_argument("--steps", type=int, default=10, help="steps before each snapshot (default 10)")
    a = p.parse_args(argv)
    from tqdm import tqdm

    for geometry in ("boxes", "meshes"):
        res = [share(geometry, seed, a.steps) for seed in tqdm(range(a.seeds), desc=geometry, unit="seed")]
        aligned, total = sum(r[0] for r in res), sum(r[1] for r in res)
        print(f"{geometry}: {100.0 * aligned / max(total, 1):.1f} % of {total} vehicle pixels face a box axis within 10°")
    return 0


if __name__ == "__main__":
    sys.exit(main())

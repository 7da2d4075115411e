"""Time the dehazers of Experiment 2 on a fogged full-resolution FogDrive frame (target: DCP ≤ 50 ms at 1280×960
on 2 cores).

The frame is a real one: the front camera of a highway scene, fogged by the fog wrapper at the chosen level.
Each dehazer runs ``--repeats`` times after one warm-up call; the median and the fastest run are printed, with
the fog wrapper's own Koschmieder pass on the same frame as the reference cost of one fog level.

    python scripts/bench_dehaze.py                      # 1280×960, dense fog
    python scripts/bench_dehaze.py --resolution 640x480 --level light --repeats 30
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

from tqdm import tqdm


def frame(resolution: tuple[int, int], level: str):
    import fog_gym
    from fog_gym.fog import parse_fog
    from fog_gym.wrappers import FogWrapper

    env = FogWrapper(fog_gym.FogDriveEnv(town="highway", resolution=resolution, cameras=["CAM_FRONT"]), [level])
    obs, _ = env.reset(seed=3)
    for _ in range(3):
        obs, *_ = env.step(env.unwrapped.idle_action)
    cam = env.unwrapped.config.rig.cameras[0]
    out = (obs["CAM_FRONT"], obs[f"CAM_FRONT_FOG_{level.upper()}"], obs["CAM_FRONT_DEPTH"], cam.intrinsic(),
           parse_fog(level).alpha, env.airlight["CAM_FRONT"])  # fmt: skip
    env.close()
    return out


def timed(fn, repeats: int, label: str) -> list[float]:
    fn()  # warm-up (numba/torch initialisation)
    times = []
    for _ in tqdm(range(repeats), desc=label, leave=False):
        t0 = time.perf_counter()
        fn()
        times.append(1000.0 * (time.perf_counter() - t0))
    return times


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], epilog=__doc__.split("\n\n", 2)[2],
                                formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip
    p.add_argument("--resolution", default="1280x960", help="camera WxH (default 1280x960)")
    p.add_argument("--level", default="dense", choices=["light", "moderate", "dense"], help="fog level (default dense)")
    p.add_argument("--repeats", type=int, default=20, help="timed runs per dehazer (default 20)")
    a = p.parse_args(argv)
    from fog_gym.cli import _resolution

    try:
        res = _resolution(a.resolution)
    except argparse.ArgumentTypeError as e:
        p.error(str(e))
    if a.repeats < 1:
        p.error("--repeats must be >= 1")

    import torch

    from fog_gym.dehaze import dcp, oracle
    from fog_gym.dehaze.aodnet import AODNet, dehaze
    from fog_gym.fog import fog_images
    from fog_gym.metrics.image_quality import psnr

    clean, fogged, depth, K, alpha, A = frame(res, a.level)
    aod = AODNet()
    runs = {
        "fog wrapper's Koschmieder pass (1 level)": lambda: fog_images(clean, depth, K, [alpha], A),
        "DCP": lambda: dcp(fogged),
        "AOD-Net (CPU, untrained weights)": lambda: dehaze(aod, fogged),
        "oracle": lambda: oracle(fogged, depth, K, alpha, A),
    }
    print(f"{res[0]}×{res[1]} {a.level} fog, {os.cpu_count()} CPU cores, torch threads {torch.get_num_threads()}, "
          f"{a.repeats} runs each")  # fmt: skip
    print(f"{'':44s} {'median ms':>10s} {'fastest ms':>11s}")
    med = {}
    for name, fn in runs.items():
        t = timed(fn, a.repeats, name)
        med[name] = statistics.median(t)
        print(f"{name:44s} {med[name]:10.1f} {min(t):11.1f}")
    print(f"PSNR against the clean frame: fogged {psnr(fogged, clean):.2f} dB, DCP {psnr(dcp(fogged), clean):.2f} dB, "
          f"oracle {psnr(oracle(fogged, depth, K, alpha, A), clean):.2f} dB")  # fmt: skip
    if res == (1280, 960):
        verdict = "met" if med["DCP"] <= 50.0 else "NOT met"
        print(f"DCP target ≤ 50 ms at 1280×960: {verdict} ({med['DCP']:.1f} ms median)")
    return 0


if __name__ == "__main__":
    sys.exit(main())

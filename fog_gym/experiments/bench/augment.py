"""Fog on real data (``fog-gym augment``), per core: Hahner LiDAR fog on a KITTI-sized scan (120 k points, HDL-64E
layout: 64 rings × 1 875 azimuths, ground at −1.73 m, walls of buildings and cars) at each level and in a fog bank,
and Koschmieder camera fog on a KITTI-sized image (1242 × 375) with depth completed from that scan (projection,
Ku et al.'s completion, the sky and ground rules) — all kernels on one thread (numba and OpenCV), so that the
figures are per core. Beside them, the reference fog program's cost per 100 k points as measured earlier on this
project's machines (1.6–1.9 s; an earlier note measured ≈ 0.9 s; not rerun here: its licence keeps its code out of
the project). Each figure is the median over ``--repeats`` calls after a warm-up. It prints a Markdown table and
asserts no timing.

Usage::

    python -m fog_gym.experiments.bench.augment            # 20 repeats
    python -m fog_gym.experiments.bench.augment --quick
"""

from __future__ import annotations

import math
import sys
from typing import Any

import numpy as np

from fog_gym.experiments.bench.common import (
    bench_main, fmt_ms, markdown_table, summarize, timed,
)  # fmt: skip

#: The reference program's cost per 100 k points [s], as measured earlier on this project's machines.
REFERENCE_S_PER_100K = (1.6, 1.9)
#: The issue's targets: LiDAR scans of 120 k points per second per core, and ms per 1242 × 375 image with completion.
TARGET_SCANS_PER_S, TARGET_IMAGE_MS = 20.0, 50.0


def kitti_like_scan(seed: int = 0, rings: int = 64, columns: int = 1875) -> np.ndarray:
    """An HDL-64E-like scan in KITTI's LiDAR frame (x forward, y left, z up; reflectance in [0, 1]): each beam hits
    the ground at −1.73 m, or a wall 8–60 m away in its azimuth sector, or nothing within 120 m (dropped)."""
    rng = np.random.default_rng(seed)
    el = np.radians(np.linspace(2.0, -24.9, rings))[:, None]
    az = np.linspace(-math.pi, math.pi, columns, endpoint=False)[None, :]
    sectors = rng.uniform(8.0, 60.0, 72)
    wall = sectors[((az + math.pi) / (2 * math.pi) * 72).astype(int) % 72]
    ground = np.where(el < 0, 1.73 / np.maximum(-np.sin(el), 1e-9), np.inf)
    wall_r = np.where(wall * np.tan(el) + 1.73 < 4.0, wall / np.cos(el), np.inf)  # walls 4 m high
    r = np.minimum(ground, wall_r)
    ok = r < 120.0
    rr, ee, aa = r[ok], np.broadcast_to(el, r.shape)[ok], np.broadcast_to(az, r.shape)[ok]
    pts = np.c_[rr * np.cos(ee) * np.cos(aa), rr * np.cos(ee) * np.sin(aa), rr * np.sin(ee), rng.uniform(0, 1, ok.sum())]
    return pts.astype(np.float32)


def kitti_like_camera(width: int = 1242, height: int = 375) -> tuple[np.ndarray, np.ndarray]:
    """KITTI's camera 2: K and the LiDAR → camera transform (rectified; the camera 0.27 m ahead, 0.08 m below)."""
    K = np.array([[721.5, 0.0, 609.6], [0.0, 721.5, 172.9], [0.0, 0.0, 1.0]])
    T = np.array([[0.0, -1.0, 0.0, 0.06], [0.0, 0.0, -1.0, -0.08], [1.0, 0.0, 0.0, -0.27], [0.0, 0.0, 0.0, 1.0]])
    return K, T


def bench_augment(repeats: int) -> dict[str, Any]:
    import cv2
    import numba

    from fog_gym.augment import fog_image, fog_points, image_depth
    from fog_gym.fog.fields import FogBank

    threads = numba.get_num_threads()
    cv_threads = cv2.getNumThreads()
    numba.set_num_threads(1)
    cv2.setNumThreads(1)
    try:
        scan = kitti_like_scan()
        scan = np.concatenate([scan, kitti_like_scan(1)])[:120_000]
        K, T = kitti_like_camera()
        rng = np.random.default_rng(0)
        img = rng.integers(0, 256, (375, 1242, 3), dtype=np.uint8)  # a textured scene under a smooth blue sky
        img[:150] = np.linspace((90, 130, 200), (170, 190, 220), 150)[:, None].astype(np.uint8)
        bank = FogBank(50.0, start=25.0, length=80.0, edge=10.0)
        calls = {
            **{f"LiDAR fog, {len(scan) // 1000} k points, {lv}": (lambda lv=lv: fog_points(scan, lv, "kitti", rng))
               for lv in ("light", "moderate", "dense")},
            f"LiDAR fog, {len(scan) // 1000} k points, a fog bank (50 m, 25 m ahead)": lambda: fog_points(scan, bank, "kitti", rng),
            "depth completion, 1242 × 375 (projection + Ku et al. + ground + the image's sky)":
                lambda: image_depth((1242, 375), K, scan, T, rgb=img),
            "depth completion, 1242 × 375, sky='horizon'": lambda: image_depth((1242, 375), K, scan, T),
            "camera fog with depth completion, 1242 × 375, dense": lambda: fog_image(img, K, "dense", points=scan, T_cam_lidar=T),
        }  # fmt: skip
        results = {}
        for name, fn in calls.items():
            fn()  # compile / warm
            results[name] = summarize([timed(fn)[1] for _ in range(repeats)])
        results["points"] = len(scan)
        return results
    finally:
        numba.set_num_threads(threads)
        cv2.setNumThreads(cv_threads)


def render_augment(results: dict[str, Any], repeats: int) -> list[str]:
    rows = []
    for name, stat in results.items():
        if not isinstance(stat, dict):
            continue
        extra = ""
        if name.startswith("LiDAR"):
            per_s = 1000.0 / stat["median"]
            extra = f"{per_s:.0f} scans/s (target ≥ {TARGET_SCANS_PER_S:.0f}: {'met' if per_s >= TARGET_SCANS_PER_S else 'not met'})"
        elif name.startswith("camera"):
            extra = f"target ≤ {TARGET_IMAGE_MS:.0f} ms: {'met' if stat['median'] <= TARGET_IMAGE_MS else 'not met'}"
        rows.append([name, fmt_ms(stat), extra])
    lo, hi = REFERENCE_S_PER_100K
    rows.append([f"reference program, 100 k points (measured earlier on this project's machines)", f"{lo * 1000:.0f}–{hi * 1000:.0f}", ""])
    return [f"**Fog on real data, one core** (median of {repeats}; ms)", "",
            markdown_table(["stage", "ms", ""], rows)]  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    return bench_main(argv, "fog_gym.experiments.bench.augment", __doc__, "augment",
                      lambda repeats, quick: bench_augment(repeats), render_augment)


if __name__ == "__main__":
    sys.exit(main())

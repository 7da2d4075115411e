"""Sensors like real ones, what they cost: each option against the same work without it, alternating call by call in
one run (so the machine's drift falls on both sides of each ratio):

* dual LiDAR returns: the fog of one dense-fog FogDrive sweep (Hahner et al., then the return rule) against the
  strongest echo alone — target ≤ 1.2×;
* a sweep that takes time: the LiDAR's sweep (``motion="continuous"``, 16 slices cast from where the ego and the
  vehicles are at each slice's time) against the instantaneous sweep — target ≤ 1.5×;
* camera noise: a full-rig frame (``FogDrive-v0``'s step: four cameras at 1280 × 960, the LiDAR, semantic LiDAR,
  radar and labels) with ``camera_noise="default"`` against one without — target ≤ 1.1×; by day and at night (the
  exact law's table, its laws summed afresh every frame);
* anti-aliasing: the full-rig day frame with ``antialias=True`` against one without — default on at ≤ 1.25×, else
  opt-in with the cost documented.

Medians over ``--repeats`` calls after a warm-up; prints a Markdown table and asserts no timing.

Usage::

    python -m fog_gym.experiments.bench.realism            # 20 repeats
    python -m fog_gym.experiments.bench.realism --quick
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from typing import Any

import numpy as np

from fog_gym.experiments.bench.common import (
    bench_main, fmt_ms, markdown_table, summarize, timed,
)  # fmt: skip

#: The issue's targets: the ratio of each option's cost to the cost without it.
TARGETS = {"dual returns": 1.2, "continuous sweep": 1.5, "camera noise": 1.1, "camera noise, night": 1.1,
           "anti-aliasing": 1.25}


def paired(a: Callable[[], Any], b: Callable[[], Any], repeats: int) -> tuple[dict[str, Any], dict[str, Any], float]:
    """Alternate ``a`` (the plain call) and ``b`` (with the option) ``repeats`` times after a warm-up of each; the
    medians and the ratio of the medians."""
    a()
    b()
    ta, tb = [], []
    for _ in range(repeats):
        ta.append(timed(a)[1])
        tb.append(timed(b)[1])
    sa, sb = summarize(ta), summarize(tb)
    return sa, sb, sb["median"] / sa["median"]


def bench_realism(repeats: int, resolution: tuple[int, int] = (1280, 960)) -> dict[str, Any]:
    from dataclasses import replace

    from fog_gym.channels.packing import pack_points, unpack_points
    from fog_gym.envs.fogdrive import FogDriveEnv
    from fog_gym.fog.models import FogContext, model_for
    from fog_gym.fog.physics import parse_fog
    from fog_gym.sensors import LidarSensor

    results: dict[str, Any] = {"resolution": list(resolution)}
    # the LiDAR: a FogDrive scene a few steps in, its sweep, its fog
    env = FogDriveEnv(town="highway", resolution=(64, 48), cameras=["CAM_FRONT"], labels=None)
    env.reset(seed=0)
    for _ in range(4):
        env.step(env.idle_action)
    scene = env.scene
    prims = env.cameras.primitives(scene, in_view=False)
    cfg = env.config.rig.lidar
    instant = LidarSensor(cfg, env.config.simulation_frequency)
    moving = LidarSensor(replace(cfg, motion="continuous"), env.config.simulation_frequency)
    rng = np.random.default_rng(0)
    results["continuous sweep"] = paired(lambda: instant.measure(scene, prims, rng, 3),
                                         lambda: moving.measure(scene, prims, rng, 3), repeats)  # fmt: skip
    sweep = unpack_points(env._observe(), "LIDAR_TOP")
    dense = parse_fog("dense")
    hahner = model_for("lidar")
    capacity = instant.space().shape[0]  # the channels' own capacities: one row per ray, two for dual
    obs4 = {"LIDAR_TOP": pack_points(sweep, capacity)}
    obs5 = {"LIDAR_TOP_DUAL": pack_points(np.c_[sweep, np.zeros(len(sweep), np.float32)], 2 * capacity)}
    # the counts of points the env gives the fog wrapper for the channels it packed (FogDriveEnv.point_rows)
    rows = {"LIDAR_TOP": len(sweep), "LIDAR_TOP_DUAL": len(sweep)}
    ctx = {m: FogContext(rngs={dense.name: np.random.default_rng(1)}, lidar_returns=m, point_rows=rows)
           for m in ("strongest", "dual")}  # fmt: skip
    results["dual returns"] = paired(lambda: hahner.apply(obs4, "LIDAR_TOP", [dense], ctx["strongest"]),
                                     lambda: hahner.apply(obs5, "LIDAR_TOP_DUAL", [dense], ctx["dual"]), repeats)  # fmt: skip
    results["points"] = int(len(sweep))
    # full-rig frames
    for name, kwargs, light in (("camera noise", {"camera_noise": "default"}, "day"),
                                ("camera noise, night", {"camera_noise": "default"}, "night"),
                                ("anti-aliasing", {"antialias": True}, "day")):  # fmt: skip
        plain = FogDriveEnv(town="highway", resolution=resolution, time_of_day=light)
        option = FogDriveEnv(town="highway", resolution=resolution, time_of_day=light, **kwargs)
        plain.reset(seed=1)
        option.reset(seed=1)
        results[name] = paired(lambda: plain.step(plain.idle_action), lambda: option.step(option.idle_action), repeats)
    return results


def render_realism(results: dict[str, Any], repeats: int) -> list[str]:
    w, h = results["resolution"]
    what = {
        "dual returns": f"LiDAR fog of one dense-fog sweep ({results['points'] // 1000} k points): strongest → dual",
        "continuous sweep": "the LiDAR's sweep: instantaneous → continuous (16 slices)",
        "camera noise": f"full-rig frame, 4 cameras {w} × {h}: noise-free → camera_noise='default'",
        "camera noise, night": f"full-rig night frame, 4 cameras {w} × {h}: noise-free → camera_noise='default'",
        "anti-aliasing": f"full-rig day frame, 4 cameras {w} × {h}: point-sampled → antialias=True",
    }
    rows = []
    for key, label in what.items():
        if key not in results:  # a result file written before this figure existed
            continue
        a, b, ratio = results[key]
        target = TARGETS[key]
        rows.append([label, fmt_ms(a), fmt_ms(b), f"**{ratio:.2f}×**", f"≤ {target:g}×: {'met' if ratio <= target else 'not met'}"])
    return [f"**Sensors like real ones** (median of {repeats}, alternating; ms)", "",
            markdown_table(["option", "without", "with", "ratio", "target"], rows)]  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    def bench(repeats: int, quick: bool) -> dict[str, Any]:
        return bench_realism(repeats, (320, 240) if quick else (1280, 960))

    return bench_main(argv, "fog_gym.experiments.bench.realism", __doc__, "realism", bench, render_realism)


if __name__ == "__main__":
    sys.exit(main())

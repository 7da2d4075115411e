"""Fog stages on one real full-rig frame (``highway``, seed 0): Koschmieder camera fog per 1280×960 image at
each level and for three levels in one pass, Hahner LiDAR fog on 100 k points and on the frame's sweep, the
atmospheric-light estimate, and the full paired frame (4 cameras × 3 levels + 3 LiDAR levels) as
``FogWrapper.fog_channels`` computes it; night against day; fog fields (a bank, ground fog) against homogeneous fog. Each figure is the median over ``--repeats`` calls, after a warm-up
call that compiles the kernels. It prints a Markdown table and asserts no timing.

Usage::

    python -m fog_gym.experiments.bench.fog            # 20 repeats
    python -m fog_gym.experiments.bench.fog --quick    # 3 repeats
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from tqdm import tqdm

from fog_gym.experiments.bench.common import (
    add_common_arguments, finish_meta, fmt_ms, markdown_table, meta_line, repeats_of, run_meta, summarize, timed,
    write_json,
)  # fmt: skip

LEVELS = ("light", "moderate", "dense")


def bench_fog(repeats: int) -> dict[str, Any]:
    """Fog stages on one real full-rig frame: camera fog per 1280×960 image, LiDAR fog per 100 k points, and the
    full paired frame (4 cameras × 3 levels + 3 LiDAR levels) as ``FogWrapper`` computes it."""
    from fog_gym.envs.fogdrive import FogDriveEnv
    from fog_gym.fog import atmospheric_light, fog_image, fog_images, fog_lidar, parse_fog
    from fog_gym.dataset.packing import unpack_points
    from fog_gym.wrappers import FogWrapper

    env = FogWrapper(FogDriveEnv(town="highway"), list(LEVELS))
    obs, _ = env.reset(seed=0)
    base = env.unwrapped
    K = base.intrinsics["CAM_FRONT"]
    rgb, depth = base.frames["CAM_FRONT"].rgb, base.frames["CAM_FRONT"].depth
    airlight = env.airlight["CAM_FRONT"]
    clean_lidar = base.points["LIDAR_TOP"]
    rng = np.random.default_rng(0)
    r = rng.uniform(1.5, 120.0, 100_000)
    az, el = rng.uniform(-np.pi, np.pi, r.size), rng.uniform(-0.35, 0.09, r.size)
    cloud = np.c_[r * np.cos(el) * np.cos(az), r * np.cos(el) * np.sin(az), r * np.sin(el), np.exp(-0.004 * r)]
    cloud = cloud.astype(np.float32)
    alphas = [parse_fog(lv).alpha for lv in LEVELS]
    calls: dict[str, Callable[[], Any]] = {
        **{f"camera fog, 1 image, {lv}": (lambda a=parse_fog(lv).alpha: fog_image(rgb, depth, K, a, airlight))
           for lv in LEVELS},
        "camera fog, 1 image, 3 levels in one pass": lambda: fog_images(rgb, depth, K, alphas, airlight),
        "LiDAR fog, 100 k points, dense": lambda: fog_lidar(cloud, parse_fog("dense"), rng),
        f"LiDAR fog, this frame's sweep ({len(clean_lidar)} points), dense": lambda: fog_lidar(
            clean_lidar, parse_fog("dense"), rng),
        "atmospheric light estimate, 1 image (once per episode)": lambda: atmospheric_light(rgb),
        "**full paired frame: 4 cameras × 3 levels + 3 LiDAR levels**": lambda: env.fog_channels(obs),
    }  # fmt: skip
    for fn in calls.values():  # warm-up (compiles)
        fn()
    stats = {}
    for name, fn in tqdm(calls.items(), desc="fog stages", unit="stage", file=sys.stderr):
        stats[name] = summarize([timed(fn)[1] for _ in range(repeats)])
    env.close()
    assert unpack_points(obs, "LIDAR_TOP_FOG_DENSE").shape == clean_lidar.shape
    return {"stages": stats, "lidar_points": int(len(clean_lidar)), "night": bench_night_fog(repeats),
            "fields": bench_fields(repeats),
            "targets": {"LiDAR 100k": 5.0, "paired frame": 20.0, "night / day": 2.0, "field frame": 1.5,
                        "field LiDAR 100k": 2.0}}  # fmt: skip


def bench_night_fog(repeats: int, town: str = "highway") -> dict[str, Any]:
    """Night against day, timed in alternation on the same seed: the full paired fog frame (``fog_channels``, where
    the night adds the glow of lit fog), and a whole ``env.step`` with dense fog in place (render, fog, labels)."""
    from fog_gym.envs.fogdrive import FogDriveEnv
    from fog_gym.wrappers import FogWrapper

    paired, dense = {}, {}
    for tod in ("day", "night"):
        env = FogWrapper(FogDriveEnv(town=town, time_of_day=tod), list(LEVELS))
        obs, _ = env.reset(seed=0)
        paired[tod] = (env, obs)
        dense[tod] = FogWrapper(FogDriveEnv(town=town, time_of_day=tod), "dense")
        dense[tod].reset(seed=0)
    times: dict[str, list[float]] = {k: [] for k in ("paired day", "paired night", "dense step day", "dense step night")}
    for k in tqdm(range(repeats + 1), desc="night vs day fog", unit="frame", file=sys.stderr):
        for tod in ("day", "night"):
            env, obs = paired[tod]
            ms = timed(env.fog_channels, obs)[1]
            step = dense[tod]
            ms_step = timed(step.step, step.unwrapped.idle_action)[1]
            if k:  # the first round warms up
                times[f"paired {tod}"].append(ms)
                times[f"dense step {tod}"].append(ms_step)
    for env, _ in paired.values():
        env.close()
    for env in dense.values():
        env.close()
    stats = {k: summarize(v) for k, v in times.items()}
    return {"stats": stats, "paired ratio": stats["paired night"]["median"] / stats["paired day"]["median"],
            "dense ratio": stats["dense step night"]["median"] / stats["dense step day"]["median"]}  # fmt: skip


def bench_fields(repeats: int, town: str = "highway") -> dict[str, Any]:
    """Fog fields against homogeneous fog, timed in alternation on the same seed: a whole ``env.step`` with the fog in
    place (full rig: render, camera and LiDAR fog, labels) and the LiDAR fog on 100 k points. The ratios are the median
    over rounds of each round's ratio to homogeneous fog."""
    from fog_gym.envs.fogdrive import FogDriveEnv
    from fog_gym.fog import fog_lidar, parse_fog
    from fog_gym.fog.fields import FogBank, HeightFog
    from fog_gym.fog.depth import field_pose
    from fog_gym.fog.lidar_field import fog_lidar_field
    from fog_gym.wrappers import FogWrapper

    fields = {"homogeneous (dense)": parse_fog("dense"), "FogBank 50 m, 60 m ahead, 100 m long": FogBank(50.0, 60.0, 100.0),
              "FogBank 50 m, the ego inside (from −50 m, 100 m long)": FogBank(50.0, -50.0, 100.0),
              "HeightFog 50 m, scale height 5 m": HeightFog(50.0, 5.0)}  # fmt: skip
    envs = {name: FogWrapper(FogDriveEnv(town=town), f) for name, f in fields.items()}
    for env in envs.values():
        env.reset(seed=0)
    rng = np.random.default_rng(0)
    r = rng.uniform(1.5, 120.0, 100_000)
    az, el = rng.uniform(-np.pi, np.pi, r.size), rng.uniform(-0.35, 0.09, r.size)
    cloud = np.c_[r * np.cos(el) * np.cos(az), r * np.cos(el) * np.sin(az), r * np.sin(el), np.exp(-0.004 * r)]
    cloud = cloud.astype(np.float32)
    pose = field_pose(np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, 1.0, 1.8], [0, 0, 0, 1.0]]), (0.0, 0.0, 0.0))

    def lidar(field):
        return (lambda: fog_lidar(cloud, field, rng)) if field.is_homogeneous else \
            (lambda: fog_lidar_field(cloud, field, rng, pose))  # fmt: skip

    steps: dict[str, list[float]] = {k: [] for k in fields}
    points: dict[str, list[float]] = {k: [] for k in fields}
    for k in tqdm(range(repeats + 1), desc="fog fields vs homogeneous", unit="round", file=sys.stderr):
        for name, field in fields.items():
            env = envs[name]
            ms = timed(env.step, env.unwrapped.idle_action)[1]
            ms_points = timed(lidar(field))[1]
            if k:  # the first round warms up (and compiles)
                steps[name].append(ms)
                points[name].append(ms_points)
    for env in envs.values():
        env.close()
    base = next(iter(fields))
    step_stats = {k: summarize(v) for k, v in steps.items()}
    point_stats = {k: summarize(v) for k, v in points.items()}
    # each round's ratio to the homogeneous call of the same round, then their median: a slow phase of the machine
    # moves both calls of a round
    return {"step": step_stats, "points": point_stats,
            "step ratio": {k: float(np.median(np.divide(v, steps[base]))) for k, v in steps.items()},
            "points ratio": {k: float(np.median(np.divide(v, points[base]))) for k, v in points.items()}}  # fmt: skip


def render_fog(fog: dict[str, Any], repeats: int) -> list[str]:
    rows = [[name, fmt_ms(stat)] for name, stat in fog["stages"].items()]
    lines = [f"## Fog (full rig, highway, seed 0): ms, median (p25–p75), {repeats} repeats", "",
             markdown_table(["stage", "ms"], rows), "",
             "Targets: LiDAR fog on 100 k points ≤ 5 ms; full paired frame ≤ 20 ms (2-core CPU)."]  # fmt: skip
    night = fog.get("night")
    if night:
        st = night["stats"]
        lines += ["", "### Night against day (same seed, timed in alternation)", "",
                  markdown_table(["", "day ms", "night ms", "night / day"], [
                      ["full paired fog frame (4 cameras × 3 levels + 3 LiDAR levels)", fmt_ms(st["paired day"]),
                       fmt_ms(st["paired night"]), f"**{night['paired ratio']:.2f}×**"],
                      ["env.step, dense fog in place (render, fog, labels)", fmt_ms(st["dense step day"]),
                       fmt_ms(st["dense step night"]), f"**{night['dense ratio']:.2f}×**"]]), "",
                  "Target: night ≤ 2× day for both (the glow of lit fog is the night's addition)."]  # fmt: skip
    fields = fog.get("fields")
    if fields:
        lines += ["", "### Fog fields against homogeneous fog (same seed, timed in alternation)", "",
                  markdown_table(["fog", "env.step ms (full rig, in place)", "× homogeneous", "LiDAR fog, 100 k points, ms",
                                  "× homogeneous"],
                                 [[name, fmt_ms(fields["step"][name]), f"**{fields['step ratio'][name]:.2f}×**",
                                   fmt_ms(fields["points"][name]), f"**{fields['points ratio'][name]:.2f}×**"]
                                  for name in fields["step"]]), "",
                  "× homogeneous: the median over rounds of each round's ratio (a round times every fog once). Targets: a "
                  "full-rig frame with a bank or ground fog ≤ 1.5× the homogeneous frame; LiDAR fog on 100 k points ≤ 2× "
                  "homogeneous."]  # fmt: skip
    return lines


def build_parser(prog: str = "python -m fog_gym.experiments.bench.fog") -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog=prog, description="Milliseconds of camera fog, LiDAR fog and the full "
                                     "paired fog frame on one full-rig frame. It prints Markdown and asserts nothing.")
    return add_common_arguments(parser)


def main(argv: list[str] | None = None, prog: str = "python -m fog_gym.experiments.bench.fog") -> int:
    args = build_parser(prog).parse_args(argv)
    repeats = repeats_of(args)
    meta, t0 = run_meta(repeats=repeats, quick=args.quick), time.perf_counter()
    fog = bench_fog(repeats)
    finish_meta(meta, t0)
    print("\n".join(render_fog(fog, repeats)) + f"\n\n{meta_line(meta)}")
    write_json(args.json, {"meta": meta, "fog": fog})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Sensor timings of FogDrive-v0. This script only reports numbers and never asserts a timing.

1. **Point sensors** on the ``highway`` town with packed traffic (60 vehicles, 5 lanes, density 12: ~50 within
   the LiDAR's range; no cameras), over ``--repeats`` steps of an episode (the env is stepped, untimed, between
   measurements): the LiDAR, the semantic LiDAR and the radar each alone (a ``PointSensors`` holding that sensor
   only), and all three through the env's ``point_sensors.measure``, against the target of 10 ms per tick for
   all three. The same calls are then timed with 500 extra boxes appended to the primitives, all with their
   centres 310–600 m from the ego (every point of them beyond 300 m, out of every sensor's reach), in
   alternation with the plain calls. Their cost must not grow with such boxes, so the ratio should stay near 1.
2. **Ground truth** (``env.ground_truth()``) for the four 1280×960 cameras, both visibility rules, same traffic.
3. **Night vs day cameras**: ``CameraRig.render`` of the full rig by day and by night on the same scenes,
   timed in alternation (``--night-figure PNG`` draws the bar chart); ``--night-phases`` adds a night frame's
   process CPU time by phase against the day and the *raster floor* (the night scene drawn unlit).

Usage::

    python -m fog_gym.experiments.bench.sensors                  # 20 timed steps each
    python -m fog_gym.experiments.bench.sensors --quick          # 3
    python -m fog_gym.experiments.bench.sensors --night-only --night-figure docs/images/night_bench.png
    python -m fog_gym.experiments.bench.sensors --night-only --night-phases --repeats 10
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from fog_gym.experiments.bench.common import (
    CHANNEL_LABELS, POINT_SENSOR_TRAFFIC, WARMUP_STEPS, EpisodeKeeper, add_common_arguments, counts_summary,
    finish_meta, fmt_ms, markdown_table, meta_line, repeats_of, run_meta, sensor_tick, summarize, timed, write_json,
)  # fmt: skip

FAR_BOXES = 500  # extra boxes out of every sensor's reach, for the out-of-range check
FAR_RADIUS = (310.0, 600.0)  # their centres' distance from the ego [m]; a box's nearest point stays beyond 300 m
POINT_SENSORS_TARGET_MS = 10.0  # LiDAR + semantic LiDAR + radar, per tick


# -- point sensors on a dense highway ------------------------------------------------------------------


def far_boxes(template: Any, ego_xy: np.ndarray, rng: np.random.Generator, n: int) -> Any:
    """``n`` car-sized boxes (``Primitives``) on the ground with their centres ``FAR_RADIUS`` from ``ego_xy``.

    Their nearest points lie beyond 300 m from the ego (a car box reaches under 3 m from its centre), out of the
    LiDARs' 120 m and of the radar's rays (under 303 m from the bumper). Static world (``insts`` 0), car tag.
    """
    from fog_gym.world.primitives import Primitives

    r = rng.uniform(*FAR_RADIUS, n)
    a = rng.uniform(0.0, 2.0 * np.pi, n)
    halves = np.tile([2.4, 1.0, 0.8], (n, 1))
    centers = np.c_[ego_xy[0] + r * np.cos(a), ego_xy[1] + r * np.sin(a), halves[:, 2]]
    tag = template.tags[template.insts > 0][:1]  # a vehicle's tag where there is one
    return Primitives.coerce({
        "centers": centers, "halves": halves, "yaws": rng.uniform(-np.pi, np.pi, n), "colors": np.full((n, 3), 0.5),
        "tags": np.full(n, tag[0] if tag.size else 14), "insts": np.zeros(n), "emissive": np.zeros(n, bool),
    })  # fmt: skip


def solo_point_sensors(env: Any) -> dict[str, Any]:
    """One ``PointSensors`` per point sensor of the env's rig, holding that sensor alone (no cameras)."""
    from dataclasses import replace

    from fog_gym.sensors import PointSensors

    rig, f = env.config.rig, env.point_sensors.simulation_frequency
    kinds = ("lidar", "semantic_lidar", "radar")
    solos = {}
    for kind in kinds:
        if getattr(rig, kind) is not None:
            solo = PointSensors(replace(rig, cameras=(), **{k: None for k in kinds if k != kind}), f)
            solos[solo.channels[0]] = solo
    return solos


def point_sensor_calls(env: Any, scene: Any, prims: dict[str, np.ndarray], solos: dict[str, Any]) -> dict[str, Callable[[], Any]]:
    """One zero-argument call per sensor alone (its solo ``PointSensors.measure``), and ``"all"`` = the env's."""
    tick = sensor_tick(env)
    rng = np.random.default_rng(tick)  # the bench's own draws: the env's sensor stream is left to env.step
    calls: dict[str, Callable[[], Any]] = {
        ch: (lambda s=solo: s.measure(scene, prims, rng, tick)) for ch, solo in solos.items()
    }
    calls["all"] = lambda: env.point_sensors.measure(scene, prims, rng, tick)
    return calls


def rays_per_tick(env: Any) -> dict[str, int]:
    from fog_gym.sensors.lidar import lidar_directions
    from fog_gym.dataset.packing import LIDAR, RADAR, SEMANTIC_LIDAR

    rig, f = env.config.rig, env.point_sensors.simulation_frequency
    out = {}
    for name, cfg in ((LIDAR, rig.lidar), (SEMANTIC_LIDAR, rig.semantic_lidar)):
        if cfg is not None:
            out[name] = int(lidar_directions(cfg, f).shape[0])
    if rig.radar is not None:
        out[RADAR] = rig.radar.rays_per_tick(f)
    return out


def bench_point_sensors(repeats: int) -> dict[str, Any]:
    """Point sensors on the ``highway`` town with ``DENSE_VEHICLES`` vehicles, without and with far boxes.

    The env has no cameras (the sensors only need ``cameras.primitives``, which does not depend on the cameras).
    After the warm-up, each repeat steps the env (untimed), then times every call on the plain primitives and on
    the primitives plus ``FAR_BOXES`` far boxes, the two in alternating order so both see the same load.
    """
    from fog_gym.envs.fogdrive import FogDriveEnv

    # packed traffic (5 lanes, density 12) so that ~50 vehicles are within the LiDAR's 120 m, as the target asks
    env = FogDriveEnv(town="highway", cameras=[], highway_config=POINT_SENSOR_TRAFFIC)
    action = env.idle_action
    box_rng = np.random.default_rng(1234)
    solos = solo_point_sensors(env)
    env.reset(seed=0)
    for _ in range(WARMUP_STEPS):
        env.step(action)
    warm_prims = env.cameras.primitives(env.scene)
    for variant in (warm_prims, concat_prims(warm_prims, far_boxes(warm_prims, env.scene.ego_pose[:2], box_rng, 1))):
        for call in point_sensor_calls(env, env.scene, variant, solos).values():
            call()
    keep = EpisodeKeeper(env, {})
    keys = [*env.point_sensors.channels, "all"]
    t: dict[str, dict[str, list[float]]] = {v: {k: [] for k in keys} for v in ("near", "far")}
    counts: dict[str, list[int]] = {"vehicles": [], "within_lidar_range": [], "prims": [], "prims_far": [],
                                    **{f"points:{c}": [] for c in env.point_sensors.channels}}  # fmt: skip
    same_points: dict[str, bool] = {}
    lidar_range = env.config.rig.lidar.range if env.config.rig.lidar is not None else 120.0
    for i in tqdm(range(repeats), desc="point sensors", unit="step", leave=False):
        _, _, terminated, truncated, _ = env.step(action)
        scene = env.scene
        prims = env.cameras.primitives(scene)
        ego_xy = np.asarray(scene.ego_pose[:2])
        with_far = concat_prims(prims, far_boxes(prims, ego_xy, box_rng, FAR_BOXES))
        variants = [("near", prims), ("far", with_far)]
        sweeps: dict[str, dict[str, np.ndarray]] = {}
        for variant, p in variants if i % 2 == 0 else variants[::-1]:
            for key, call in point_sensor_calls(env, scene, p, solos).items():
                out, ms = timed(call)
                t[variant][key].append(ms)
                if key == "all":
                    sweeps[variant] = out
        for ch, pts in sweeps["near"].items():
            counts[f"points:{ch}"].append(len(pts))
            # same seed for both variants: out-of-range boxes must not change a single point
            same_points[ch] = same_points.get(ch, True) and np.array_equal(pts, sweeps["far"][ch])
        others = scene.vehicles.ids != scene.ego_id
        dist = np.hypot(*(scene.vehicles.centers[others, :2] - ego_xy).T)
        counts["vehicles"].append(len(scene.vehicles.ids))
        counts["within_lidar_range"].append(int(np.count_nonzero(dist <= lidar_range)))
        counts["prims"].append(len(prims))
        counts["prims_far"].append(len(with_far))
        keep.after_step(terminated, truncated)
    result = {
        "label": f"highway, {POINT_SENSOR_TRAFFIC}, no cameras",
        "lidar_range": lidar_range, "far_boxes": FAR_BOXES, "far_radius": list(FAR_RADIUS),
        "target_ms": POINT_SENSORS_TARGET_MS, "rays_per_tick": rays_per_tick(env), "resets": keep.resets,
        "same_points_with_far_boxes": same_points,
        "near": {k: summarize(v) for k, v in t["near"].items()}, "far": {k: summarize(v) for k, v in t["far"].items()},
        "counts": counts_summary(counts),
    }  # fmt: skip
    env.close()
    return result


def concat_prims(*groups: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    from fog_gym.world.primitives import Primitives

    return Primitives.concat(*groups)


def render_point_sensors(ps: dict[str, Any], repeats: int) -> list[str]:
    c = ps["counts"]

    def count(key: str) -> str:
        return f"{c[key]['median']:.0f} ({c[key]['min']}–{c[key]['max']})" if key in c else "—"

    out = [
        f"## Point sensors per tick ({ps['label']}): ms, median (p25–p75), {repeats} steps",
        "",
        f"Vehicles (incl. ego): {count('vehicles')}; other vehicles within the LiDAR range ({ps['lidar_range']:.0f} m) "
        f"of the ego: {count('within_lidar_range')}; primitives: {count('prims')} (props within 600 m + vehicles), "
        f"{count('prims_far')} with the {ps['far_boxes']} far boxes (centres {ps['far_radius'][0]:.0f}–"
        f"{ps['far_radius'][1]:.0f} m from the ego). Episode resets while timing (untimed): {ps['resets']}.",
        "",
    ]
    rows = []
    near, far, target = ps["near"], ps["far"], ps["target_ms"]
    for key in [k for k in near if k != "all"]:
        rows.append([f"{CHANNEL_LABELS.get(key, key)} `{key}` alone", f"{ps['rays_per_tick'].get(key, 0)}",
                     count(f"points:{key}"), fmt_ms(near[key]), fmt_ms(far[key]),
                     f"{far[key]['median'] / near[key]['median']:.2f}×", ""])  # fmt: skip
    alone = sum(near[k]["median"] for k in near if k != "all")
    rows.append(["  sum of the sensors alone (medians)", "", "", f"{alone:.2f}",
                 f"{sum(far[k]['median'] for k in far if k != 'all'):.2f}", "", ""])  # fmt: skip
    ok = "met" if near["all"]["median"] <= target else "**missed**"
    ratio = far["all"]["median"] / near["all"]["median"]
    rows.append(["**all three: `point_sensors.measure`**", f"{sum(ps['rays_per_tick'].values())}", "",
                 f"**{fmt_ms(near['all'])}**", fmt_ms(far["all"]), f"**{ratio:.2f}×**",
                 f"≤ {target:.0f} ms: {ok}"])  # fmt: skip
    out.append(markdown_table(
        ["sensor", "rays / tick", "points / tick", "ms", f"ms, + {ps['far_boxes']} boxes > 300 m", "ratio far / plain",
         "target"], rows))  # fmt: skip
    same = ps.get("same_points_with_far_boxes", {})
    differ = [c for c, ok in same.items() if not ok]
    out += ["", "The far boxes lie out of every sensor's reach, so the ratio should stay near 1: the ray caster "
            "drops boxes beyond its range before binning them. With the same seed, the sweeps with the far boxes "
            + ("are identical to those without, in every channel and step." if same and not differ else
               f"**differ** from those without in {', '.join(differ)}." if differ else "were not compared.")]
    return out


# -- ground truth --------------------------------------------------------------------------------------


def bench_labels(repeats: int) -> dict[str, Any]:
    """Ground truth for all four 1280×960 cameras (``env.ground_truth()``), both visibility rules, packed traffic."""
    from fog_gym.envs.fogdrive import FogDriveEnv

    out: dict[str, Any] = {}
    for rule in ("lidar", "camera"):
        env = FogDriveEnv(town="highway", visibility=rule, highway_config=POINT_SENSOR_TRAFFIC)
        env.reset(seed=0)
        samples, boxes, near = [], [], []
        for _ in tqdm(range(repeats + WARMUP_STEPS), desc=f"labels ({rule})", unit="frame", leave=False, file=sys.stderr):
            _, _, terminated, truncated, _ = env.step(env.idle_action)
            if terminated or truncated:
                env.reset()
            gt, ms = timed(env.ground_truth)
            samples.append(ms)
            boxes.append(sum(len(b["vehicle_ids"]) for b in gt["boxes_2d"].values()))
            v = env.scene.vehicles
            near.append(int((np.hypot(*(v.centers[1:, :2] - np.asarray(env.scene.ego_pose[:2])).T) <= 120.0).sum()))
        out[rule] = {"ms": summarize(samples[WARMUP_STEPS:]), "boxes_2d": float(np.median(boxes)),
                     "vehicles_within_120m": float(np.median(near))}  # fmt: skip
        env.close()
    return out


def render_labels(lab: dict[str, Any], repeats: int) -> list[str]:
    rows = [[f"`visibility=\"{rule}\"`", f"{r['vehicles_within_120m']:.0f}", f"{r['boxes_2d']:.0f}", fmt_ms(r["ms"])]
            for rule, r in lab.items()]  # fmt: skip
    return [f"## Ground truth, 4 cameras × 1280×960 (highway, {POINT_SENSOR_TRAFFIC}): ms per frame, {repeats} frames", "",
            markdown_table(["rule", "vehicles within 120 m", "2D boxes (all cameras)", "ms"], rows), "",
            "Target: ≤ 2 ms per frame with ~50 vehicles."]  # fmt: skip


# -- night vs day camera rendering ---------------------------------------------------------------------


def night_twin(scene: Any) -> Any:
    """The same instant at night: same geometry, night lighting and lamp colours (street lamps, beams, exposure)."""
    import dataclasses

    from fog_gym.world.scene import Lighting, vehicle_primitives

    light = Lighting.for_time_of_day("night", np.random.default_rng(0))
    return dataclasses.replace(scene, lighting=light,
                               primitives=vehicle_primitives(scene.vehicles, True, exclude_id=scene.ego_id))


def bench_night(town: str, repeats: int) -> dict[str, Any]:
    """``CameraRig.render`` of the full rig by day and by night on the same scenes, timed in alternation."""
    from fog_gym.envs.fogdrive import FogDriveEnv

    env = FogDriveEnv(town=town, time_of_day="day", labels=None)
    action = env.idle_action
    env.reset(seed=0)
    day, night, lights = [], [], []
    for k in tqdm(range(repeats + WARMUP_STEPS), desc="night vs day cameras", file=sys.stderr):
        env.step(action)
        scene = env.scene
        twin = night_twin(scene)
        prims_day, prims_night = env.cameras.primitives(scene), env.cameras.primitives(twin)
        order = [(scene, prims_day, day), (twin, prims_night, night)]
        for sc, pr, sink in order if k % 2 == 0 else order[::-1]:
            _, ms = timed(env.cameras.render, sc, pr)
            if k >= WARMUP_STEPS:
                sink.append(ms)
        if k >= WARMUP_STEPS:
            lights.append(len(env.cameras.night_lights(twin)[1]))
    env.close()
    d, n = summarize(day), summarize(night)
    return {"day": d, "night": n, "ratio": n["median"] / d["median"], "lights": summarize([float(x) for x in lights]),
            "label": "full rig: 4 × 1280×960"}


def cpu_timed(fn: Callable[..., Any], *args: Any, **kwargs: Any) -> tuple[Any, float]:
    """Call ``fn`` and return ``(result, process CPU milliseconds)``: every thread's time, so steady under load."""
    t0 = time.process_time()
    out = fn(*args, **kwargs)
    return out, (time.process_time() - t0) * 1e3


def bench_night_phases(town: str, repeats: int) -> dict[str, Any]:
    """Process CPU time of a full-rig night frame by phase, against the day frame and against the *raster floor*
    (the same night scene drawn unlit: the rasteriser's own cost with no lighting, exposure or encoding).

    The night frame is what ``CameraRig.render`` does for a rig of one resolution: ``night_lights`` (lamp heads,
    lights in reach, the ground light window with the low beams), then ``render_night`` (light set-up, exposure,
    lit render, lamp heads). Alternating order, same scenes."""
    from fog_gym.envs.fogdrive import FogDriveEnv
    from fog_gym.render.lights import render_night as lit
    from fog_gym.render.raster import render
    from fog_gym.render.surface import albedo_lut, tiled_surface
    from fog_gym.world.scenery import SURFACE_TAGS

    env = FogDriveEnv(town=town, time_of_day="day", labels=None)
    cams = env.cameras
    if len(cams._groups) != 1:
        raise ValueError("the phase breakdown times a rig whose cameras share one resolution")
    (width, height), group = cams._groups[0]
    env.reset(seed=0)
    samples: dict[str, list[float]] = {}
    for k in tqdm(range(repeats + WARMUP_STEPS), desc="night phases", file=sys.stderr):
        env.step(env.idle_action)
        scene = env.scene
        twin = night_twin(scene)
        light = twin.lighting
        mats = np.array([cams.world_to_camera(twin, c.name) for c in group])
        ks = np.array([[q[0, 0], q[1, 1], q[0, 2], q[1, 2]] for q in (cams.intrinsics[c.name] for c in group)])
        prims_day, prims = cams.primitives(scene), cams.primitives(twin)
        frame: dict[str, float] = {}

        def night() -> None:
            (heads, lights, ground), frame["lights and ground maps"] = cpu_timed(cams.night_lights, twin)
            lit(mats[:, :3, :3], mats[:, :3, 3], ks, width, height, cams.far, prims, tiled_surface(twin.static),
                albedo_lut(), SURFACE_TAGS, light.sky_horizon, light.sky_zenith, lights, ground, heads,
                timings=frame)  # fmt: skip

        def floor() -> None:
            render(mats[:, :3, :3], mats[:, :3, 3], ks, width, height, cams.far, prims, tiled_surface(twin.static),
                   albedo_lut(), SURFACE_TAGS, light.sky_horizon, light.sky_zenith, np.array([0.0, 0.0, -1.0]),
                   1.0, 0.0)  # fmt: skip

        runs = [("day", lambda: cams.render(scene, prims_day)), ("night", night), ("raster floor", floor)]
        for name, fn in runs if k % 2 == 0 else runs[::-1]:
            _, ms = cpu_timed(fn)
            if k >= WARMUP_STEPS:
                samples.setdefault(name, []).append(ms)
        if k >= WARMUP_STEPS:
            for phase, ms in frame.items():
                samples.setdefault(phase, []).append(ms)
    env.close()
    return {name: summarize(v) for name, v in samples.items()}


def render_night_phases(res: dict[str, Any], repeats: int) -> list[str]:
    day = res["day"]["median"]
    rows = [[name, f"{res[name]['median']:.1f}", f"{res[name]['median'] / day:.2f}"]
            for name in ("day", "raster floor", "night", "lights and ground maps", "light set-up", "exposure",
                         "lit render", "lamp heads")]  # fmt: skip
    return [f"### Night frame by phase (full rig, process CPU ms, medians of {repeats} frames)", "",
            markdown_table(["", "CPU ms", "× day"], rows), "",
            "raster floor: the night scene drawn unlit (no lighting, exposure or encoding); the night's phases add up "
            "to its total."]  # fmt: skip


def render_night(res: dict[str, Any], repeats: int) -> list[str]:
    return [
        f"### Night vs day camera rendering ({res['label']}, `CameraRig.render`, {repeats} frames, alternating)",
        "",
        markdown_table(["", "day", "night", "night / day"],
                       [["ms", fmt_ms(res["day"]), fmt_ms(res["night"]), f"{res['ratio']:.2f}×"]]),
        "",
        f"Lights in a night frame (street lamps + low beams within reach): median {res['lights']['median']:.0f}.",
    ]


def night_figure(res: dict[str, Any], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(4.5, 3.2), dpi=120)
    keys = ("day", "night")
    med = [res[k]["median"] for k in keys]
    err = [[res[k]["median"] - res[k]["p25"] for k in keys], [res[k]["p75"] - res[k]["median"] for k in keys]]
    ax.bar(keys, med, yerr=err, color=["#e0b040", "#304070"], capsize=6)
    ax.set_ylabel("CameraRig.render [ms] (median, p25–p75)")
    ax.set_title(f"{res['label']}: night / day = {res['ratio']:.2f}×", fontsize=9)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)


def build_parser(prog: str = "python -m fog_gym.experiments.bench.sensors") -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=prog,
        description="Milliseconds of the point sensors (each alone and all three) on a 50-vehicle highway, with and "
        "without 500 boxes out of range; ground truth for 4 × 1280×960 cameras under both visibility rules; the "
        "full rig's cameras by night against by day. It prints Markdown tables and asserts nothing.",
    )
    add_common_arguments(parser)
    parser.add_argument("--town", default="highway", help="town of the night vs day comparison (default highway)")
    parser.add_argument("--night-only", action="store_true",
                        help="only time the full rig's cameras by night against by day (same scenes)")
    parser.add_argument("--night-phases", action="store_true",
                        help="also break a night frame's CPU time down by phase, against the day and the raster floor")
    parser.add_argument("--night-figure", type=Path, default=None, metavar="PNG",
                        help="write the night vs day camera bar chart to PNG")
    return parser


def main(argv: list[str] | None = None, prog: str = "python -m fog_gym.experiments.bench.sensors") -> int:
    args = build_parser(prog).parse_args(argv)
    repeats = repeats_of(args)
    meta, t0 = run_meta(repeats=repeats, quick=args.quick), time.perf_counter()
    results: dict[str, Any] = {"meta": meta}
    if not args.night_only:
        results["point_sensors"] = bench_point_sensors(repeats)
        results["labels"] = bench_labels(repeats)
    results["night"] = night = bench_night(args.town, repeats)
    if args.night_phases:
        results["night_phases"] = bench_night_phases(args.town, repeats)
    if args.night_figure is not None:
        night_figure(night, args.night_figure)
    finish_meta(meta, t0)
    sections = [] if args.night_only else [render_point_sensors(results["point_sensors"], repeats),
                                           render_labels(results["labels"], repeats)]  # fmt: skip
    sections.append(render_night(night, repeats))
    if args.night_phases:
        sections.append(render_night_phases(results["night_phases"], repeats))
    print("\n\n".join("\n".join(s) for s in sections) + f"\n\n{meta_line(meta)}")
    write_json(args.json, results)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Every fog-gym benchmark in one run (what ``fog-gym bench`` and ``./dev bench`` print). It only reports numbers
and never asserts a timing. Each concern has its own module, runnable alone (``python -m
fog_gym.experiments.bench.<name>``):

* :mod:`~fog_gym.experiments.bench.env`: FogDrive-v0 per stage (traffic, scene, cameras, point sensors, full step) for the full and
  the RL rig against a bare highway-env step; bare highway-env profiled; the ``FogDriveRL-v0`` preset;
* :mod:`~fog_gym.experiments.bench.sensors`: the point sensors alone and with 500 out-of-range boxes, ground truth, night vs day
  cameras;
* :mod:`~fog_gym.experiments.bench.fog`: camera and LiDAR fog, and the full paired fog frame;
* :mod:`~fog_gym.experiments.bench.dataset`: the recorder against the PNG-encoder bound, ``fog-gym generate`` with 1 and 2 workers;
* :mod:`~fog_gym.experiments.bench.geometry`: the world of meshes against the box world in the same run (day and night
  steps, point sensors, the pixel RL vector env, memory);
* :mod:`~fog_gym.experiments.bench.augment`: fog on real data per core (a KITTI-sized scan per level and in a bank, a
  KITTI-sized image with depth completion) beside the reference fog program's cost;
* :mod:`~fog_gym.experiments.bench.realism`: sensors like real ones against the same work without them (dual LiDAR
  returns, a sweep that takes time, camera noise, anti-aliasing), each a ratio measured in one run;
* :mod:`~fog_gym.experiments.bench.speed` (with ``--speed``, ``--previous DIR`` or ``--scaling``): the vector envs and
  the sums of fog fields, against another install in one run with ``--previous`` (child processes in turn, the
  median of per-round ratios; the sums over homogeneous fog alternating in one process), and scaling over cores.

Usage::

    fog-gym bench                  # 20 timed frames per configuration, town "highway"
    fog-gym bench --quick          # smoke run (3 frames, 3 profiled steps)
    fog-gym bench --town merge --repeats 50 --json out/bench.json
    fog-gym bench --night-only --night-figure docs/images/night_bench.png
    fog-gym bench --previous ../fog-gym-prev --rounds 3   # also the speed figures against another install
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from fog_gym.experiments.bench import augment as bench_augment
from fog_gym.experiments.bench import realism as bench_realism
from fog_gym.experiments.bench import dataset as bench_dataset
from fog_gym.experiments.bench import env as bench_env
from fog_gym.experiments.bench import fog as bench_fog
from fog_gym.experiments.bench import geometry as bench_geometry
from fog_gym.experiments.bench import sensors as bench_sensors
from fog_gym.experiments.bench import speed as bench_speed
from fog_gym.experiments.bench.common import add_common_arguments, finish_meta, repeats_of, run_meta, write_json
from fog_gym.world.towns import TOWNS


def build_parser(prog: str = "fog-gym bench") -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=prog,
        description="Per-stage milliseconds of FogDrive-v0 (traffic step, scene build, cameras batched and alone, "
        "point sensors, full env.step) for the full 4×1280×960 rig and a 1×128×128 RL rig (both with LiDAR, "
        "semantic LiDAR and radar), against a bare highway-env step; the point sensors alone on a 50-vehicle "
        "highway, with and without 500 boxes out of range; fog, ground truth, recording, the RL preset, night vs "
        "day cameras. It runs the env, sensors, fog and dataset benchmarks (python -m fog_gym.experiments.bench.<name>), prints Markdown "
        "tables and asserts nothing. With --speed or --previous DIR also the vector envs and the sums of fog fields "
        "(against another install in one run), with --scaling generate and the sharded vector env over cores.",
    )
    add_common_arguments(parser)
    parser.add_argument("--town", choices=TOWNS, default="highway", help="fog-gym town (default highway)")
    parser.add_argument("--night-only", action="store_true",
                        help="only time the full rig's cameras by night against by day (same scenes)")
    parser.add_argument("--night-figure", type=Path, default=None, metavar="PNG",
                        help="write the night vs day camera bar chart to PNG")
    parser.add_argument("--speed", action="store_true",
                        help="also the speed figures: the vector envs and the sums of fog fields "
                             "(python -m fog_gym.experiments.bench.speed)")  # fmt: skip
    parser.add_argument("--previous", metavar="DIR", default=None,
                        help="a checkout of another release: the speed figures against it, in one run (implies --speed)")
    parser.add_argument("--rounds", type=int, default=3, help="rounds of each speed figure per install (default 3)")
    parser.add_argument("--scaling", action="store_true", help="also generate and the sharded vector env over 1 … N cores")
    return parser


def main(argv: list[str] | None = None, prog: str = "fog-gym bench") -> int:
    parser = build_parser(prog)
    args = parser.parse_args(argv)
    if args.rounds < 1:
        parser.error("--rounds must be >= 1")
    try:
        trees = bench_speed.installs(args.previous)
    except ValueError as e:
        parser.error(str(e))
    repeats = repeats_of(args)
    profile_steps = 3 if args.quick else bench_env.PROFILE_STEPS
    meta = run_meta(town=args.town, repeats=repeats, quick=args.quick, profile_steps=profile_steps)
    t0 = time.perf_counter()
    night = bench_sensors.bench_night(args.town, repeats)
    if args.night_figure is not None:
        bench_sensors.night_figure(night, args.night_figure)
    if args.night_only:
        print("\n".join(bench_sensors.render_night(night, repeats)))
        write_json(args.json, {"meta": meta, "night": night})
        return 0
    rigs = {key: bench_env.bench_rig(args.town, key, repeats) for key in bench_env.RIGS}
    point_sensors = bench_sensors.bench_point_sensors(repeats)
    fog = bench_fog.bench_fog(repeats)
    labels = bench_sensors.bench_labels(repeats)
    recording = bench_dataset.bench_recording(repeats)
    rl = bench_env.bench_rl(repeats)
    baseline = bench_env.bench_baselines(args.town, repeats, profile_steps)
    geometry = bench_geometry.bench_geometry(repeats, 5 if args.quick else 15)
    augment = bench_augment.bench_augment(repeats)
    realism = bench_realism.bench_realism(repeats, (320, 240) if args.quick else (1280, 960))
    rounds = 1 if args.quick else args.rounds
    speed = ratios = scaling = None
    if args.speed or args.previous is not None:
        speed = bench_speed.bench_figures(trees, rounds, args.quick)
        ratios = bench_speed.bench_ratios(trees["this tree"], rounds, args.quick)
    if args.scaling:
        scaling = bench_speed.bench_scaling(bench_speed.core_counts(), args.quick)
    finish_meta(meta, t0)
    results = {"meta": meta, "rigs": rigs, "point_sensors": point_sensors, "fog": fog, "labels": labels,
               "recording": recording, "rl": rl, "baseline": baseline, "night": night, "geometry": geometry,
               "augment": augment, "realism": realism, "speed": speed, "speed_ratios": ratios,
               "scaling": scaling}  # fmt: skip

    print(bench_env.render_stages(results))
    print("\n" + "\n".join(bench_sensors.render_point_sensors(point_sensors, repeats)))
    print("\n" + bench_env.render_baselines(results))
    print("\n" + "\n".join(bench_fog.render_fog(fog, repeats)))
    print("\n" + "\n".join(bench_sensors.render_labels(labels, repeats)))
    print("\n" + "\n".join(bench_dataset.render_recording(recording)))
    print("\n" + "\n".join(bench_env.render_rl(rl)))
    print("\n" + "\n".join(bench_sensors.render_night(night, repeats)))
    print("\n" + "\n".join(bench_geometry.render_geometry(geometry)))
    print("\n" + "\n".join(bench_augment.render_augment(augment, repeats)))
    print("\n" + "\n".join(bench_realism.render_realism(realism, repeats)))
    if speed is not None:
        print("\n" + "\n".join(bench_speed.render_figures(speed, rounds, ratios)))
    if scaling is not None:
        print("\n" + "\n".join(bench_speed.render_scaling(scaling)))
    write_json(args.json, results)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Recording one full paired frame (full rig, clean + 3 fog levels): the PNG-encoder bound (the 24 images of a
sample) against the recorder's whole per-frame cost (every file encoded and written atomically), and
``fog-gym generate`` (4 scenes × 3 s at 640×480) with 1 and 2 workers. It prints a Markdown table and asserts
no timing.

Usage::

    python -m fog_gym.experiments.bench.dataset            # 20 repeats (5 recorded frames)
    python -m fog_gym.experiments.bench.dataset --quick    # 3 recorded frames
    python -m fog_gym.experiments.bench.dataset --previous ../fog-gym-prev --generate-only   # against a release
"""

from __future__ import annotations

import argparse
import sys
import time
from typing import Any

import numpy as np
from tqdm import tqdm

from fog_gym.experiments.bench.common import (
    add_common_arguments, finish_meta, fmt_ms, markdown_table, meta_line, repeats_of, run_meta, summarize, timed,
    write_json,
)  # fmt: skip


def bench_recording(repeats: int) -> dict[str, Any]:
    """Recording one full paired frame: the PNG-encoder bound (the 24 images of D2) against the recorder's whole
    per-frame cost (every file encoded and written atomically), and ``fog-gym generate`` scaling with workers."""
    import tempfile

    from fog_gym.generate import generate, plan_scenes
    from fog_gym.dataset.writer import SceneWriter, encode_png
    from fog_gym.encoding import encode_depth, semantic_to_carla_rgb
    from fog_gym.envs.fogdrive import FogDriveEnv
    from fog_gym.wrappers import FogWrapper

    env = FogWrapper(FogDriveEnv(town="highway"), ["light", "moderate", "dense"])
    obs, info = env.reset(seed=0)
    images = []
    for cam in ("CAM_FRONT", "CAM_BACK", "CAM_LEFT", "CAM_RIGHT"):
        images += [obs[cam]] + [obs[f"{cam}_FOG_{lv}"] for lv in ("LIGHT", "MODERATE", "DENSE")]
        images += [encode_depth(obs[f"{cam}_DEPTH"]), semantic_to_carla_rgb(obs[f"{cam}_SEM"])]
    with tempfile.TemporaryDirectory() as tmp:
        writer = SceneWriter(tmp, "data_collection_T1_day_run1_00000000")
        bound, record, sizes = [], [], []
        for i in tqdm(range(max(3, repeats // 4)), desc="recording", unit="frame", leave=False, file=sys.stderr):
            bound.append(timed(lambda: [encode_png(im) for im in images])[1])
            files, ms_encode = timed(writer.encode_sample, obs, info)
            _, ms_write = timed(writer.write_files, i, files)
            record.append(ms_encode + ms_write)
            sizes.append(sum(len(b) for b in files.values()) / 1e6)
    env.close()
    scaling = {}
    plan = plan_scenes(4, towns=("merge", "roundabout"), seed=0, resolution=(640, 480), seconds=3.0)
    for workers in (1, 2):
        with tempfile.TemporaryDirectory() as tmp:
            _, ms = timed(generate, tmp, plan, workers, False, None, False)
            scaling[workers] = ms / 1000.0
    return {"bound": summarize(bound), "recorder": summarize(record), "mb_per_frame": float(np.median(sizes)),
            "generate_s": scaling}  # fmt: skip


def render_recording(rec: dict[str, Any]) -> list[str]:
    ratio = rec["recorder"]["median"] / rec["bound"]["median"]
    s1, s2 = rec["generate_s"][1], rec["generate_s"][2]
    return ["## Recording (full rig, clean + 3 paired fog levels)", "",
            markdown_table(["stage", "ms per frame"], [
                ["PNG-encoder bound: the 24 PNGs of one sample (zlib-ng level 1, no filter)", fmt_ms(rec["bound"])],
                ["recorder: all 35 files encoded + written atomically", fmt_ms(rec["recorder"])],
                ["**ratio recorder / bound**", f"**{ratio:.2f}×** (target ≤ 1.3×)"],
                ["bytes per sample", f"{rec['mb_per_frame']:.1f} MB"]]), "",
            f"`fog-gym generate`, 4 scenes × 3 s at 640×480 (incl. process start and kernel load): 1 worker "
            f"{s1:.1f} s, 2 workers {s2:.1f} s ({s1 / s2:.2f}× faster)."]  # fmt: skip


def bench_generate_previous(previous: str, scenes: int = 4, seconds: float = 2.0, workers: int = 2,
                            rounds: int = 2) -> dict[str, Any]:  # fmt: skip
    """``fog-gym generate`` of the full rig (1280×960, day and night 50:50, town merge) by the previous release (a
    checkout at ``previous``) and by this tree, each in its own process tree (working folder outside both, so
    ``PYTHONPATH`` picks the release), ``rounds`` times in turn after one warm-up each: samples per second, wall
    time from start to exit (process start, kernel load and the index included)."""
    import os
    import re
    import subprocess
    import sys
    import tempfile
    from pathlib import Path

    from fog_gym.experiments.bench.geometry import _checkout

    here = str(Path(__file__).resolve().parents[3])
    sides = {"previous release": _checkout(previous), "this tree": here}
    args = ["--scenes", str(scenes), "--seconds", str(seconds), "--workers", str(workers), "--towns", "merge"]
    runs: dict[str, list[dict[str, float]]] = {k: [] for k in sides}
    with tempfile.TemporaryDirectory() as tmp:
        for k in tqdm(range(rounds + 1), desc="generate: previous release and this tree", unit="round",
                      file=sys.stderr):  # fmt: skip
            for name, tree in sides.items():
                root = Path(tmp) / f"{k}-{name.replace(' ', '_')}"
                env = {**os.environ, "PYTHONPATH": tree}
                run_args = args if k else ["--scenes", "2", "--seconds", "0.2", "--workers", str(workers), "--towns", "merge"]
                t0 = time.perf_counter()
                out = subprocess.run([sys.executable, "-m", "fog_gym.cli", "generate", "--root", str(root), *run_args],
                                     cwd=tmp, env=env, capture_output=True, text=True, check=True).stdout  # fmt: skip
                wall = time.perf_counter() - t0
                if k:  # the first round warms the kernel caches up
                    samples = int(re.search(r"(\d+) samples", out).group(1))
                    mb = sum(p.stat().st_size for p in root.rglob("*") if p.is_file()) / 1e6
                    runs[name].append({"samples": samples, "seconds": wall, "samples_per_s": samples / wall, "mb": mb})
    res = {name: {"samples_per_s": float(np.median([r["samples_per_s"] for r in rs])), "runs": rs}
           for name, rs in runs.items()}  # fmt: skip
    res["ratio"] = res["this tree"]["samples_per_s"] / res["previous release"]["samples_per_s"]
    res["settings"] = {"scenes": scenes, "seconds": seconds, "workers": workers}
    return res


def render_generate_previous(res: dict[str, Any]) -> list[str]:
    p, t = res["previous release"], res["this tree"]
    st = res["settings"]
    row = lambda name, r: [name, f"{r['samples_per_s']:.2f}", f"{np.median([x['seconds'] for x in r['runs']]):.1f} s",  # noqa: E731
                           f"{np.median([x['mb'] / x['samples'] for x in r['runs']]):.1f} MB"]  # fmt: skip
    return [f"### `fog-gym generate` against the previous release ({st['scenes']} scenes × {st['seconds']:g} s, "
            f"1280×960, day and night 50:50, {st['workers']} workers; own processes, in turn)", "",
            markdown_table(["release", "samples/s", "wall", "per sample"], [row("previous release", p), row("this tree", t)]),
            "", f"**this tree / previous: {res['ratio']:.2f}×** (target ≥ 2.5×)."]  # fmt: skip


def build_parser(prog: str = "python -m fog_gym.experiments.bench.dataset") -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog=prog, description="Recorder cost per full paired frame against the PNG "
                                     "encoder bound, and fog-gym generate with 1 and 2 workers. It prints Markdown "
                                     "and asserts nothing.")  # fmt: skip
    parser.add_argument("--previous", metavar="DIR", help="also time `fog-gym generate` of the full rig against the "
                        "previous release: a checkout of it (e.g. `git worktree add ../fog-gym-prev <tag>`)")
    parser.add_argument("--generate-only", action="store_true", help="with --previous: skip the recorder figures")
    return add_common_arguments(parser)


def main(argv: list[str] | None = None, prog: str = "python -m fog_gym.experiments.bench.dataset") -> int:
    args = build_parser(prog).parse_args(argv)
    repeats = repeats_of(args)
    meta, t0 = run_meta(repeats=repeats, quick=args.quick), time.perf_counter()
    if args.previous is not None:
        from fog_gym.experiments.bench.geometry import _checkout

        try:
            _checkout(args.previous)
        except ValueError as e:
            build_parser(prog).error(str(e))
    recording = None if args.generate_only else bench_recording(repeats)
    previous = None if args.previous is None else bench_generate_previous(args.previous, rounds=1 if args.quick else 2)
    finish_meta(meta, t0)
    lines = (render_recording(recording) if recording else []) + (render_generate_previous(previous) if previous else [])
    print("\n".join(lines) + f"\n\n{meta_line(meta)}")
    write_json(args.json, {"meta": meta, "recording": recording, "generate_previous": previous})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

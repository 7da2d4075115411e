"""Recording one full paired frame (full rig, clean + 3 fog levels): the PNG-encoder bound (the 24 images of a
sample) against the recorder's whole per-frame cost (every file encoded and written atomically), and
``fog-gym generate`` (4 scenes × 3 s at 640×480) with 1 and 2 workers. It prints a Markdown table and asserts
no timing.

Usage::

    python -m fog_gym.experiments.bench.dataset            # 20 repeats (5 recorded frames)
    python -m fog_gym.experiments.bench.dataset --quick    # 3 recorded frames
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
                ["PNG-encoder bound: the 24 PNGs of one sample (cv2, zlib 1, no filter)", fmt_ms(rec["bound"])],
                ["recorder: all 35 files encoded + written atomically", fmt_ms(rec["recorder"])],
                ["**ratio recorder / bound**", f"**{ratio:.2f}×** (target ≤ 1.3×)"],
                ["bytes per sample", f"{rec['mb_per_frame']:.1f} MB"]]), "",
            f"`fog-gym generate`, 4 scenes × 3 s at 640×480 (incl. process start and kernel load): 1 worker "
            f"{s1:.1f} s, 2 workers {s2:.1f} s ({s1 / s2:.2f}× faster)."]  # fmt: skip


def build_parser(prog: str = "python -m fog_gym.experiments.bench.dataset") -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog=prog, description="Recorder cost per full paired frame against the PNG "
                                     "encoder bound, and fog-gym generate with 1 and 2 workers. It prints Markdown "
                                     "and asserts nothing.")  # fmt: skip
    return add_common_arguments(parser)


def main(argv: list[str] | None = None, prog: str = "python -m fog_gym.experiments.bench.dataset") -> int:
    args = build_parser(prog).parse_args(argv)
    repeats = repeats_of(args)
    meta, t0 = run_meta(repeats=repeats, quick=args.quick), time.perf_counter()
    recording = bench_recording(repeats)
    finish_meta(meta, t0)
    print("\n".join(render_recording(recording)) + f"\n\n{meta_line(meta)}")
    write_json(args.json, {"meta": meta, "recording": recording})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

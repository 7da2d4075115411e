#!/usr/bin/env python
"""Export speed: ``fog-gym export`` of one FogDrive set to nuScenes, KITTI and COCO, in samples per second, with
the ``validate`` pass every export starts with measured on its own. Prints a Markdown table and asserts no timing.

Usage::

    fog-gym generate --root out/bench20 --scenes 20 --resolution 320x240 --seconds 3
    python scripts/bench_export.py out/bench20 [--fog dense] [--out /tmp/exports]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import tempfile
import time
from pathlib import Path

from fog_gym.experiments.bench.common import load_average, markdown_table


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="bench_export.py", description=__doc__.split("\n\n")[0])
    parser.add_argument("root", type=Path, help="a FogDrive set (fog-gym generate)")
    parser.add_argument("--fog", default="dense", choices=("clear", "light", "moderate", "dense"))
    parser.add_argument("--out", type=Path, default=None, help="where the exports go (default: a temporary folder)")
    args = parser.parse_args(argv)
    from fog_gym.dataset import FogDrive
    from fog_gym.dataset.export import export
    from fog_gym.dataset.validate import validate

    load_start = load_average()
    samples = len(FogDrive(args.root).sample)
    tv = time.perf_counter()
    problems = validate(args.root)
    validate_s = time.perf_counter() - tv
    if problems:
        raise SystemExit(f"bench_export.py: {args.root} is not valid: {problems[0]}")
    out = args.out or Path(tempfile.mkdtemp(prefix="fog-gym-export-"))
    rows = [["validate alone (every export's first step)", f"{validate_s:.1f}", f"{samples / validate_s:.1f}", "—"]]
    for fmt in ("nuscenes", "kitti", "coco"):
        target = out / fmt
        shutil.rmtree(target, ignore_errors=True)
        report = export(args.root, target, fmt, fog=args.fog, progress=False)
        own = report["seconds"] - report["validate_seconds"]
        cams = json.loads((target / "fog_gym_export.json").read_text())["cameras"]
        what = f"{len(cams)} camera{'s' * (len(cams) > 1)}" + (" + LiDAR" if fmt != "coco" else "")
        rows.append([f"{fmt} ({what})", f"{report['seconds']:.1f}", f"{samples / report['seconds']:.1f}",
                     f"{samples / own:.1f}"])  # fmt: skip
    print(f"{samples} samples of {args.root}, fog {args.fog}; {os.cpu_count()} CPUs; load average at start "
          f"{load_start}, at end {load_average()}")  # fmt: skip
    print(markdown_table(["export", "seconds (with validate)", "samples/s", "samples/s without validate"], rows))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

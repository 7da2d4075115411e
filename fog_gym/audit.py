"""Annotation audit (FogDrive paper §3.7) of both visibility rules on the same frames.

* precision: share of 2D boxes whose area holds ≥ 10 % vehicle pixels in the semantic image;
* recall: share of vehicle blobs (8-connected components of vehicle pixels, ≥ 100 px²) of which ≥ 50 % lies
  inside one 2D box, overall and per distance bin (median planar depth of the blob: < 20, 20–40, 40–70,
  70–100 m; blobs beyond 100 m are outside every rule's range and not counted).

Example:
    >>> r = audit_frame(np.zeros((4, 4), np.uint8), np.full((4, 4), 10.0, np.float32), np.zeros((0, 2, 2), int))
    >>> r["boxes"], r["blobs"]
    (0, 0)
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np

VEHICLE_TAGS = (14, 15, 16, 17, 18, 19)
DISTANCE_BINS = ((0.0, 20.0), (20.0, 40.0), (40.0, 70.0), (70.0, 100.0))
BIN_NAMES = ("< 20 m", "20–40 m", "40–70 m", "70–100 m")


def audit_frame(semantic: np.ndarray, depth: np.ndarray, bboxes: np.ndarray, min_blob: int = 100,
                fill: float = 0.1, cover: float = 0.5) -> dict[str, Any]:  # fmt: skip
    """Precision and recall counts of one camera frame's 2D boxes against its semantic image."""
    vehicle = np.isin(semantic, VEHICLE_TAGS)
    precise = 0
    for (x0, y0), (x1, y1) in np.asarray(bboxes).reshape(-1, 2, 2):
        if vehicle[y0 : y1 + 1, x0 : x1 + 1].mean() >= fill:
            precise += 1
    n, labels, stats, _ = cv2.connectedComponentsWithStats(vehicle.astype(np.uint8), connectivity=8)
    bins_total = np.zeros(len(DISTANCE_BINS), np.int64)
    bins_found = np.zeros(len(DISTANCE_BINS), np.int64)
    for k in range(1, n):
        if stats[k, cv2.CC_STAT_AREA] < min_blob:
            continue
        x, y, w, h = (stats[k, i] for i in (cv2.CC_STAT_LEFT, cv2.CC_STAT_TOP, cv2.CC_STAT_WIDTH, cv2.CC_STAT_HEIGHT))
        mask = labels[y : y + h, x : x + w] == k
        d = float(np.median(depth[y : y + h, x : x + w][mask]))
        b = next((i for i, (lo, hi) in enumerate(DISTANCE_BINS) if lo <= d < hi), None)
        if b is None:
            continue
        size = mask.sum()
        found = False
        for (x0, y0), (x1, y1) in np.asarray(bboxes).reshape(-1, 2, 2):
            ix0, iy0, ix1, iy1 = max(x0, x), max(y0, y), min(x1, x + w - 1), min(y1, y + h - 1)
            if ix1 >= ix0 and iy1 >= iy0 and mask[iy0 - y : iy1 - y + 1, ix0 - x : ix1 - x + 1].sum() >= cover * size:
                found = True
                break
        bins_total[b] += 1
        bins_found[b] += found
    return {"boxes": len(bboxes), "precise": precise, "blobs": int(bins_total.sum()), "bins_total": bins_total,
            "bins_found": bins_found}  # fmt: skip


def run_audit(frames: int = 200, resolution: tuple[int, int] = (1280, 960), seed: int = 0,
              progress: bool = True) -> dict[str, Any]:  # fmt: skip
    """Drive every town by day and night, label each frame with both rules and audit them."""
    from tqdm import tqdm

    from fog_gym.config import TIMES_OF_DAY, TOWNS
    from fog_gym.env import FogDriveEnv
    from fog_gym.labels import LabelConfig

    rules = {"lidar": LabelConfig(visibility="lidar"), "camera": LabelConfig(visibility="camera")}
    totals = {r: {"boxes": 0, "precise": 0, "bins_total": np.zeros(4, np.int64), "bins_found": np.zeros(4, np.int64)}
              for r in rules}  # fmt: skip
    combos = [(t, d) for t in TOWNS for d in TIMES_OF_DAY]
    per_combo = -(-frames // len(combos))
    bar = tqdm(total=per_combo * len(combos), desc="audit", unit="frame", disable=not progress)
    done = 0
    for i, (town, tod) in enumerate(combos):
        env = FogDriveEnv(town=town, time_of_day=tod, resolution=resolution)
        env.reset(seed=seed + i)
        idle = 1 if env.action_space.shape == () else np.zeros(env.action_space.shape, np.float32)
        for _ in range(per_combo):
            _, _, terminated, truncated, _ = env.step(idle)
            for name, cfg in rules.items():
                env.config = replace(env.config, labels=cfg)
                gt = env.ground_truth()
                for cam, b in gt["boxes_2d"].items():
                    f = env.frames[cam]
                    r = audit_frame(f.semantic, f.depth, b["bboxes"])
                    t = totals[name]
                    t["boxes"] += r["boxes"]
                    t["precise"] += r["precise"]
                    t["bins_total"] += r["bins_total"]
                    t["bins_found"] += r["bins_found"]
            done += 1
            bar.update()
            if terminated or truncated:
                env.reset()
        env.close()
    bar.close()
    return {"frames": done, "resolution": list(resolution), "rules": totals}


def report(result: dict[str, Any]) -> str:
    lines = [f"Annotation audit: {result['frames']} frames (4 cameras each) over every town, day and night, "
             f"{result['resolution'][0]}×{result['resolution'][1]}", "",
             "| rule | boxes | precision (≥ 10 % vehicle pixels) | blobs ≥ 100 px² | recall | "
             + " | ".join(f"recall {b}" for b in BIN_NAMES) + " |",
             "|---|---|---|---|---|" + "---|" * len(BIN_NAMES)]  # fmt: skip
    for rule, t in result["rules"].items():
        prec = t["precise"] / max(t["boxes"], 1)
        rec = t["bins_found"].sum() / max(t["bins_total"].sum(), 1)
        per_bin = [f"{f / n:.1%} ({n})" if n else "—" for f, n in zip(t["bins_found"], t["bins_total"])]
        lines.append(f"| `{rule}` | {t['boxes']} | {prec:.1%} | {t['bins_total'].sum()} | {rec:.1%} | " + " | ".join(per_bin) + " |")
    return "\n".join(lines)


def figure(result: dict[str, Any], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 3.6), dpi=120)
    width = 0.38
    x = np.arange(len(BIN_NAMES))
    for k, (rule, t) in enumerate(result["rules"].items()):
        rec = t["bins_found"] / np.maximum(t["bins_total"], 1)
        prec = t["precise"] / max(t["boxes"], 1)
        ax.bar(x + (k - 0.5) * width, rec, width, label=f"{rule} rule (precision {prec:.1%})")
    ax.set_xticks(x, BIN_NAMES)
    ax.set_ylim(0, 1.05)
    ax.set_ylabel("recall of vehicle blobs ≥ 100 px²")
    ax.set_title(f"fog-gym annotation audit, {result['frames']} frames × 4 cameras")
    ax.legend(loc="lower left")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)

"""Annotation audit (FogDrive paper §3.7) of both visibility rules on the same frames.

* precision: share of 2D boxes whose area holds ≥ 10 % vehicle pixels in the semantic image;
* recall: share of vehicle blobs (8-connected components of vehicle pixels, ≥ 100 px²) of which ≥ 50 % lies
  inside one 2D box, overall and per distance bin (median camera distance of the blob: < 20, 20–40, 40–70,
  70–100 m; blobs beyond 100 m are outside every rule's range and not counted).

Example:
    >>> r = audit_frame(np.zeros((4, 4), np.uint8), np.full((4, 4), 10.0, np.float32), np.zeros((0, 2, 2), int))
    >>> r["boxes"], r["blobs"]
    (0, 0)
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import cv2
import numpy as np

VEHICLE_TAGS = (14, 15, 16, 17, 18, 19)
DISTANCE_BINS = ((0.0, 20.0), (20.0, 40.0), (40.0, 70.0), (70.0, 100.0))
BIN_NAMES = ("< 20 m", "20–40 m", "40–70 m", "70–100 m")


def _covered(mask: np.ndarray, x: int, y: int, bboxes: np.ndarray, cover: float) -> bool:
    """Does one box hold ≥ ``cover`` of the blob ``mask`` (whose top-left pixel is (x, y))?"""
    h, w = mask.shape
    size = mask.sum()
    for (x0, y0), (x1, y1) in bboxes:
        ix0, iy0, ix1, iy1 = max(x0, x), max(y0, y), min(x1, x + w - 1), min(y1, y + h - 1)
        if ix1 >= ix0 and iy1 >= iy0 and mask[iy0 - y : iy1 - y + 1, ix0 - x : ix1 - x + 1].sum() >= cover * size:
            return True
    return False


def _bin(d: float) -> int | None:
    return next((i for i, (lo, hi) in enumerate(DISTANCE_BINS) if lo <= d < hi), None)


def audit_frame(semantic: np.ndarray, depth: np.ndarray, bboxes: np.ndarray, min_blob: int = 100,
                fill: float = 0.1, cover: float = 0.5, K: np.ndarray | None = None,
                instance: np.ndarray | None = None) -> dict[str, Any]:  # fmt: skip
    """Precision and recall counts of one camera frame's 2D boxes against its semantic image.

    A blob's distance is the median over its pixels of the Euclidean camera distance (planar depth × the ray
    length factor of ``K``; planar depth when ``K`` is None), the quantity the rules' ``max_dist`` bounds.
    With ``instance``, recall is also counted per vehicle (each id's visible pixels as one blob), which does not
    merge a distant queue of cars into one blob the way semantic blobs do.
    """
    if K is not None:
        from fog_gym.fog import ray_length_factor

        depth = depth * ray_length_factor(depth.shape[1], depth.shape[0], K)
    vehicle = np.isin(semantic, VEHICLE_TAGS)
    precise = 0
    for (x0, y0), (x1, y1) in np.asarray(bboxes).reshape(-1, 2, 2):
        if vehicle[y0 : y1 + 1, x0 : x1 + 1].mean() >= fill:
            precise += 1
    n, labels, stats, _ = cv2.connectedComponentsWithStats(vehicle.astype(np.uint8), connectivity=8)
    bins_total = np.zeros(len(DISTANCE_BINS), np.int64)
    bins_found = np.zeros(len(DISTANCE_BINS), np.int64)
    boxes = np.asarray(bboxes).reshape(-1, 2, 2)
    for k in range(1, n):
        if stats[k, cv2.CC_STAT_AREA] < min_blob:
            continue
        x, y, w, h = (stats[k, i] for i in (cv2.CC_STAT_LEFT, cv2.CC_STAT_TOP, cv2.CC_STAT_WIDTH, cv2.CC_STAT_HEIGHT))
        mask = labels[y : y + h, x : x + w] == k
        b = _bin(float(np.median(depth[y : y + h, x : x + w][mask])))
        if b is not None:
            bins_total[b] += 1
            bins_found[b] += _covered(mask, x, y, boxes, cover)
    inst_total = np.zeros(len(DISTANCE_BINS), np.int64)
    inst_found = np.zeros(len(DISTANCE_BINS), np.int64)
    if instance is not None:
        ids, counts = np.unique(instance[instance > 0], return_counts=True)
        for vid in ids[counts >= min_blob]:
            rows, cols = np.nonzero(instance == vid)
            y, x = rows.min(), cols.min()
            mask = np.zeros((rows.max() - y + 1, cols.max() - x + 1), bool)
            mask[rows - y, cols - x] = True
            b = _bin(float(np.median(depth[rows, cols])))
            if b is not None:
                inst_total[b] += 1
                inst_found[b] += _covered(mask, x, y, boxes, cover)
    return {"boxes": len(bboxes), "precise": precise, "blobs": int(bins_total.sum()), "bins_total": bins_total,
            "bins_found": bins_found, "vehicles_total": inst_total, "vehicles_found": inst_found}  # fmt: skip


def run_audit(frames: int = 200, resolution: tuple[int, int] = (1280, 960), seed: int = 0,
              progress: bool = True) -> dict[str, Any]:  # fmt: skip
    """Drive every town by day and night, label each frame with both rules and audit them."""
    from tqdm import tqdm

    from fog_gym.world.towns import TIMES_OF_DAY, TOWNS
    from fog_gym.envs.fogdrive import FogDriveEnv
    from fog_gym.labels.boxes import LabelConfig

    rules = {"lidar": LabelConfig(visibility="lidar"), "camera": LabelConfig(visibility="camera")}
    counters = ("bins_total", "bins_found", "vehicles_total", "vehicles_found")
    totals = {r: {"boxes": 0, "precise": 0, **{c: np.zeros(4, np.int64) for c in counters}} for r in rules}
    combos = [(t, d) for t in TOWNS for d in TIMES_OF_DAY]
    per_combo = -(-frames // len(combos))
    bar = tqdm(total=per_combo * len(combos), desc="audit", unit="frame", disable=not progress)
    done = 0
    for i, (town, tod) in enumerate(combos):
        env = FogDriveEnv(town=town, time_of_day=tod, resolution=resolution)
        env.reset(seed=seed + i)
        idle = env.idle_action
        for _ in range(per_combo):
            _, _, terminated, truncated, _ = env.step(idle)
            for name, cfg in rules.items():
                gt = env.ground_truth(labels=cfg)
                for cam, b in gt["boxes_2d"].items():
                    f = env.frames[cam]
                    r = audit_frame(f.semantic, f.depth, b["bboxes"], K=gt["intrinsics"][cam], instance=f.instance)
                    t = totals[name]
                    for c in ("boxes", "precise", *counters):
                        t[c] += r[c]
            done += 1
            bar.update()
            if terminated or truncated:
                env.reset()
        env.close()
    bar.close()
    return {"frames": done, "resolution": list(resolution), "rules": totals}


def report(result: dict[str, Any]) -> str:
    lines = [f"Annotation audit: {result['frames']} frames (4 cameras each) over every town, day and night, "
             f"{result['resolution'][0]}×{result['resolution'][1]}", ""]  # fmt: skip
    for title, total, found in (("semantic blobs ≥ 100 px² (the paper's measure)", "bins_total", "bins_found"),
                                ("vehicles ≥ 100 visible px (instance buffer)", "vehicles_total", "vehicles_found")):
        lines += [f"Recall over {title}:", "",
                  "| rule | boxes | precision (≥ 10 % vehicle pixels) | blobs | recall | "
                  + " | ".join(f"recall {b}" for b in BIN_NAMES) + " |",
                  "|---|---|---|---|---|" + "---|" * len(BIN_NAMES)]  # fmt: skip
        for rule, t in result["rules"].items():
            prec = t["precise"] / max(t["boxes"], 1)
            rec = t[found].sum() / max(t[total].sum(), 1)
            per_bin = [f"{f / n:.1%} ({n})" if n else "—" for f, n in zip(t[found], t[total])]
            lines.append(f"| `{rule}` | {t['boxes']} | {prec:.1%} | {t[total].sum()} | {rec:.1%} | "
                         + " | ".join(per_bin) + " |")  # fmt: skip
        lines.append("")
    return "\n".join(lines).rstrip()


def figure(result: dict[str, Any], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 4), dpi=120)
    x = np.arange(len(BIN_NAMES))
    width = 0.2
    for k, (rule, t) in enumerate(result["rules"].items()):
        prec = t["precise"] / max(t["boxes"], 1)
        for m, (total, found, what) in enumerate((("bins_total", "bins_found", "semantic blobs"),
                                                  ("vehicles_total", "vehicles_found", "vehicles"))):  # fmt: skip
            rec = t[found] / np.maximum(t[total], 1)
            ax.bar(x + (2 * k + m - 1.5) * width, rec, width, label=f"{rule} rule, {what} (precision {prec:.1%})")
    ax.set_xticks(x, BIN_NAMES)
    ax.set_ylim(0, 1.05)
    ax.set_ylabel("recall (≥ 50 % inside one box)")
    ax.set_title(f"fog-gym annotation audit, {result['frames']} frames × 4 cameras")
    ax.legend(loc="lower left", fontsize=7)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)

"""Experiment 2's report: the detection table and the image-quality table, shaped like the paper's (means over
seeds, ± the 95 % CI across seeds when there are several), and the figure (mAP@0.5 per pipeline and level; PSNR
against detection)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from fog_gym.experiments.defog.dehazers import DEHAZERS
from fog_gym.experiments.runner import fmt_stat, save_figure

PIPELINE_NAMES = {"A": "A (clean→clean)", "B": "B (clean→fog)", "C-DCP": "C – DCP", "C-AOD-Net": "C – AOD-Net (trained here)",
                  "C-oracle": "C – oracle", "D": "D (fog→fog)"}  # fmt: skip


def markdown(detection: dict[str, Any], image_quality: dict[str, Any], seeds: int = 1) -> str:
    """Both tables from ``detection[pipeline][level][metric]`` and ``image_quality[level][method][metric]``
    (:func:`fog_gym.experiments.runner.aggregate`)."""
    across = f"; mean ± 95 % CI across {seeds} seeds" if seeds > 1 else ""
    lines = [f"**Detection** (COCO evaluation; P and R at confidence 0.25; AP@0.5 per class{across})", "",
             "| Pipeline | Fog | mAP@0.5 | mAP@.5:.95 | P | R | car | truck | bigger car |", "|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for key, name in PIPELINE_NAMES.items():
        for lv, r in detection.get(key, {}).items():
            cls = [fmt_stat(r[f"AP50/{c}"], "{:.3f}") if f"AP50/{c}" in r else "–" for c in (0, 1, 4)]
            lines.append(f"| {name} | {lv} | " + " | ".join(fmt_stat(r[m], "{:.3f}") for m in ("mAP50", "mAP50_95",
                         "precision", "recall")) + " | " + " | ".join(cls) + " |")  # fmt: skip
    levels = list(image_quality)
    lines += ["", f"**Image quality** against the paired clean frame (at the detector's input size{across})", "",
              "| Method | " + " | ".join(f"PSNR {lv}" for lv in levels) + " | " + " | ".join(f"SSIM {lv}" for lv in levels) + " |",
              "|---|" + "---|" * (2 * len(levels))]  # fmt: skip
    for method in ("foggy", *DEHAZERS):
        lines.append(f"| {method} | " + " | ".join(fmt_stat(image_quality[lv][method]["PSNR"], "{:.2f}") for lv in levels)
                     + " | " + " | ".join(fmt_stat(image_quality[lv][method]["SSIM"], "{:.3f}") for lv in levels) + " |")  # fmt: skip
    return "\n".join(lines) + "\n"


def figure(detection: dict[str, Any], image_quality: dict[str, Any], path: Path) -> None:
    """mAP@0.5 per pipeline and level (bars; the 95 % CIs across seeds as error bars) and image quality against
    detection (scatter of the means)."""
    import matplotlib.pyplot as plt

    def mean(cell: dict[str, Any]) -> float:
        return cell["mean"]

    det, iq = detection, image_quality
    levels = list(iq)
    keys = ["B", "C-DCP", "C-AOD-Net", "C-oracle", "D"]
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(12, 4))
    width = 0.8 / len(keys)
    for i, k in enumerate(keys):
        cells = [det[k][lv]["mAP50"] for lv in levels]
        err = None if all(c["ci95"] is None for c in cells) else [c["ci95"] or 0.0 for c in cells]
        ax.bar(np.arange(len(levels)) + i * width, [mean(c) for c in cells], width, yerr=err, capsize=2,
               label=PIPELINE_NAMES[k])  # fmt: skip
    ax.axhline(mean(det["A"]["clean"]["mAP50"]), color="k", ls="--", lw=1, label="A (clean→clean)")
    ax.set_xticks(np.arange(len(levels)) + 0.4 - width / 2, levels)
    ax.set_ylabel("mAP@0.5")
    ax.set_title("Detection per pipeline and fog level")
    ax.legend(fontsize=7)
    markers = {"light": "o", "moderate": "s", "dense": "^"}
    for method, key in (("foggy", "B"), ("DCP", "C-DCP"), ("AOD-Net", "C-AOD-Net"), ("oracle", "C-oracle")):
        for lv in levels:
            ax2.scatter(mean(iq[lv][method]["PSNR"]), mean(det[key][lv]["mAP50"]), marker=markers.get(lv, "o"),
                        color=f"C{['foggy', 'DCP', 'AOD-Net', 'oracle'].index(method)}",
                        label=f"{method}" if lv == levels[0] else None)  # fmt: skip
    ax2.set_xlabel("PSNR against the clean frame [dB]  (○ light, □ moderate, △ dense)")
    ax2.set_ylabel("mAP@0.5 of the clean-trained detector")
    ax2.set_title("Image quality vs detection")
    ax2.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path, dpi=120)

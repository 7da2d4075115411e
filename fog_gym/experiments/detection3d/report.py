"""Experiment 1's report: the matrices (training subset × test fog) of mAP@0.5, Mean TP, ATE, ASE and AOE at the
best-FDS epoch — mean over seeds, ± the 95 % CI across seeds when there are several — and their heatmaps."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from fog_gym.experiments.detection3d.protocol import TEST_COLUMNS
from fog_gym.experiments.runner import fmt_stat, save_figure

TABLES = (("mAP", "mAP@0.5 (3D IoU)"), ("mean_TP", "Mean TP"), ("ATE", "ATE (1 − error / 2 m)"),
          ("ASE", "ASE (1 − scale error)"), ("AOE", "AOE (1 − orientation error / π)"))  # fmt: skip


def markdown(table: dict[str, Any], seeds: int = 1) -> str:
    """``table[row][column][metric]`` (:func:`fog_gym.experiments.runner.aggregate`) as Markdown matrices; the
    column-wise best mean in bold."""
    across = f" (mean ± 95 % CI across {seeds} seeds)" if seeds > 1 else ""
    lines = []
    for metric, title in TABLES:
        lines += [f"**{title}** — best-FDS epoch per cell{across}; column-wise best in bold", "",
                  "| train ↓ / test → | " + " | ".join(TEST_COLUMNS) + " |", "|---|" + "---|" * len(TEST_COLUMNS)]  # fmt: skip
        best_col = {c: max((r[c][metric]["mean"] for r in table.values()), default=0.0) for c in TEST_COLUMNS}
        for name, r in table.items():
            cells = []
            for c in TEST_COLUMNS:
                text = fmt_stat(r[c][metric], "{:.4f}")
                cells.append(f"**{text}**" if r[c][metric]["mean"] == best_col[c] and len(table) > 1 else text)
            lines.append(f"| {name} | " + " | ".join(cells) + " |")
        lines.append("")
    return "\n".join(lines)


def figure(table: dict[str, Any], path: Path) -> None:
    """Heatmaps of mAP@0.5, Mean TP and ATE (means over seeds)."""
    import matplotlib.pyplot as plt

    rows = list(table)
    fig, axes = plt.subplots(1, 3, figsize=(12, 0.55 * len(rows) + 1.8))
    for ax, metric in zip(axes, ("mAP", "mean_TP", "ATE"), strict=True):
        m = np.array([[table[r][c][metric]["mean"] for c in TEST_COLUMNS] for r in rows])
        im = ax.imshow(m, cmap="viridis", aspect="auto")
        ax.set_xticks(range(len(TEST_COLUMNS)), TEST_COLUMNS)
        ax.set_yticks(range(len(rows)), rows)
        for i in range(len(rows)):
            for j in range(len(TEST_COLUMNS)):
                ax.text(j, i, f"{m[i, j]:.3f}", ha="center", va="center", color="w" if m[i, j] < m.mean() else "k",
                        fontsize=8)  # fmt: skip
        ax.set_title({"mAP": "mAP@0.5", "mean_TP": "Mean TP", "ATE": "ATE"}[metric])
        ax.set_xlabel("test fog")
        fig.colorbar(im, ax=ax, fraction=0.046)
    axes[0].set_ylabel("training subset")
    fig.tight_layout()
    save_figure(fig, path, dpi=120)

"""The RL benchmark's report: the train × test matrices (mean over training seeds ± 95 % CI across seeds
[episode-level SD]), plain statements of which differences the CIs separate, the wall-time table per agent, the
heatmaps, the fog-effect figure and the learning curves (episode return against training steps, from the
VecMonitor logs)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from fog_gym.experiments.rl_bench.data import CONDITIONS, EVAL_SEED, TEST_LEVELS
from fog_gym.experiments.rl_bench.evaluate import METRICS


def _header(meta: dict[str, Any], title: str, per: str, extra: str = "") -> list[str]:
    """A report's title, its run's setting and its budget line (what the run is, from its own numbers)."""
    lines = [f"# {title}", "",
             f"{meta['seeds']} training seed(s) × {meta['steps']} steps per {per} ({meta.get('algo', 'PPO')}), "
             f"{meta['episodes']} evaluation episodes per agent and test fog (seeds {EVAL_SEED}+). Cells: mean over "
             f"training seeds ± 95 % CI across seeds (n/a for one seed){extra}.", ""]  # fmt: skip
    note = meta.get("budget") or meta.get("smoke")  # (reports of earlier runs kept a smoke warning)
    return lines + ([f"**{note}**", ""] if note else [])


def render_matrix(table: dict[str, Any], meta: dict[str, Any]) -> str:
    """The Markdown matrices of every metric and the separation statements (:func:`significance`)."""
    lines = _header(meta, f"{meta['env']} fog benchmark: train × test matrix", "condition", " [episode-level SD]")
    for metric, label, fmt in METRICS:
        lines += [f"## {label}", "", "| trained on \\ tested on | " + " | ".join(TEST_LEVELS) + " |",
                  "|---|" + "---|" * len(TEST_LEVELS)]  # fmt: skip
        for cond in [c for c in CONDITIONS if c in table]:
            cells = []
            for test in TEST_LEVELS:
                c = table[cond][test][metric]
                ci = "n/a" if c["ci95"] is None else fmt.format(c["ci95"])
                cells.append(f"{fmt.format(c['mean'])} ± {ci} [{fmt.format(c['episode_std'])}]")
            lines.append(f"| {cond} | " + " | ".join(cells) + " |")
        lines.append("")
    lines += significance(table)
    return "\n".join(lines)


def _verdict(a: dict[str, Any], b: dict[str, Any]) -> str:
    if a["ci95"] is None or b["ci95"] is None:
        return "not testable (one seed)"
    separated = a["mean"] + a["ci95"] < b["mean"] - b["ci95"] or b["mean"] + b["ci95"] < a["mean"] - a["ci95"]
    return "separated" if separated else "CIs overlap"


def significance(table: dict[str, Any]) -> list[str]:
    """Plain statements from the 95 % CIs across training seeds (separated = the intervals do not overlap):
    the fog effect (each condition's agents tested clear against tested dense) and each condition against the
    clear-trained agents, tested clear and tested dense, on collision rate and return.

    >>> cell = lambda m, ci: {"collision": {"mean": m, "ci95": ci}, "return": {"mean": 10 * m, "ci95": 10 * ci}}
    >>> t = {"clear": {"clear": cell(0.2, 0.05), "dense": cell(0.8, 0.1)}}
    >>> significance(t)[4]
    '- clear: collision rate 20% clear vs 80% dense — separated; return 2.0 vs 8.0 — separated'
    """
    out = ["## Separated? (95 % CIs across training seeds that do not overlap)", "",
           "Fog effect (the same agents tested in clear air and in dense fog):", ""]  # fmt: skip
    conds = [c for c in CONDITIONS if c in table]
    for cond in conds:
        a, b = table[cond]["clear"], table[cond]["dense"]
        out.append(f"- {cond}: collision rate {a['collision']['mean']:.0%} clear vs {b['collision']['mean']:.0%} dense "
                   f"— {_verdict(a['collision'], b['collision'])}; return {a['return']['mean']:.1f} vs "
                   f"{b['return']['mean']:.1f} — {_verdict(a['return'], b['return'])}")  # fmt: skip
    if "clear" not in table:
        return out + ["", "(no clear-trained agent)"]
    out += ["", "Against the clear-trained agents:", ""]
    for test in ("clear", "dense"):
        ref = table["clear"][test]
        for cond in [c for c in conds if c != "clear"]:
            c = table[cond][test]
            out.append(f"- tested {test}: {cond} collision rate {c['collision']['mean']:.0%} vs clear "
                       f"{ref['collision']['mean']:.0%} — {_verdict(c['collision'], ref['collision'])}; return "
                       f"{c['return']['mean']:.1f} vs {ref['return']['mean']:.1f} — {_verdict(c['return'], ref['return'])}")  # fmt: skip
    return out


def wall_times(out: Path, agents: Sequence[str], eval_s: dict[str, float]) -> dict[str, dict[str, float | None]]:
    """Training wall time and steps of each agent from its VecMonitor logs (summed over resumed parts; each part's
    time runs from its start to its last finished episode), and its evaluation wall time (``eval_s``: the sum over
    this run's cells, None when unknown)."""
    times: dict[str, dict[str, float | None]] = {}
    for name in agents:
        wall, steps = 0.0, 0.0
        for f in sorted((out / "monitor").glob(f"{name}_*.monitor.csv")):
            rows = monitor_rows(f)
            if rows.size:
                wall += float(rows[-1, 2])
                steps += float(rows[:, 1].sum())
        times[name] = {"train_s": wall, "steps": steps, "eval_s": eval_s.get(name)}
    return times


def render_wall_times(times: dict[str, dict[str, float | None]]) -> list[str]:
    lines = ["## Wall time", "", "| agent | training [min] | steps/s | evaluation [min] |", "|---|---|---|---|"]
    for name, t in times.items():
        rate = t["steps"] / t["train_s"] if t["train_s"] > 0 else float("nan")
        ev = "—" if t["eval_s"] is None else f"{t['eval_s'] / 60:.1f}"
        lines.append(f"| {name} | {t['train_s'] / 60:.1f} | {rate:.0f} | {ev} |")
    total = sum(t["train_s"] for t in times.values())
    return lines + ["", f"Training in all: {total / 3600:.2f} h of wall time (from the monitor logs)."]


def heatmap(table: dict[str, Any], path: Path) -> None:
    """Collision rate and return, train × test, as two heatmaps."""
    import matplotlib.pyplot as plt

    from fog_gym.experiments.runner import save_figure

    conds = [c for c in CONDITIONS if c in table]
    fig, axes = plt.subplots(1, 2, figsize=(11, 0.55 * len(conds) + 2), dpi=120)
    for ax, (metric, label, fmt) in zip(axes, METRICS[:2]):
        grid = np.array([[table[c][t][metric]["mean"] for t in TEST_LEVELS] for c in conds])
        im = ax.imshow(grid, cmap="magma_r" if metric == "collision" else "viridis")
        ax.set_xticks(range(len(TEST_LEVELS)), TEST_LEVELS)
        ax.set_yticks(range(len(conds)), conds)
        ax.set_xlabel("tested on")
        ax.set_ylabel("trained on")
        for i in range(len(conds)):
            for j in range(len(TEST_LEVELS)):
                ax.text(j, i, fmt.format(grid[i, j]), ha="center", va="center", color="w", fontsize=8)
        fig.colorbar(im, ax=ax, label=label)
        ax.set_title(label)
    fig.tight_layout()
    save_figure(fig, path)


def fog_effect(table: dict[str, Any], env: str, path: Path) -> None:
    """The means against the test fog, with the 95 % CIs across training seeds as error bars."""
    import matplotlib.pyplot as plt

    from fog_gym.experiments.runner import save_figure

    conds = [c for c in CONDITIONS if c in table]
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), dpi=120)
    x = np.arange(len(TEST_LEVELS))
    for ax, (metric, label, _) in zip(axes, METRICS[:2]):
        scale = 100.0 if metric == "collision" else 1.0
        for k, cond in enumerate(conds):
            cells = [table[cond][t][metric] for t in TEST_LEVELS]
            err = [0.0 if c["ci95"] is None else c["ci95"] * scale for c in cells]
            ax.errorbar(x + (k - (len(conds) - 1) / 2) * 0.06, [c["mean"] * scale for c in cells], yerr=err,
                        marker="o", ms=4, capsize=3, label=cond)  # fmt: skip
        ax.set_xticks(x, TEST_LEVELS)
        ax.set_xlabel("tested on")
        ax.set_ylabel(label + (" [%]" if metric == "collision" else ""))
        if metric == "collision":  # a t interval over few seeds can reach past 0 and 100 %
            ax.set_ylim(-5, 105)
        ax.set_title(f"{label}: mean over training seeds ± 95 % CI")
    axes[0].legend(fontsize=7)
    fig.suptitle(env, fontsize=9)
    fig.tight_layout()
    save_figure(fig, path)


def monitor_rows(path: Path) -> np.ndarray:
    """(episodes, 3) array of return, length, time of a VecMonitor CSV (empty when no episode finished)."""
    lines = path.read_text().splitlines()[2:] if path.stat().st_size else []
    return np.array([[float(v) for v in line.split(",")[:3]] for line in lines if line.strip()]).reshape(-1, 3)


def episode_curve(out: Path, cond: str, seed: int) -> tuple[np.ndarray, np.ndarray] | None:
    """(cumulative steps, trailing moving average of the episode returns over ≥ 10 episodes) of one agent from its
    VecMonitor logs."""
    files = sorted((out / "monitor").glob(f"{cond}_s{seed}_*.monitor.csv"))
    rows = [r for r in (monitor_rows(f) for f in files) if r.size]
    if not rows:
        return None
    data = np.concatenate(rows)  # r, l, t per episode
    k = min(max(10, len(data) // 40), len(data))  # about 40 windows over the run, at least 10 episodes each
    return np.cumsum(data[:, 1])[k - 1 :], np.convolve(data[:, 0], np.ones(k) / k, mode="valid")


def _mean_curve(out: Path, cond: str, seeds: Sequence[int]):
    curves = [(s, c) for s, c in ((s, episode_curve(out, cond, s)) for s in seeds) if c is not None]
    if not curves:
        return curves, None
    grid = np.linspace(0, min(c[0][-1] for _, c in curves), 50)
    return curves, (grid, np.mean([np.interp(grid, steps, ret) for _, (steps, ret) in curves], axis=0))


def learning_curves(out: Path, conditions: Sequence[str], seeds: Sequence[int], env: str, path: Path) -> None:
    """Every condition's learning curve: the mean over seeds of the moving-average episode return."""
    import matplotlib.pyplot as plt

    from fog_gym.experiments.runner import save_figure

    fig, ax = plt.subplots(figsize=(7, 4), dpi=120)
    for cond in conditions:
        _, mean = _mean_curve(out, cond, seeds)
        if mean is not None:
            ax.plot(*mean, label=cond)
    ax.set_xlabel("training steps")
    ax.set_ylabel("episode return (moving average)")
    ax.legend()
    ax.set_title(f"{env} learning curves")
    fig.tight_layout()
    save_figure(fig, path)


def condition_curves(out: Path, cond: str, seeds: Sequence[int], env: str, path: Path) -> None:
    """One condition's learning curves: each training seed's and their mean."""
    import matplotlib.pyplot as plt

    from fog_gym.experiments.runner import save_figure

    curves, mean = _mean_curve(out, cond, seeds)
    fig, ax = plt.subplots(figsize=(6, 3.5), dpi=120)
    for seed, (steps, ret) in curves:
        ax.plot(steps, ret, lw=0.8, alpha=0.6, label=f"seed {seed}")
    if mean is not None:
        ax.plot(*mean, color="k", lw=2, label="mean")
    ax.set_xlabel("training steps")
    ax.set_ylabel("episode return (moving average)")
    ax.set_title(f"{env}: trained {cond}")
    ax.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path)


# -- a study over sensor sets (the perceived-objects observation) ---------------------------------------------------


def complete(table: dict[str, Any]) -> dict[str, Any]:
    """The rows of ``table`` that have every test fog (an interrupted study reports what it has)."""
    return {cond: row for cond, row in table.items() if all(t in row for t in TEST_LEVELS)}


def _cell(c: dict[str, Any], fmt: str, scale: float = 1.0) -> str:
    ci = "n/a" if c["ci95"] is None else fmt.format(c["ci95"] * scale)
    return f"{fmt.format(c['mean'] * scale)} ± {ci}"


def best_condition(table: dict[str, Any], test: str) -> str | None:
    """The training condition with the highest mean return tested at ``test`` (None for an empty table)."""
    rows = [c for c in CONDITIONS if c in table and test in table[c]]
    return max(rows, key=lambda c: table[c][test]["return"]["mean"]) if rows else None


def sensor_statements(sset: str, table: dict[str, Any], drivers: dict[str, Any]) -> list[str]:
    """What one sensor set's matrix says: the fog effect, the best condition in dense fog and its cost in clear air,
    the curricula against dense-only and mixed training, and the agents against the scripted driver.

    >>> cell = lambda r, ci: {"return": {"mean": r, "ci95": ci}, "collision": {"mean": 0.1, "ci95": 0.05}}
    >>> t = {"clear": {"clear": cell(40, 2), "dense": cell(20, 2)}, "dense": {"clear": cell(30, 2), "dense": cell(25, 2)}}
    >>> sensor_statements("lidar", t, {"clear": {"return": 50.0}})[1]
    '- Best in dense fog: trained dense (return 25.0 ± 2.0); it costs 10.0 in clear air against the best there (clear, 40.0).'
    """
    out = ["- Fog effect (tested clear vs dense, same agents): " + "; ".join(
        f"{cond} {table[cond]['clear']['return']['mean']:.1f} vs {table[cond]['dense']['return']['mean']:.1f} — "
        f"{_verdict(table[cond]['clear']['return'], table[cond]['dense']['return'])}"
        for cond in CONDITIONS if cond in table and "clear" in table[cond] and "dense" in table[cond])]  # fmt: skip
    best_d, best_c = best_condition(table, "dense"), best_condition(table, "clear")
    if best_d is not None and best_c is not None:
        d, cost = table[best_d]["dense"]["return"], table[best_c]["clear"]["return"]["mean"] - table[best_d]["clear"]["return"]["mean"]
        out.append(f"- Best in dense fog: trained {best_d} (return {_cell(d, '{:.1f}')}); it costs {cost:.1f} in clear air "
                   f"against the best there ({best_c}, {table[best_c]['clear']['return']['mean']:.1f}).")  # fmt: skip
    for cur in ("curriculum", "success", "continuous"):
        if cur not in table or "dense" not in table[cur]:
            continue
        parts = [f"vs {ref} {table[ref]['dense']['return']['mean']:.1f} — "
                 f"{_verdict(table[cur]['dense']['return'], table[ref]['dense']['return'])}"
                 for ref in ("dense", "mixed") if ref in table and "dense" in table[ref]]  # fmt: skip
        if parts:
            out.append(f"- {cur} tested dense: {table[cur]['dense']['return']['mean']:.1f}, " + ", ".join(parts))
    gaps = []
    for test in TEST_LEVELS:
        best = best_condition(table, test)
        drv = drivers.get(test)
        if best is not None and drv and drv["return"] > 0:
            gaps.append(f"{test} {table[best][test]['return']['mean'] / drv['return']:.0%} ({best})")
    if gaps:
        out.append("- Best agent / scripted driver (return): " + ", ".join(gaps))
    return out


def render_sensor_study(tables: dict[str, Any], drivers: dict[str, Any], meta: dict[str, Any]) -> str:
    """The Markdown of a study over sensor sets: the drivers' bound, then per set its return and collision-rate
    matrices (mean over training seeds ± 95 % CI across seeds) and :func:`sensor_statements`."""
    lines = _header(meta, f"{meta['env']} with perceived objects: fog × training condition × sensor set", "agent")
    lines += ["## The scripted detection driver (return, collision rate)", "",
              "| sensors | " + " | ".join(TEST_LEVELS) + " |", "|---|" + "---|" * len(TEST_LEVELS)]  # fmt: skip
    for sset in meta["sensor_sets"]:
        d = drivers.get(sset, {})
        lines.append(f"| {sset} | " + " | ".join(f"{d[t]['return']:.1f} ({d[t]['collisions']:.0%})" if t in d else "—"
                                                 for t in TEST_LEVELS) + " |")  # fmt: skip
    for sset in meta["sensor_sets"]:
        table = tables.get(sset, {})
        lines += ["", f"## {sset}", ""]
        for metric, label, fmt, scale in (("return", "return", "{:.1f}", 1.0), ("collision", "collision rate [%]", "{:.0f}", 100.0)):
            lines += [f"**{label}**", "", "| trained on \\ tested on | " + " | ".join(TEST_LEVELS) + " |",
                      "|---|" + "---|" * len(TEST_LEVELS)]  # fmt: skip
            for cond in [c for c in CONDITIONS if c in table]:
                lines.append(f"| {cond} | " + " | ".join(_cell(table[cond][t][metric], fmt, scale) if t in table[cond]
                                                         else "—" for t in TEST_LEVELS) + " |")  # fmt: skip
            lines.append("")
        lines += sensor_statements(sset, table, drivers.get(sset, {}))
    return "\n".join(lines)


def result_json(tables: dict[str, Any], drivers: dict[str, Any], meta: dict[str, Any]) -> dict[str, Any]:
    """The machine-readable result: env, algo, steps, seeds, the drivers' return and collision rate per sensor set and
    fog, and every cell's mean and 95 % CI (``[lo, hi]``, null for one seed) of return and collision rate."""

    def ci(c: dict[str, Any]) -> list[float] | None:
        return None if c["ci95"] is None else [c["mean"] - c["ci95"], c["mean"] + c["ci95"]]

    cells = [{"sensor": sset, "train": cond, "test": test,
              "return_mean": row[test]["return"]["mean"], "return_ci": ci(row[test]["return"]),
              "collision_mean": row[test]["collision"]["mean"], "collision_ci": ci(row[test]["collision"])}
             for sset in meta["sensor_sets"] for cond, row in tables.get(sset, {}).items() for test in TEST_LEVELS
             if test in row]  # fmt: skip
    return {"env": meta["env"], "algo": meta.get("algo", "PPO"), "steps": meta["steps"], "seeds": meta["seeds"],
            "drivers": {s: {t: {"return": d["return"], "collisions": d["collisions"]} for t, d in drivers.get(s, {}).items()}
                        for s in meta["sensor_sets"]},
            "cells": cells}  # fmt: skip


def sensor_fog_effect(tables: dict[str, Any], drivers: dict[str, Any], env: str, path: Path) -> None:
    """Per sensor set: the best-in-dense condition's return and collision rate against the test fog (± 95 % CI
    across seeds), the clear-trained agents', and the scripted driver's (dashed)."""
    import matplotlib.pyplot as plt

    from fog_gym.experiments.runner import save_figure

    sets = [s for s in tables if s is not None]
    fig, axes = plt.subplots(2, max(1, len(sets)), figsize=(3.4 * max(1, len(sets)), 6), dpi=120, squeeze=False)
    x = np.arange(len(TEST_LEVELS))
    for col, sset in enumerate(sets):
        table = complete(tables[sset])
        rows = [c for c in dict.fromkeys(("clear", best_condition(table, "dense"))) if c in table]
        for r, (metric, label, scale) in enumerate((("return", "return", 1.0), ("collision", "collisions [%]", 100.0))):
            ax = axes[r, col]
            for k, cond in enumerate(rows):
                cells = [table[cond][t][metric] for t in TEST_LEVELS]
                ax.errorbar(x + 0.05 * k, [c["mean"] * scale for c in cells],
                            yerr=[0.0 if c["ci95"] is None else c["ci95"] * scale for c in cells], marker="o", ms=4,
                            capsize=3, label=f"trained {cond}")  # fmt: skip
            d = drivers.get(sset, {})
            if all(t in d for t in TEST_LEVELS):
                key = "return" if metric == "return" else "collisions"
                ax.plot(x, [d[t][key] * scale for t in TEST_LEVELS], "k--", lw=1, label="scripted driver")
            ax.set_xticks(x, TEST_LEVELS, fontsize=7)
            ax.set_title(f"{sset}: {label}", fontsize=9)
            if metric == "collision":
                ax.set_ylim(-5, 105)
            if r == 0 or col == 0:  # each set's best-in-dense condition is its own: a legend per column
                ax.legend(fontsize=6)
    fig.suptitle(f"{env}: tested fog (mean over training seeds ± 95 % CI); per sensor set the clear-trained "
                 "agents and the condition best in dense fog", fontsize=9)
    fig.tight_layout()
    save_figure(fig, path)

"""Experiment 1's report: a verdict per claim from paired bootstrap comparisons, the matrices (training subset ×
test fog) of mAP@0.5, Mean TP, ATE, ASE, AOE and FDS at the best-FDS epoch — mean over seeds ± the 95 % CI across
seeds — per detector, per-class AP and AP per distance band, the learning curve, and the figures.

**Comparisons** (:func:`comparisons`): on the same test sweeps, for each detector and test level, the difference
of a metric between two training rows, with a 95 % interval from a two-level bootstrap
(:mod:`fog_gym.metrics.bootstrap`: test scenes resampled with replacement, the same resample for both rows; each
row's seeds resampled with replacement; :data:`~fog_gym.metrics.bootstrap.N_RESAMPLES` resamples). A difference is
"better" when its interval lies above 0, "worse" when below, else "not resolved".

**Verdicts** (:func:`verdicts`), per detector, over the light, moderate and dense test columns:

* *Claim 1, mixing densities tightens geometry at no cost in mAP*: Mixed-L against Light and against Dense in ATE
  and ASE (12 differences) and mAP (6). **Confirmed** when every geometry difference is better and no mAP
  difference is worse; **refuted** when a geometry difference or an mAP difference is worse; else **not resolved
  at this power**.
* *Claim 2, Mixed-S matches the single-density rows at the same data budget*: Mixed-S (thinned to the Light row's
  sweep count) against Light and against Dense in mAP (6 differences), as non-inferiority with a margin of
  :data:`MARGIN` mAP. **Confirmed** when every interval's lower end is above −margin; **refuted** when an
  interval's upper end is below −margin; else **not resolved at this power**.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from fog_gym.experiments.detection3d.protocol import TEST_COLUMNS, TRAIN_ROWS
from fog_gym.experiments.runner import Report, aggregate, fmt_stat, save_figure

TABLES = (("mAP", "mAP@0.5 (3D IoU)"), ("mean_TP", "Mean TP"), ("ATE", "ATE (1 − error / 2 m)"),
          ("ASE", "ASE (1 − scale error)"), ("AOE", "AOE (1 − orientation error / π)"), ("FDS", "FDS (½ mAP + ½ Mean TP)"))  # fmt: skip
FOG_COLUMNS = ("light", "moderate", "dense")
#: Non-inferiority margin of claim 2 [mAP].
MARGIN = 0.02
#: The competence bar of the pillar detector's best row on the light test column (the issue's; TransFusion 0.89–0.93).
COMPETENCE = 0.85
CLASS_NAMES = {0: "car", 4: "bigger car", 1: "truck"}
DETECTOR_NAMES = {"pillars": "PointPillars + CenterPoint heads", "bev": "small BEV CenterNet"}


# -- tables ----------------------------------------------------------------------------------------------------
def tables(records: dict[str, dict[str, Any]], rows: tuple[str, ...]) -> dict[str, dict[str, Any]]:
    """Per detector, :func:`~fog_gym.experiments.runner.aggregate` of the rows stage's best-FDS cells (metrics,
    per-class AP as ``AP/<class>``, AP per band as ``band/<name>``)."""
    cells: dict[str, dict[str, Any]] = {}
    for r in records.values():
        if r["stage"] != "rows":
            continue
        det, row, res = r["params"]["detector"], r["params"]["row"], r["result"]
        for col, b in res["best"].items():
            flat = {k: v for k, v in b.items() if isinstance(v, (int, float)) and not isinstance(v, bool)}
            flat |= {f"AP/{c}": v for c, v in b.get("AP", {}).items()}
            flat |= {f"band/{n}": v for n, v in b.get("bands", {}).items() if v is not None and not math.isnan(v)}
            cells.setdefault(det, {}).setdefault(row, {}).setdefault(col, {})[r["seed"]] = flat
    return {det: aggregate({row: c[row] for row in rows if row in c}) for det, c in cells.items()}


def matrix_markdown(table: dict[str, Any], seeds: int) -> list[str]:
    across = f" (mean ± 95 % CI across {seeds} seeds)" if seeds > 1 else ""
    lines = []
    cols = [c for c in TEST_COLUMNS if any(c in r for r in table.values())]
    for metric, title in TABLES:
        lines += [f"**{title}** — best-FDS epoch per cell{across}; column-wise best in bold", "",
                  "| train ↓ / test → | " + " | ".join(cols) + " |", "|---|" + "---|" * len(cols)]  # fmt: skip
        best_col = {c: max((r[c][metric]["mean"] for r in table.values() if c in r), default=0.0) for c in cols}
        for name, r in table.items():
            cells = []
            for c in cols:
                text = fmt_stat(r[c][metric], "{:.3f}")
                cells.append(f"**{text}**" if r[c][metric]["mean"] == best_col[c] and len(table) > 1 else text)
            lines.append(f"| {name} | " + " | ".join(cells) + " |")
        lines.append("")
    return lines


def competence_markdown(table: dict[str, Any], det: str) -> list[str]:
    """Per-class AP and AP per distance band on every test column, for every row (means over seeds)."""
    lines = ["| train | test | mAP@0.5 | " + " | ".join(CLASS_NAMES.values()) + " | 0–20 m | 20–40 m | 40+ m |",
             "|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for row, cols in table.items():
        for col in FOG_COLUMNS + ("clear",):
            if col not in cols:
                continue
            c = cols[col]

            def cell(key: str) -> str:
                return fmt_stat(c[key], "{:.3f}") if key in c else "–"

            lines.append(f"| {row} | {col} | {cell('mAP')} | " + " | ".join(cell(f"AP/{k}") for k in CLASS_NAMES)
                         + " | " + " | ".join(cell(f"band/{b}") for b in ("0-20 m", "20-40 m", "40+ m")) + " |")  # fmt: skip
    return lines


def best_light_row(table: dict[str, Any]) -> tuple[str, dict[str, Any]] | None:
    """The row with the highest mean mAP on the light test column, and its cell."""
    rows = [(r, c["light"]) for r, c in table.items() if "light" in c]
    return max(rows, key=lambda rc: rc[1]["mAP"]["mean"]) if rows else None


# -- paired comparisons ----------------------------------------------------------------------------------------
def _matches(out: Path, records: dict[str, dict[str, Any]]) -> dict[tuple[str, str], dict[int, dict[str, Any]]]:
    """Per (detector, row), per seed: per test level the frames' match records and scenes."""
    from fog_gym.experiments.detection3d.train import load_predictions
    from fog_gym.metrics.detection3d import match_frames

    found: dict[tuple[str, str], dict[int, dict[str, Any]]] = {}
    for key, r in records.items():
        if r["stage"] != "rows":
            continue
        path = out / "preds" / f"{key}.npz"
        if not path.exists():
            continue
        preds = load_predictions(path)
        found.setdefault((r["params"]["detector"], r["params"]["row"]), {})[r["seed"]] = {
            lv: {"m": match_frames(p["gt"], p["pred"]), "scenes": p["scenes"]} for lv, p in preds.items()}  # fmt: skip
    return found


def comparisons(out: Path, records: dict[str, dict[str, Any]], n: int | None = None, seed: int = 0) -> dict[str, Any]:
    """Paired bootstrap differences (module docstring) for every detector: ``[detector][f"{A} − {B}"][level]
    [metric]`` → :func:`~fog_gym.metrics.bootstrap.interval` plus its ``verdict``."""
    from fog_gym.metrics.bootstrap import N_RESAMPLES, cluster_weights, interval, paired_differences, verdict
    from fog_gym.metrics.detection3d import summarise

    n = n or N_RESAMPLES
    m = _matches(out, records)
    pairs = [("Mixed-L", "Light", ("ATE", "ASE", "mAP")), ("Mixed-L", "Dense", ("ATE", "ASE", "mAP")),
             ("Mixed-S", "Light", ("mAP", "mean_TP")), ("Mixed-S", "Dense", ("mAP", "mean_TP"))]  # fmt: skip
    result: dict[str, Any] = {}
    for det in sorted({d for d, _ in m}):
        for a, b, metrics in pairs:
            if (det, a) not in m or (det, b) not in m:
                continue
            for lv in FOG_COLUMNS:
                ma, mb = m[(det, a)], m[(det, b)]
                if any(lv not in s for s in (*ma.values(), *mb.values())):
                    continue
                scenes = next(iter(ma.values()))[lv]["scenes"]
                w = cluster_weights(scenes, n, seed)
                stats = {}
                for side in (ma, mb):
                    stats[id(side)] = [summarise(s[lv]["m"], w) for s in side.values()]
                    stats[id(side), "obs"] = [summarise(s[lv]["m"]) for s in side.values()]
                for metric in metrics:
                    va = np.stack([s[metric] for s in stats[id(ma)]])
                    vb = np.stack([s[metric] for s in stats[id(mb)]])
                    obs = float(np.mean([s[metric] for s in stats[id(ma), "obs"]]) - np.mean([s[metric] for s in stats[id(mb), "obs"]]))
                    iv = interval(obs, paired_differences(va, vb, seed))
                    iv["verdict"] = verdict(iv)
                    iv["seeds"] = [len(ma), len(mb)]
                    result.setdefault(det, {}).setdefault(f"{a} − {b}", {}).setdefault(lv, {})[metric] = iv
    return result


def verdicts(comp: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """Per detector, the verdicts of the two claims (module docstring), with the differences they rest on."""
    out: dict[str, dict[str, Any]] = {}
    for det, c in comp.items():
        geo, cost, ms = [], [], []
        for base in ("Light", "Dense"):
            for lv in FOG_COLUMNS:
                cell = c.get(f"Mixed-L − {base}", {}).get(lv, {})
                geo += [cell[k] for k in ("ATE", "ASE") if k in cell]
                cost += [cell["mAP"]] if "mAP" in cell else []
                s = c.get(f"Mixed-S − {base}", {}).get(lv, {})
                ms += [s["mAP"]] if "mAP" in s else []
        v1 = "not run"
        if geo:
            if any(g["verdict"] == "worse" for g in geo + cost):
                v1 = "refuted"
            elif len(geo) == 12 and all(g["verdict"] == "better" for g in geo) and len(cost) == 6:
                v1 = "confirmed"
            else:
                v1 = "not resolved at this power"
        v2 = "not run"
        if ms:
            if any(x["hi"] < -MARGIN for x in ms):
                v2 = "refuted"
            elif len(ms) == 6 and all(x["lo"] > -MARGIN for x in ms):
                v2 = "confirmed"
            else:
                v2 = "not resolved at this power"
        out[det] = {"claim1": v1, "claim2": v2,
                    "claim1_better": sum(g["verdict"] == "better" for g in geo), "claim1_n": len(geo),
                    "claim1_map_worse": sum(g["verdict"] == "worse" for g in cost)}  # fmt: skip
    return out


def _iv(iv: dict[str, Any], scale: float = 1.0) -> str:
    return f"{iv['diff'] * scale:+.3f} [{iv['lo'] * scale:+.3f}, {iv['hi'] * scale:+.3f}]"


def comparison_markdown(comp: dict[str, Any], det: str) -> list[str]:
    lines = ["| comparison | test | metric | difference [95 % interval] | reading |", "|---|---|---|---|---|"]
    for name, levels in comp.get(det, {}).items():
        for lv, metrics in levels.items():
            for metric, iv in metrics.items():
                lines.append(f"| {name} | {lv} | {metric} | {_iv(iv)} | {iv['verdict']} |")
    return lines


# -- figures ---------------------------------------------------------------------------------------------------
def matrix_figure(tabs: dict[str, dict[str, Any]], path: Path) -> None:
    """Heatmaps of mAP@0.5, Mean TP and ATE per detector, each cell ``mean ± CI``."""
    import matplotlib.pyplot as plt

    dets = list(tabs)
    metrics = ("mAP", "mean_TP", "ATE")
    fig, axes = plt.subplots(len(dets), 3, figsize=(14, 2.9 * len(dets) + 0.6), squeeze=False)
    for i, det in enumerate(dets):
        table = tabs[det]
        rows = list(table)
        cols = [c for c in TEST_COLUMNS if all(c in table[r] for r in rows)]
        for j, metric in enumerate(metrics):
            ax = axes[i, j]
            mval = np.array([[table[r][c][metric]["mean"] for c in cols] for r in rows])
            im = ax.imshow(mval, cmap="viridis", aspect="auto")
            for a in range(len(rows)):
                for b in range(len(cols)):
                    ci = table[rows[a]][cols[b]][metric]["ci95"]
                    text = f"{mval[a, b]:.3f}" + (f"\n±{ci:.3f}" if ci is not None else "")
                    ax.text(b, a, text, ha="center", va="center", fontsize=7,
                            color="w" if mval[a, b] < np.nanmean(mval) else "k")  # fmt: skip
            ax.set_xticks(range(len(cols)), cols)
            ax.set_yticks(range(len(rows)), rows)
            ax.set_xlabel("test fog")
            ax.set_title(f"{DETECTOR_NAMES.get(det, det)}: {dict(TABLES)[metric].split(' (')[0]}", fontsize=9)
            fig.colorbar(im, ax=ax, fraction=0.046)
        axes[i, 0].set_ylabel("training subset")
    fig.tight_layout()
    save_figure(fig, path, dpi=120)


def curve_figure(records: dict[str, dict[str, Any]], path: Path) -> None:
    """mAP@0.5 on the light test column against training sweeps seen: every evaluation of every unit (mean over
    seeds per row and epoch), and the budget stage's end-of-schedule points."""
    import matplotlib.pyplot as plt

    series: dict[tuple[str, str], dict[int, list[tuple[float, float]]]] = {}
    budget: list[tuple[float, float, int]] = []
    for r in records.values():
        res = r["result"]
        if r["stage"] == "budget":
            last = res["curve"][-1]
            budget.append((last["sweeps_seen"], last["light"]["mAP"], r["params"]["epochs"]))
            continue
        key = (r["params"]["detector"], r["params"]["row"])
        for p in res.get("curve", []):
            if "light" in p:
                series.setdefault(key, {}).setdefault(p["epoch"], []).append((p["sweeps_seen"], p["light"]["mAP"]))
    dets = [d for d in ("pillars", "bev") if any(k[0] == d for k in series) or (d == "pillars" and budget)]
    dets = dets or ["pillars"]
    fig, axes = plt.subplots(1, len(dets), figsize=(6 * len(dets), 4), sharey=True, squeeze=False)
    for ax, det in zip(axes[0], dets, strict=True):
        for (d, row), epochs in sorted(series.items()):
            if d != det:
                continue
            pts = sorted((np.mean([x for x, _ in v]), np.mean([y for _, y in v])) for v in epochs.values())
            ax.plot([p[0] for p in pts], [p[1] for p in pts], marker=".", label=row)
        if det == "pillars" and budget:
            b = sorted(budget)
            ax.plot([x for x, _, _ in b], [y for _, y, _ in b], "k--o", label="Light, end of schedule (budget runs)")
            for x, y, e in b:
                ax.annotate(f"{e} ep", (x, y), textcoords="offset points", xytext=(4, -10), fontsize=7)
        ax.axhline(COMPETENCE, color="grey", ls=":", lw=1, label=f"competence bar {COMPETENCE}")
        ax.set_xscale("log")
        ax.set_xlabel("training sweeps seen")
        ax.set_title(DETECTOR_NAMES[det])
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    axes[0, 0].set_ylabel("mAP@0.5 (3D IoU), light test")
    fig.tight_layout()
    save_figure(fig, path, dpi=120)


def sweeps_figure(root: Path, out: Path, config: Any, key: str, path: Path) -> None:
    """One test sweep per fog level (the same sample): the BEV points, ground-truth boxes and the predictions of
    unit ``key`` that its metrics scored (its best-FDS epoch's, from ``preds/<key>.npz``: no model is needed)."""
    import matplotlib.pyplot as plt

    from fog_gym.dataset.access import FogDrive
    from fog_gym.experiments.detection3d.data import SweepCache, SweepDataset
    from fog_gym.experiments.detection3d.protocol import evaluation_subsets
    from fog_gym.experiments.detection3d.train import load_predictions
    from fog_gym.geometry import box_corners

    ds = FogDrive(root)
    tests = evaluation_subsets(ds.splits["test"], config.seed, config.test_fraction)
    cache = SweepCache(out / "cache", config.pillar_config.grid)
    det = key.split("_")[0]
    preds = load_predictions(out / "preds" / f"{key}.npz")
    levels = [lv for lv in ("clear", *FOG_COLUMNS) if lv in tests and lv in preds]
    fig, axes = plt.subplots(1, len(levels), figsize=(4.6 * len(levels), 4.8), squeeze=False)
    for ax, lv in zip(axes[0], levels, strict=True):
        data = SweepDataset(ds, tests[lv], cache, det, config.grid(det), config.test_every)
        if len(data) != len(preds[lv]["pred"]):
            raise ValueError(f"{key}: {len(preds[lv]['pred'])} {lv} predictions for {len(data)} test sweeps")
        counts = [len(cache.get(*it[:3])[1]["boxes"]) for it in data.items]
        k = int(np.argmax(counts))
        pred = preds[lv]["pred"][k]
        p, gt = cache.get(*data.items[k][:3])
        pts = p.points
        ax.scatter(pts[:, 1], pts[:, 0], s=0.2, c=pts[:, 2], cmap="Greys", vmin=-3, vmax=1, rasterized=True)
        for boxes, colour, label in ((gt["boxes"], "tab:green", "ground truth"), (pred["boxes"], "tab:red", "prediction")):
            for n, b in enumerate(np.asarray(boxes).reshape(-1, 7)):
                c = box_corners(b[None, :3], b[None, 3:6], b[None, 6])[0, [0, 1, 2, 3, 0]]
                ax.plot(c[:, 1], c[:, 0], color=colour, lw=1, label=label if n == 0 else None)
        r = config.range_m
        ax.set_xlim(-r, r)  # seen from above with x (forward) up, the LiDAR frame's +y (right) is to the right
        ax.set_ylim(-r, r)
        ax.set_aspect("equal")
        ax.set_xlabel("y [m] (right)")
        ax.set_ylabel("x [m] (forward)")
        ax.set_title(f"{lv}: {len(pts)} points, {len(gt['boxes'])} boxes")
        ax.legend(loc="lower left", fontsize=7)
    fig.suptitle(f"{DETECTOR_NAMES[det]} trained on {key.split('_')[1]} (seed {key.rsplit('_s', 1)[1]}): one test sweep per fog level")
    fig.tight_layout()
    save_figure(fig, path, dpi=110)


# -- the report ------------------------------------------------------------------------------------------------
def _verdict_lines(tabs: dict[str, Any], comp: dict[str, Any], ver: dict[str, Any]) -> list[str]:
    lines = ["## Verdicts", ""]
    for det, v in ver.items():
        name = DETECTOR_NAMES.get(det, det)
        c = comp.get(det, {})

        def span(cmp: str, metric: str) -> str:
            cells = [c.get(cmp, {}).get(lv, {}).get(metric) for lv in FOG_COLUMNS]
            return ", ".join(f"{lv} {_iv(x)}" for lv, x in zip(FOG_COLUMNS, cells, strict=True) if x)

        def pair(cmp: str, metrics: tuple[str, ...]) -> str:
            parts = [f"{m} {span(cmp, m)}" for m in metrics if span(cmp, m)]
            return f"{cmp}: " + ("; ".join(parts) if parts else f"not run (no {cmp.split(' − ')[1]} row)")

        claim1 = f"**{name}** — claim 1 (mixing densities tightens geometry at no mAP cost): **{v['claim1']}**"
        if v["claim1"] == "not run":
            claim1 += " (the Mixed-L row has not been trained yet)."
        else:
            claim1 += (f" ({v['claim1_better']} of {v['claim1_n']} ATE/ASE differences better, {v['claim1_map_worse']} of "
                       f"6 mAP differences worse). " + ". ".join(pair(f"Mixed-L − {b}", ("ATE", "ASE", "mAP"))
                                                          for b in ("Light", "Dense")) + ".")  # fmt: skip
        claim2 = (f"**{name}** — claim 2 (Mixed-S matches the single-density rows at equal sweeps, margin {MARGIN} mAP): "
                  f"**{v['claim2']}**")  # fmt: skip
        if v["claim2"] == "not run":
            claim2 += " (the Mixed-S row, or both single-density rows, have not been trained yet)."
        else:
            claim2 += ". " + "; ".join(pair(f"Mixed-S − {b}", ("mAP",)) for b in ("Light", "Dense")) + "."
        lines += [claim1, "", claim2, ""]
    return lines


def precision_note(records: dict[str, dict[str, Any]]) -> str | None:
    """A line for the report when the units trained at different precisions (``--precision auto`` resolves to bf16
    on a CPU that computes it natively and to fp32 elsewhere, so units kept from several machines may differ).

    >>> precision_note({"a": {"result": {"precision": "bf16"}}, "b": {"result": {"precision": "fp32"}},
    ...                 "c": {"result": {"precision": "bf16"}}})
    '**Units at different precisions**: bf16 for a, c; fp32 for b (kept from machines with and without native bf16).'
    >>> precision_note({"a": {"result": {"precision": "fp32"}}}) is None
    True
    """
    by: dict[str, list[str]] = {}
    for key, r in records.items():
        if r["result"].get("precision"):
            by.setdefault(r["result"]["precision"], []).append(key)
    if len(by) < 2:
        return None
    parts = "; ".join(f"{p} for {', '.join(sorted(keys))}" for p, keys in sorted(by.items()))
    return f"**Units at different precisions**: {parts} (kept from machines with and without native bf16)."


def build(records: dict[str, dict[str, Any]], out: Path, seeds: list[int], config: Any, data: dict[str, Any],
          device: str, root: Path | None = None) -> Report:  # fmt: skip
    """The study's :class:`~fog_gym.experiments.runner.Report`."""
    rows = tuple(r for r in TRAIN_ROWS if r in config.rows)
    tabs = tables(records, rows)
    comp = comparisons(out, records)
    ver = verdicts(comp)
    lines = _verdict_lines(tabs, comp, ver)
    note = precision_note(records)
    lines += [note, ""] if note else []
    for det, table in tabs.items():
        best = best_light_row(table)
        lines += [f"## {DETECTOR_NAMES.get(det, det)}", ""]
        if best is not None:
            row, cell = best
            bar = f" (the competence bar is {COMPETENCE}: {'met' if cell['mAP']['mean'] >= COMPETENCE else 'not met'})" if det == "pillars" else ""
            lines += [f"Best row on the light test column: **{row}**, mAP@0.5 {fmt_stat(cell['mAP'], '{:.3f}')}{bar}.", ""]
        lines += matrix_markdown(table, len(seeds))
        across = f"mean ± 95 % CI across {len(seeds)} seeds" if len(seeds) > 1 else "one seed"
        lines += [f"**Per-class AP and AP per distance band** (best-FDS epoch per cell, {across}; "
                  "bands by the bird's-eye distance of the box centre)", ""] + competence_markdown(table, det) + [""]  # fmt: skip
        if comp.get(det):
            drawn = "test scenes and seeds resampled" if len(seeds) > 1 else "test scenes resampled, one seed"
            lines += [f"**Paired comparisons** ({drawn}; differences A − B, higher is better for every metric)", ""] \
                + comparison_markdown(comp, det) + [""]  # fmt: skip
    budget = {r["params"]["epochs"]: r["result"] for r in records.values() if r["stage"] == "budget"}
    if budget:
        lines += ["## Learning curve (pillar detector, Light row, first seed, end of each schedule)", "",
                  "| epochs | sweeps seen | mAP@0.5 light | mAP@0.5 dense | minutes |", "|---|---|---|---|---|"]  # fmt: skip
        main = [r["result"] for r in records.values() if r["stage"] == "rows" and r["params"]["detector"] == "pillars"
                and r["params"]["row"] == "Light" and r["seed"] == seeds[0]]  # fmt: skip
        allb = {**budget, **({config.epochs: main[0]} if main else {})}
        for e in sorted(allb):
            last = allb[e]["curve"][-1]
            lines.append(f"| {e} | {last['sweeps_seen']} | {last['light']['mAP']:.3f} | {last['dense']['mAP']:.3f} | "
                         f"{allb[e]['seconds'] / 60:.1f} |")  # fmt: skip
        lines.append("")
    figures = {"exp1.png": lambda p: matrix_figure(tabs, p), "exp1_curve.png": lambda p: curve_figure(records, p)}
    pillar_rows = tabs.get("pillars") or tabs.get("bev")
    if pillar_rows and root is not None:
        det = "pillars" if "pillars" in tabs else "bev"
        best = best_light_row(pillar_rows)
        if best is not None:
            key = f"{det}_{best[0]}_s{seeds[0]}"
            if (out / "preds" / f"{key}.npz").exists():
                figures["exp1_sweeps.png"] = lambda p: sweeps_figure(root, out, config, key, p)
    from dataclasses import asdict

    result = {"config": asdict(config), "device": device, "seeds": seeds, "data": data, "tables": tabs,
              "comparisons": comp, "verdicts": ver,
              "units": {k: {"stage": r["stage"], "params": r["params"], "seed": r["seed"], "result": r["result"]}
                        for k, r in records.items()}}  # fmt: skip
    return Report("\n".join(lines), result, "exp1.md", "results.json", figures)

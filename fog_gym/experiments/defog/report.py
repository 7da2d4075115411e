"""Experiment 2's report: a verdict per claim from paired bootstrap comparisons on the same test images, the detection
and image-quality tables (means over seeds ± the 95 % CI across seeds), the rank correlation of PSNR and SSIM with
detection, and the figures.

**Comparisons** (:func:`bootstrap`): every pipeline's mAP@0.5 (COCO, :func:`~fog_gym.metrics.detection2d.coco_summarise`)
and every dehazer's mean PSNR and SSIM are recomputed on resamples of the test set — test scenes drawn with
replacement (an image counts as often as its scene was drawn) and the training seeds drawn with replacement, one
draw shared by all pipelines (A, B and C use the same seed's clean detector) —
:data:`~fog_gym.metrics.bootstrap.N_RESAMPLES` resamples. A difference is "better" when its 95 % interval lies
above 0, "worse" below, else "not resolved".

**Verdicts** (:func:`verdicts`), over the light, moderate and dense levels; "best C" is the real dehazer (DCP,
AOD-Net or DehazeFormer; not the oracle) with the highest mean mAP@0.5 at that level:

* *(i) a fog-trained detector approaches the clean upper bound*: D − A at each level, as non-inferiority with a
  margin of :data:`MARGIN`: **confirmed** when every interval's lower end is above −margin, **refuted** when an
  interval's upper end is below −margin, else **not resolved at this power**.
* *(ii) defogging helps but less than training on fog, and the gap grows with density*: best C − B > 0 and
  D − best C > 0 at each level, and (D − best C) at dense minus at light > 0. **Confirmed** when all seven
  intervals lie above 0, **refuted** when one lies below 0, else **not resolved at this power**.
* *(iii) PSNR / SSIM do not predict detection*, per metric: the Spearman correlation of the metric with mAP@0.5
  across dehazers × levels (pooled, as the paper) and within each level (the mean of the three; pooling mixes the
  levels, where both fall with density), each with its bootstrap interval, and every **rank reversal**: two
  dehazers at one level where the one with the higher metric has the lower mAP, both differences resolved.
  **Confirmed** when a rank reversal exists; **refuted** when none exists and the within-level correlation's
  interval lies above 0; else **not resolved at this power**.
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path
from typing import Any

import numpy as np

from fog_gym.experiments.defog.dehazers import DEHAZERS
from fog_gym.experiments.runner import Report, aggregate, fmt_stat, save_figure
from fog_gym.metrics.bootstrap import nanmean

PIPELINE_NAMES = {"A": "A (clean→clean)", "B": "B (clean→fog)", "C-DCP": "C – DCP", "C-AOD-Net": "C – AOD-Net (trained here)",
                  "C-DehazeFormer": "C – DehazeFormer-T (trained here)", "C-oracle": "C – oracle", "D": "D (fog→fog)"}  # fmt: skip
LEVELS = ("light", "moderate", "dense")
REAL_DEHAZERS = ("DCP", "AOD-Net", "DehazeFormer")
#: Non-inferiority margin of claim (i) [mAP@0.5].
MARGIN = 0.05
#: The competence bar of pipeline A (the issue's; the paper's YOLOv8-m: 0.680).
COMPETENCE = 0.45
CLASS_NAMES = {0: "car", 4: "bigger car", 1: "truck"}


# -- tables ----------------------------------------------------------------------------------------------------
def tables(records: dict[str, dict[str, Any]]) -> tuple[dict[str, Any], dict[str, Any]]:
    det_cells: dict[str, Any] = {}
    iq_cells: dict[str, Any] = {}
    for r in records.values():
        if r["stage"] != "evaluate":
            continue
        for p, levels in r["result"]["detection"].items():
            for lv, cell in levels.items():
                det_cells.setdefault(p, {}).setdefault(lv, {})[r["seed"]] = cell
        for lv, methods in r["result"]["image_quality"].items():
            for m, cell in methods.items():
                iq_cells.setdefault(lv, {}).setdefault(m, {})[r["seed"]] = cell
    return aggregate(det_cells), aggregate(iq_cells)


def table_markdown(detection: dict[str, Any], image_quality: dict[str, Any], seeds: int) -> list[str]:
    across = f"; mean ± 95 % CI across {seeds} seeds" if seeds > 1 else ""
    lines = [f"**Detection** (COCO evaluation of every box; P and R at confidence 0.25; AP@0.5 per class{across})", "",
             "| Pipeline | Fog | mAP@0.5 | mAP@.5:.95 | P | R | car | truck | bigger car |", "|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for key, name in PIPELINE_NAMES.items():
        for lv, r in detection.get(key, {}).items():
            cls = [fmt_stat(r[f"AP50/{c}"], "{:.3f}") if f"AP50/{c}" in r else "–" for c in (0, 1, 4)]
            lines.append(f"| {name} | {lv} | " + " | ".join(fmt_stat(r[m], "{:.3f}") for m in ("mAP50", "mAP50_95",
                         "precision", "recall")) + " | " + " | ".join(cls) + " |")  # fmt: skip
    levels = list(image_quality)
    lines += ["", f"**Image quality** against the paired clean frame (640 × 480{across}; seconds per image of each "
              "dehazer on this machine)", "",
              "| Method | " + " | ".join(f"PSNR {lv}" for lv in levels) + " | " + " | ".join(f"SSIM {lv}" for lv in levels)
              + " | s / image |", "|---|" + "---|" * (2 * len(levels) + 1)]  # fmt: skip
    for method in ("foggy", *DEHAZERS):
        if method not in image_quality.get(levels[0], {}):
            continue
        sec = image_quality[levels[0]][method].get("seconds_per_image")
        lines.append(f"| {method} | " + " | ".join(fmt_stat(image_quality[lv][method]["PSNR"], "{:.2f}") for lv in levels)
                     + " | " + " | ".join(fmt_stat(image_quality[lv][method]["SSIM"], "{:.3f}") for lv in levels)
                     + (f" | {sec['mean']:.3f} |" if sec else " | – |"))  # fmt: skip
    return lines


# -- the bootstrap ---------------------------------------------------------------------------------------------
def bootstrap(out: Path, records: dict[str, dict[str, Any]], n: int | None = None, seed: int = 0) -> dict[str, Any]:
    """Resampled mAP@0.5 of every pipeline and level, and PSNR / SSIM of every method and level: ``{"observed":
    {...}, "resampled": {...}}`` keyed ``("map", pipeline, level)``, ``("PSNR" | "SSIM", method, level)``, each
    observed value the mean over seeds and each resampled array (R,) the mean over that resample's seed draw."""
    from fog_gym.experiments.defog.evaluate import load_records
    from fog_gym.metrics.bootstrap import N_RESAMPLES, apply_draws, cluster_weights, seed_draws
    from fog_gym.metrics.detection2d import coco_matches, coco_summarise

    n = n or N_RESAMPLES
    evals = sorted((r["seed"], k) for k, r in records.items() if r["stage"] == "evaluate"
                   and (out / "records" / f"{k}.npz").exists())  # fmt: skip
    if not evals:
        return {"observed": {}, "resampled": {}}
    per_seed: dict[tuple[str, str, str], list[np.ndarray]] = {}
    observed: dict[tuple[str, str, str], list[float]] = {}
    w = None
    for _, key in evals:
        rec = load_records(out / "records" / f"{key}.npz")
        if w is None:
            w = cluster_weights(rec["scenes"], n, seed)
        for p, levels in rec["pred"].items():
            for lv, preds in levels.items():
                m = coco_matches(rec["gt"], preds)
                per_seed.setdefault(("map", p, lv), []).append(coco_summarise(m, w)["mAP50"])
                observed.setdefault(("map", p, lv), []).append(coco_summarise(m)["mAP50"])
        for lv, methods in rec["iq"].items():
            for method, q in methods.items():
                for metric in ("PSNR", "SSIM"):
                    v = np.asarray(q[metric], np.float64)
                    ok = np.isfinite(v)
                    per_seed.setdefault((metric, method, lv), []).append((w @ np.where(ok, v, 0.0)) / np.maximum(w @ ok, 1))
                    observed.setdefault((metric, method, lv), []).append(float(v[ok].mean()) if ok.any() else math.nan)
    draws = seed_draws(len(evals), n, np.random.default_rng([seed, 7]))
    return {"observed": {k: float(np.mean(v)) for k, v in observed.items()},
            "resampled": {k: apply_draws(np.stack(v), draws) for k, v in per_seed.items()}, "seeds": len(evals)}  # fmt: skip


def _diff(bs: dict[str, Any], a: tuple, b: tuple) -> dict[str, Any]:
    from fog_gym.metrics.bootstrap import interval, verdict

    iv = interval(bs["observed"][a] - bs["observed"][b], bs["resampled"][a] - bs["resampled"][b])
    iv["verdict"] = verdict(iv)
    return iv


def best_c(bs: dict[str, Any], lv: str) -> str | None:
    """The real dehazer with the highest mean mAP@0.5 at ``lv``."""
    have = [d for d in REAL_DEHAZERS if ("map", f"C-{d}", lv) in bs["observed"]]
    return max(have, key=lambda d: bs["observed"][("map", f"C-{d}", lv)]) if have else None


def _spearman_rows(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Spearman's ρ of the columns' pairs, per row of ``x`` and ``y`` (R, P)."""
    from scipy.stats import rankdata

    rx, ry = rankdata(x, axis=1), rankdata(y, axis=1)
    rx -= rx.mean(1, keepdims=True)
    ry -= ry.mean(1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return (rx * ry).sum(1) / np.sqrt((rx**2).sum(1) * (ry**2).sum(1))


def comparisons(bs: dict[str, Any]) -> dict[str, Any]:
    """Every comparison the verdicts rest on (module docstring), and the image-quality analysis."""
    from fog_gym.metrics.bootstrap import interval

    if not bs["observed"]:
        return {}
    comp: dict[str, Any] = {"D − A": {}, "D − B": {}, "best C − B": {}, "D − best C": {}, "C − B": {}, "best C": {}}
    for lv in LEVELS:
        if ("map", "D", lv) not in bs["observed"]:
            continue
        comp["D − A"][lv] = _diff(bs, ("map", "D", lv), ("map", "A", "clean"))
        comp["D − B"][lv] = _diff(bs, ("map", "D", lv), ("map", "B", lv))
        for d in DEHAZERS:
            if ("map", f"C-{d}", lv) in bs["observed"]:
                comp["C − B"].setdefault(d, {})[lv] = _diff(bs, ("map", f"C-{d}", lv), ("map", "B", lv))
        c = best_c(bs, lv)
        if c is not None:
            comp["best C"][lv] = c
            comp["best C − B"][lv] = _diff(bs, ("map", f"C-{c}", lv), ("map", "B", lv))
            comp["D − best C"][lv] = _diff(bs, ("map", "D", lv), ("map", f"C-{c}", lv))
    if all(lv in comp["D − best C"] for lv in ("light", "dense")):
        from fog_gym.metrics.bootstrap import verdict

        def gap(lv: str, src: str) -> Any:
            c = comp["best C"][lv]
            return bs[src][("map", "D", lv)] - bs[src][("map", f"C-{c}", lv)]

        iv = interval(gap("dense", "observed") - gap("light", "observed"), gap("dense", "resampled") - gap("light", "resampled"))
        iv["verdict"] = verdict(iv)
        comp["gap dense − light"] = iv
    # image quality against detection
    iqa: dict[str, Any] = {}
    methods = [d for d in DEHAZERS if ("PSNR", d, LEVELS[0]) in bs["observed"] and ("map", f"C-{d}", LEVELS[0]) in bs["observed"]]
    for metric in ("PSNR", "SSIM"):
        pts = [(d, lv) for lv in LEVELS for d in methods]
        x_obs = np.array([[bs["observed"][(metric, d, lv)] for d, lv in pts]])
        y_obs = np.array([[bs["observed"][("map", f"C-{d}", lv)] for d, lv in pts]])
        x_res = np.stack([bs["resampled"][(metric, d, lv)] for d, lv in pts], 1)
        y_res = np.stack([bs["resampled"][("map", f"C-{d}", lv)] for d, lv in pts], 1)
        pooled = interval(float(_spearman_rows(x_obs, y_obs)[0]), _spearman_rows(x_res, y_res))
        k = len(methods)
        within_obs = np.mean([_spearman_rows(x_obs[:, i * k:(i + 1) * k], y_obs[:, i * k:(i + 1) * k])[0] for i in range(len(LEVELS))])
        within_res = nanmean(np.stack([_spearman_rows(x_res[:, i * k:(i + 1) * k], y_res[:, i * k:(i + 1) * k])
                                       for i in range(len(LEVELS))]), axis=0)  # fmt: skip
        within = interval(float(within_obs), within_res)
        reversals = []
        for lv in LEVELS:
            for a, b in itertools.permutations(methods, 2):
                q = _diff(bs, (metric, a, lv), (metric, b, lv))
                m = _diff(bs, ("map", f"C-{a}", lv), ("map", f"C-{b}", lv))
                if q["lo"] > 0 and m["hi"] < 0:
                    reversals.append({"level": lv, "higher": a, "lower": b, "quality": q, "mAP": m})
        iqa[metric] = {"pooled": pooled, "within": within, "reversals": reversals,
                       "points": [{"method": d, "level": lv, metric: bs["observed"][(metric, d, lv)],
                                   "mAP50": bs["observed"][("map", f"C-{d}", lv)]} for d, lv in pts]}  # fmt: skip
    comp["image_quality"] = iqa
    return comp


def verdicts(comp: dict[str, Any]) -> dict[str, str]:
    """The three claims' verdicts (module docstring)."""
    if not comp:
        return {}
    out: dict[str, str] = {}
    da = list(comp["D − A"].values())
    if len(da) == 3:
        out["i"] = ("refuted" if any(x["hi"] < -MARGIN for x in da) else "confirmed" if all(x["lo"] > -MARGIN for x in da)
                    else "not resolved at this power")  # fmt: skip
    parts = [*comp["best C − B"].values(), *comp["D − best C"].values()]
    if "gap dense − light" in comp:
        parts.append(comp["gap dense − light"])
    if len(parts) == 7:
        out["ii"] = ("refuted" if any(x["hi"] < 0 for x in parts) else "confirmed" if all(x["lo"] > 0 for x in parts)
                     else "not resolved at this power")  # fmt: skip
    for metric, a in comp.get("image_quality", {}).items():
        out[f"iii-{metric}"] = ("confirmed" if a["reversals"] else "refuted" if a["within"]["lo"] > 0
                                else "not resolved at this power")  # fmt: skip
    return out


def _iv(iv: dict[str, Any]) -> str:
    return f"{iv['diff']:+.3f} [{iv['lo']:+.3f}, {iv['hi']:+.3f}]"


def verdict_markdown(comp: dict[str, Any], ver: dict[str, str]) -> list[str]:
    if not comp:
        return []
    lines = ["## Verdicts", ""]

    def per_level(name: str) -> str:
        return "; ".join(f"{lv} {_iv(x)}" for lv, x in comp[name].items())

    if "i" in ver:
        lines += [f"**(i) A fog-trained detector approaches the clean upper bound** (D − A, margin {MARGIN} mAP@0.5): "
                  f"**{ver['i']}**. D − A: {per_level('D − A')}. D − B: {per_level('D − B')}.", ""]  # fmt: skip
    if "ii" in ver:
        best = ", ".join(f"{lv} {c}" for lv, c in comp["best C"].items())
        lines += [f"**(ii) Defogging helps, but less than training on fog, and the gap grows with density**: "
                  f"**{ver['ii']}**. Best real dehazer per level: {best}. Best C − B: {per_level('best C − B')}. "
                  f"D − best C: {per_level('D − best C')}. Gap at dense − gap at light: {_iv(comp['gap dense − light'])}.", ""]  # fmt: skip
    for metric in ("PSNR", "SSIM"):
        key = f"iii-{metric}"
        if key not in ver:
            continue
        a = comp["image_quality"][metric]
        rev = "; ".join(f"{r['level']}: {r['higher']} has the higher {metric} ({_iv(r['quality'])}) but the lower mAP@0.5 "
                        f"({_iv(r['mAP'])}) than {r['lower']}" for r in a["reversals"]) or "none resolved"  # fmt: skip
        lines += [f"**(iii) {metric} does not predict detection**: **{ver[key]}**. Spearman ρ({metric}, mAP@0.5) across "
                  f"dehazers × levels {a['pooled']['diff']:+.2f} [{a['pooled']['lo']:+.2f}, {a['pooled']['hi']:+.2f}]; "
                  f"within a level (mean of three) {a['within']['diff']:+.2f} [{a['within']['lo']:+.2f}, "
                  f"{a['within']['hi']:+.2f}]. Rank reversals: {rev}.", ""]  # fmt: skip
    return lines


def comparison_markdown(comp: dict[str, Any]) -> list[str]:
    if not comp:
        return []
    lines = ["**Paired comparisons of mAP@0.5** (test scenes and seeds resampled; differences A − B)", "",
             "| comparison | fog | difference [95 % interval] | reading |", "|---|---|---|---|"]  # fmt: skip
    for name in ("D − A", "D − B", "best C − B", "D − best C"):
        for lv, iv in comp[name].items():
            label = name.replace("best C", f"C-{comp['best C'][lv]}") if "best C" in name else name
            lines.append(f"| {label} | {lv} | {_iv(iv)} | {iv['verdict']} |")
    for d, levels in comp["C − B"].items():
        for lv, iv in levels.items():
            lines.append(f"| C-{d} − B | {lv} | {_iv(iv)} | {iv['verdict']} |")
    if "gap dense − light" in comp:
        iv = comp["gap dense − light"]
        lines.append(f"| (D − best C) dense − light | – | {_iv(iv)} | {iv['verdict']} |")
    return lines


# -- figures ---------------------------------------------------------------------------------------------------
def clipped_errors(means, half) -> np.ndarray:
    """Matplotlib's ``(2, N)`` lower and upper error-bar lengths of ``means ± half``, cut at 0 and 1 (a score's range).

    >>> clipped_errors([0.1, 0.5], [0.3, 0.2]).round(6).tolist()  # the lower bar cut at 0
    [[0.1, 0.2], [0.3, 0.2]]
    >>> clipped_errors([0.9], [0.5]).round(6).tolist()  # the upper bar cut at 1
    [[0.5], [0.1]]
    """
    means, half = np.asarray(means, float), np.asarray(half, float)
    return np.stack([means - np.maximum(means - half, 0.0), np.minimum(means + half, 1.0) - means])


def figure(detection: dict[str, Any], path: Path) -> None:
    """mAP@0.5 per pipeline and level (bars; the 95 % CIs across seeds as error bars, cut at 0 and 1, the metric's
    range: with two or three seeds a Student-t interval can reach past both), A as a line."""
    import matplotlib.pyplot as plt

    keys = [k for k in ("B", "C-DCP", "C-AOD-Net", "C-DehazeFormer", "C-oracle", "D") if k in detection]
    fig, ax = plt.subplots(figsize=(12, 4))
    width = 0.8 / max(1, len(keys))
    for i, k in enumerate(keys):
        cells = [detection[k][lv]["mAP50"] for lv in LEVELS]
        means = np.array([c["mean"] for c in cells])
        err = None if all(c["ci95"] is None for c in cells) else clipped_errors(means, [c["ci95"] or 0.0 for c in cells])
        ax.bar(np.arange(len(LEVELS)) + i * width, means, width, yerr=err, capsize=2, label=PIPELINE_NAMES[k])
    a = detection["A"]["clean"]["mAP50"]
    ax.axhline(a["mean"], color="k", ls="--", lw=1, label="A (clean→clean)")
    if a["ci95"]:
        ax.axhspan(max(a["mean"] - a["ci95"], 0.0), min(a["mean"] + a["ci95"], 1.0), color="k", alpha=0.08)
    ax.set_ylim(0.0, 1.0)
    ax.set_xticks(np.arange(len(LEVELS)) + 0.4 - width / 2, LEVELS)
    ax.set_xlabel("test fog level")
    ax.set_ylabel("mAP@0.5 (COCO, every box)")
    ax.set_title("Detection per pipeline and fog level (mean ± 95 % CI across seeds, cut at 0 and 1)")
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))  # beside the axes: no bar hidden
    fig.tight_layout()
    save_figure(fig, path, dpi=120)


def quality_figure(comp: dict[str, Any], path: Path) -> None:
    """PSNR and SSIM against mAP@0.5 of every dehazer and level, with the rank correlations."""
    import matplotlib.pyplot as plt

    iqa = comp.get("image_quality", {})
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    markers = {"light": "o", "moderate": "s", "dense": "^"}
    for ax, metric in zip(axes, ("PSNR", "SSIM"), strict=True):
        a = iqa.get(metric)
        if not a:
            continue
        methods = list(dict.fromkeys(p["method"] for p in a["points"]))
        for p in a["points"]:
            ax.scatter(p[metric], p["mAP50"], marker=markers[p["level"]], color=f"C{methods.index(p['method'])}",
                       label=p["method"] if p["level"] == "light" else None)  # fmt: skip
        ax.set_xlabel(f"{metric} against the clean frame" + (" [dB]" if metric == "PSNR" else ""))
        ax.set_ylabel("mAP@0.5 of the clean-trained detector")
        ax.set_title(f"ρ pooled {a['pooled']['diff']:+.2f} [{a['pooled']['lo']:+.2f}, {a['pooled']['hi']:+.2f}], "
                     f"within levels {a['within']['diff']:+.2f}", fontsize=9)  # fmt: skip
        ax.legend(fontsize=7, title="○ light □ moderate △ dense", title_fontsize=7)
        ax.grid(alpha=0.3)
    fig.tight_layout()
    save_figure(fig, path, dpi=120)


def curve_figure(records: dict[str, dict[str, Any]], path: Path) -> None:
    """Validation mAP@0.5 of every detector against training images seen (mean over seeds)."""
    import matplotlib.pyplot as plt

    series: dict[str, dict[int, list[tuple[float, float]]]] = {}
    for r in records.values():
        if r["stage"] != "train" or r["params"].get("model") != "detector":
            continue
        for h in r["result"].get("history", []):
            series.setdefault(r["params"]["level"], {}).setdefault(h["epoch"], []).append((h["images_seen"], h["val_mAP50"]))
    fig, ax = plt.subplots(figsize=(6.5, 4))
    for lv, epochs in series.items():
        pts = sorted((np.mean([x for x, _ in v]), np.mean([y for _, y in v])) for v in epochs.values())
        ax.plot([p[0] for p in pts], [p[1] for p in pts], marker=".", label=f"trained on {lv}")
    ax.axhline(COMPETENCE, color="grey", ls=":", lw=1, label=f"competence bar {COMPETENCE} (pipeline A)")
    ax.set_xlabel("training images seen")
    ax.set_ylabel("validation mAP@0.5 (own level)")
    ax.set_title("Detector learning curves (mean over seeds)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path, dpi=120)


def examples_figure(study: Any, out: Path, seed: int, path: Path) -> None:
    """One test image per fog level through every pipeline (seed ``seed``'s models): predicted boxes scoring at
    least 0.25 (red) and the ground truth (green)."""
    import matplotlib.pyplot as plt
    import torch

    from fog_gym.dataset.access import FogDrive
    from fog_gym.experiments.defog.data import load_boxes, load_image
    from fog_gym.experiments.defog.dehazers import dehazers
    from fog_gym.experiments.defog.evaluate import detect
    from fog_gym.experiments.detection3d.train import resolve_precision

    ds = FogDrive(study.root)
    device = torch.device("cpu")
    clean_det, fog_dets, aod, df = study.load_models(out, seed, device)
    fns = dehazers(ds, aod, df, resolve_precision(study.config.precision, device))
    test = study._frames(ds, "test")
    counts = [len(load_boxes(ds, f)[1]) for f in test]
    f = test[int(np.argsort(counts)[len(counts) * 3 // 4])]  # a busy, not the busiest, image
    boxes, _ = load_boxes(ds, f)
    columns = ["B", *[f"C-{d}" for d in fns], "D"]
    fig, axes = plt.subplots(len(LEVELS) + 1, len(columns), figsize=(2.6 * len(columns), 2.2 * (len(LEVELS) + 1)))
    size = tuple(study.config.input_size)

    def show(ax: Any, img: np.ndarray, model: Any, title: str) -> None:
        from fog_gym.experiments.defog.data import resize

        h0, w0 = img.shape[:2]
        d = detect(model, [resize(img, size)], [(w0 / size[0], h0 / size[1])], device, 0.25)[0]
        ax.imshow(img)
        for b, colour in [(b, "lime") for b in boxes] + [(b, "red") for b in d["boxes"]]:
            ax.add_patch(plt.Rectangle((b[0], b[1]), b[2] - b[0], b[3] - b[1], fill=False, lw=0.8, edgecolor=colour))
        ax.set_title(title, fontsize=7)
        ax.axis("off")

    show(axes[0, 0], load_image(ds, f, "clean"), clean_det, "A: clean → clean")
    for ax in axes[0, 1:]:
        ax.axis("off")
    axes[0, 1].text(0, 0.5, "green: ground truth\nred: detections (score ≥ 0.25)", fontsize=8)
    for i, lv in enumerate(LEVELS, start=1):
        fogged = load_image(ds, f, lv)
        for j, col in enumerate(columns):
            if col == "B":
                show(axes[i, j], fogged, clean_det, f"B ({lv})")
            elif col == "D":
                show(axes[i, j], fogged, fog_dets[lv], f"D ({lv})")
            else:
                show(axes[i, j], fns[col[2:]](fogged, f, lv), clean_det, f"{col} ({lv})")
    fig.suptitle(f"One test image per fog level through every pipeline ({f.camera}, seed {seed})", fontsize=9)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)


# -- the report ------------------------------------------------------------------------------------------------
def build(study: Any, records: dict[str, dict[str, Any]], out: Path, seeds: list[int], data: dict[str, Any],
          device: str) -> Report:  # fmt: skip
    detection, image_quality = tables(records)
    bs = bootstrap(out, records)
    comp = comparisons(bs)
    ver = verdicts(comp)
    lines = verdict_markdown(comp, ver)
    if "A" in detection:
        a = detection["A"]["clean"]["mAP50"]
        lines += [f"Pipeline A (clean → clean): mAP@0.5 {fmt_stat(a, '{:.3f}')} (the competence bar is {COMPETENCE}: "
                  f"{'met' if a['mean'] >= COMPETENCE else 'not met'}).", ""]  # fmt: skip
        if a["mean"] < COMPETENCE and ver:
            lines += ["Below the bar the verdicts describe this detector, not the paper's claims: a detector that finds "
                      "little anywhere makes every pipeline alike.", ""]  # fmt: skip
    lines += table_markdown(detection, image_quality, len(seeds)) + [""] + comparison_markdown(comp) + [""]
    figures: dict[str, Any] = {}
    if detection:
        figures["exp2.png"] = lambda p: figure(detection, p)
    if comp:
        figures["exp2_quality.png"] = lambda p: quality_figure(comp, p)
    figures["exp2_curve.png"] = lambda p: curve_figure(records, p)
    if all((out / "models" / f"{k}_s{seeds[0]}.pt").exists()
           for k in ("detector_clean", *[f"detector_{lv}" for lv in LEVELS], "aodnet", "dehazeformer")):  # fmt: skip
        figures["exp2_examples.png"] = lambda p: examples_figure(study, out, seeds[0], p)

    def plain(x: Any) -> Any:
        if isinstance(x, dict):
            return {str(k): plain(v) for k, v in x.items()}
        if isinstance(x, (list, tuple)):
            return [plain(v) for v in x]
        return x

    result = {"config": study.config.settings(), "device": device, "seeds": seeds, "data": data,
              "detectors": {k: r["result"] for k, r in records.items() if r["stage"] == "train"},
              "detection": detection, "image_quality": image_quality, "comparisons": plain(comp), "verdicts": ver}  # fmt: skip
    return Report("\n".join(lines), result, "exp2.md", "results.json", figures)

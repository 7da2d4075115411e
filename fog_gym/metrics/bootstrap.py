"""Paired bootstrap intervals for comparisons of trained models on the same test items. Pure numpy.

A comparison of two training conditions A and B (two rows of Experiment 1, two pipelines of Experiment 2) has two
sources of noise: which test items were drawn, and which training seeds. The bootstrap here resamples both, as a
two-level (hierarchical) bootstrap:

* **items**, in clusters: consecutive frames of one scene are not independent draws, so a resample draws whole
  scenes with replacement (:func:`cluster_weights`); an item is counted as many times as its scene was drawn.
  Both conditions see the *same* resample (the pairing).
* **seeds**: each condition's seeds are drawn with replacement, independently for A and B
  (:func:`seed_means`), and the metric averaged over the drawn seeds.

A metric of a resample is computed from per-item match records (e.g.
:func:`fog_gym.metrics.detection3d.summarise`), never by matching again. :func:`interval` gives the observed
difference (mean over seeds on the full test set), the percentile interval of the resampled differences and the
share of resamples in which the difference is ≤ 0 (a one-sided bootstrap p-value).

Example:
    >>> w = cluster_weights(np.array(["a", "a", "b", "c"]), 3, seed=0)
    >>> w.shape, bool((w[:, 0] == w[:, 1]).all())  # the two frames of scene "a" are drawn together
    ((3, 4), True)
    >>> r = interval(0.1, np.array([0.05, 0.1, 0.15, 0.2]))
    >>> r["diff"], r["lo"] > 0, r["p_le0"]
    (0.1, True, 0.0)
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np


def nanmean(values: np.ndarray, axis: int = 0) -> np.ndarray:
    """``np.nanmean`` along ``axis`` without its warning: NaN where every value is NaN (a class that no resample or
    seed evaluated is not a number, and not a problem to warn about).

    >>> nanmean(np.array([[1.0, np.nan], [3.0, np.nan]])).tolist()
    [2.0, nan]
    """
    v = np.asarray(values, np.float64)
    ok = ~np.isnan(v)
    n = ok.sum(axis)
    return np.where(n > 0, np.where(ok, v, 0.0).sum(axis) / np.maximum(n, 1), np.nan)


#: Resamples per comparison unless a caller asks for others.
N_RESAMPLES = 2000


def cluster_weights(clusters: Sequence[Any], n: int = N_RESAMPLES, seed: int = 0) -> np.ndarray:
    """``(n, F)`` integer weights of the ``F`` items: per resample, the clusters (e.g. scenes; one label per item)
    are drawn with replacement as many times as there are clusters, and each item is counted as often as its
    cluster was drawn."""
    labels = np.asarray(clusters)
    if labels.ndim != 1 or len(labels) == 0:
        raise ValueError(f"clusters must give one label per item (a non-empty sequence), got shape {labels.shape}")
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"n must be a positive integer, got {n!r}")
    _, index = np.unique(labels, return_inverse=True)
    k = int(index.max()) + 1
    rng = np.random.default_rng(seed)
    draws = rng.integers(0, k, (n, k))
    counts = np.zeros((n, k), np.int64)
    np.add.at(counts, (np.repeat(np.arange(n), k), draws.ravel()), 1)
    return counts[:, index]


def seed_means(values: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """``values`` (S, R): a metric per training seed (rows) and item resample (columns); per resample, the mean over
    S seeds drawn with replacement → (R,)."""
    v = np.asarray(values, np.float64)
    if v.ndim != 2 or v.shape[0] < 1:
        raise ValueError(f"values must be (seeds, resamples), got shape {v.shape}")
    s, r = v.shape
    pick = rng.integers(0, s, (r, s))
    return nanmean(v[pick, np.arange(r)[:, None]], axis=1)


def paired_differences(a: np.ndarray, b: np.ndarray, seed: int = 0) -> np.ndarray:
    """Resampled differences ``mean(A) − mean(B)``: ``a`` (S_a, R) and ``b`` (S_b, R), the metric of each seed of
    each condition on the same R item resamples; seeds drawn independently per condition."""
    rng = np.random.default_rng(seed)
    return seed_means(a, rng) - seed_means(b, rng)


def interval(observed: float, diffs: np.ndarray, level: float = 0.95) -> dict[str, float]:
    """The observed difference, the percentile interval of the resampled ``diffs`` at ``level`` and the share of
    resamples with a difference ≤ 0 (NaN resamples, e.g. a class absent from a resample, are left out)."""
    d = np.asarray(diffs, np.float64)
    d = d[np.isfinite(d)]
    if not 0 < level < 1:
        raise ValueError(f"level must lie in (0, 1), got {level!r}")
    if len(d) == 0:
        return {"diff": float(observed), "lo": float("nan"), "hi": float("nan"), "p_le0": float("nan"), "n": 0}
    lo, hi = np.quantile(d, [(1 - level) / 2, (1 + level) / 2])
    return {"diff": float(observed), "lo": float(lo), "hi": float(hi), "p_le0": float(np.mean(d <= 0)), "n": int(len(d))}


def verdict(iv: dict[str, float], margin: float = 0.0, higher_is_better: bool = True) -> str:
    """One comparison's reading: ``"better"`` when the interval lies above ``margin`` (below ``−margin`` for
    ``higher_is_better=False``, i.e. reversed), ``"worse"`` when it lies on the other side of zero, else
    ``"not resolved"``.

    >>> verdict({"lo": 0.01, "hi": 0.03}), verdict({"lo": -0.03, "hi": -0.01}), verdict({"lo": -0.01, "hi": 0.02})
    ('better', 'worse', 'not resolved')
    """
    lo, hi = (iv["lo"], iv["hi"]) if higher_is_better else (-iv["hi"], -iv["lo"])
    if not (np.isfinite(lo) and np.isfinite(hi)):
        return "not resolved"
    if lo > margin:
        return "better"
    if hi < 0:
        return "worse"
    return "not resolved"


def seed_draws(seeds: int, n: int, rng: np.random.Generator) -> np.ndarray:
    """``(n, seeds)`` seed indices drawn with replacement, one row per resample — shared by every condition when
    their seeds are paired (e.g. pipelines that use the same seed's detector)."""
    return rng.integers(0, seeds, (n, seeds))


def apply_draws(values: np.ndarray, draws: np.ndarray) -> np.ndarray:
    """Per resample, the mean over the drawn seeds of ``values`` (S, R) → (R,)."""
    v = np.asarray(values, np.float64)
    return nanmean(v[draws, np.arange(v.shape[1])[:, None]], axis=1)

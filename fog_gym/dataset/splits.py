"""Train/val/test splits (D6): 70/15/15 over scenes, day/night 50/50 in every split, per-town shares kept.

Scenes are paired (one day, one night of the same town) and whole pairs are assigned, so day/night is exactly
50/50 in every split whenever every town has as many day as night scenes (``fog-gym generate`` makes sure of
that). Pair counts per split follow the fractions by largest remainder, globally and then per town, so each
town's share of a split stays close to its share of the dataset (within ±2 points once a split holds a few
dozen scenes; :func:`check_splits` reports the actual figures).

Example:
    >>> names = [f"T{t}_{d}_scene{i:03d}" for t in (1, 2) for d in ("day", "night") for i in range(1, 11)]
    >>> s = make_splits(names)
    >>> [len(s[k]) for k in ("train", "val", "test")]
    [28, 6, 6]
"""

from __future__ import annotations

import re
from collections import Counter, defaultdict

import numpy as np

from fog_gym.dataset.layout import SPLITS

FRACTIONS = (0.70, 0.15, 0.15)
_NAME = re.compile(r"^T(\d+)_(day|night)_scene(\d+)$")


def _parse(name: str) -> tuple[int, str, int]:
    m = _NAME.match(name)
    if m is None:
        raise ValueError(f"not a FogDrive scene name (T<town>_<day|night>_scene<NNN>): {name!r}")
    return int(m.group(1)), m.group(2), int(m.group(3))


def _largest_remainder(total: int, weights: np.ndarray) -> np.ndarray:
    quota = total * weights / weights.sum()
    out = np.floor(quota).astype(int)
    for k in np.argsort(-(quota - out), kind="stable")[: total - out.sum()]:
        out[k] += 1
    return out


def make_splits(scene_names: list[str], fractions: tuple[float, float, float] = FRACTIONS, seed: int = 0) -> dict[str, list[str]]:
    """Assign scenes to train/val/test as described above (deterministic for a seed)."""
    if len(fractions) != 3 or min(fractions) < 0 or not np.isclose(sum(fractions), 1.0):
        raise ValueError(f"fractions must be three non-negative numbers summing to 1, got {fractions!r}")
    by_town: dict[int, dict[str, list[str]]] = defaultdict(lambda: {"day": [], "night": []})
    for name in sorted(set(scene_names)):
        town, tod, _ = _parse(name)
        by_town[town][tod].append(name)
    rng = np.random.default_rng(seed)
    pairs: dict[int, list[tuple[str, ...]]] = {}
    leftovers: list[str] = []
    for town, d in sorted(by_town.items()):
        day, night = list(d["day"]), list(d["night"])
        rng.shuffle(day)
        rng.shuffle(night)
        n = min(len(day), len(night))
        pairs[town] = list(zip(day[:n], night[:n]))
        leftovers += day[n:] + night[n:]
    f = np.asarray(fractions, np.float64)
    towns = sorted(pairs)
    target = _largest_remainder(sum(len(pairs[t]) for t in towns), f)  # pairs per split
    counts = {t: np.floor(len(pairs[t]) * f).astype(int) for t in towns}
    # hand out the remaining pairs: the town/split with the largest unmet quota first, within the split targets
    while True:
        missing = target - sum(counts[t] for t in towns)
        best, best_gap = None, -np.inf
        for t in towns:
            if counts[t].sum() >= len(pairs[t]):
                continue
            for s in np.flatnonzero(missing > 0):
                gap = len(pairs[t]) * f[s] - counts[t][s]
                if gap > best_gap:
                    best, best_gap = (t, s), gap
        if best is None:
            break
        counts[best[0]][best[1]] += 1
    out: dict[str, list[str]] = {s: [] for s in SPLITS}
    for t in towns:
        k = 0
        for s, n in zip(SPLITS, counts[t]):
            for pair in pairs[t][k : k + n]:
                out[s] += list(pair)
            k += n
    out["train"] += leftovers  # unpaired scenes cannot keep 50/50 anywhere; train absorbs them (reported)
    return {s: sorted(v) for s, v in out.items()}


def check_splits(splits: dict[str, list[str]], index_scene_names: list[str]) -> dict[str, object]:
    """The three coverage checks (lists; empty when all is well) and the balance figures."""
    assigned = [n for s in SPLITS for n in splits.get(s, [])]
    counts = Counter(assigned)
    index = set(index_scene_names)
    report: dict[str, object] = {
        "duplicate_assignments": sorted(n for n, c in counts.items() if c > 1),
        "scenes_in_no_split": sorted(index - set(assigned)),
        "scenes_in_split_but_not_in_index": sorted(set(assigned) - index),
    }
    total = max(len(index), 1)
    overall = Counter(_parse(n)[0] for n in index)
    fractions, day_share, town_dev = {}, {}, {}
    for s in SPLITS:
        names = splits.get(s, [])
        fractions[s] = len(names) / total
        day_share[s] = sum(_parse(n)[1] == "day" for n in names) / max(len(names), 1)
        per_town = Counter(_parse(n)[0] for n in names)
        town_dev[s] = max((abs(per_town[t] / max(len(names), 1) - overall[t] / total) * 100 for t in overall), default=0.0)
    report.update(fractions=fractions, day_share=day_share, max_town_share_deviation_points=town_dev)
    return report

"""Experiment 1's subsets (FogDrive paper §5), as lists of (scene name, fog level). Pure.

From a seeded permutation S of the training scenes (n of them), with fog levels read from the paired channels:

* **Light**: S[0 : 20 %] at light fog; **Dense**: the same scenes at dense fog; **Clear** (an extra row): the same
  scenes without fog.
* **Mixed-S**: S[0 : 8 %] at light, S[8 : 16 %] at moderate, S[16 : 24 %] at dense (≈ 24 % in all: matched on
  total scene budget with Light and Dense).
* **Mixed-L**: S[0 : 20 %] at light, moderate *and* dense (60 %: matched on per-density budget with Light and
  Dense; it contains both).

Test subsets: 20 % of the test scenes (at least one), each at light, moderate and dense (and clear as an extra).
Counts round to the nearest scene with at least one.

Example:
    >>> subsets = training_subsets([f"s{i:02d}" for i in range(50)], seed=0)
    >>> {k: len(v) for k, v in subsets.items()}
    {'Light': 10, 'Dense': 10, 'Mixed-S': 12, 'Mixed-L': 30, 'Clear': 10}
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

TRAIN_ROWS = ("Light", "Dense", "Mixed-S", "Mixed-L", "Clear")
TEST_COLUMNS = ("light", "moderate", "dense", "clear")
LEVEL_CHANNEL = {"clear": "LIDAR_TOP", "light": "LIDAR_TOP_FOG_LIGHT", "moderate": "LIDAR_TOP_FOG_MODERATE",
                 "dense": "LIDAR_TOP_FOG_DENSE"}  # fmt: skip


def _count(n: int, fraction: float) -> int:
    return max(1, int(round(n * fraction)))


def training_subsets(train_scenes: Sequence[str], seed: int = 0, fraction: float = 0.2,
                     mixed_fraction: float = 0.08) -> dict[str, list[tuple[str, str]]]:  # fmt: skip
    """The five training subsets of (scene name, fog level) pairs (module docstring)."""
    names = sorted(train_scenes)
    if not names:
        raise ValueError("the training split has no scenes")
    if not 0 < mixed_fraction <= fraction <= 1 / 3:
        raise ValueError(f"need 0 < mixed_fraction <= fraction <= 1/3, got {mixed_fraction} and {fraction}")
    s = [names[i] for i in np.random.default_rng(seed).permutation(len(names))]
    k, m = _count(len(s), fraction), _count(len(s), mixed_fraction)
    base = s[:k]
    mixed_s = [(n, "light") for n in s[:m]] + [(n, "moderate") for n in s[m:2 * m]] + [(n, "dense") for n in s[2 * m:3 * m]]
    return {
        "Light": [(n, "light") for n in base],
        "Dense": [(n, "dense") for n in base],
        "Mixed-S": mixed_s,
        "Mixed-L": [(n, lv) for lv in ("light", "moderate", "dense") for n in base],
        "Clear": [(n, "clear") for n in base],
    }


def evaluation_subsets(test_scenes: Sequence[str], seed: int = 0, fraction: float = 0.2) -> dict[str, list[tuple[str, str]]]:
    """Per-density test subsets: the same 20 % of the test scenes at each level."""
    names = sorted(test_scenes)
    if not names:
        raise ValueError("the test split has no scenes")
    s = [names[i] for i in np.random.default_rng(seed + 1).permutation(len(names))][: _count(len(names), fraction)]
    return {lv: [(n, lv) for n in s] for lv in TEST_COLUMNS}

"""Fog schedules for curricula: which visibility an episode gets. Pure Python, no environment.

* :class:`StepSchedule` — clear → 160 → 100 → 50 m, a fixed number of episodes per level;
* :class:`SuccessSchedule` — advance when the success rate (episodes without a crash) over a window reaches a
  threshold;
* :class:`ContinuousSchedule` — visibility sliding from ``start`` to ``end`` metres over ``episodes``, linear in α;
* :class:`MixedSampler` — a level drawn per episode from a seeded generator (the paper's Mixed training).

``level(episode)`` gives the fog of a 0-based episode index; ``record(success)`` tells the schedule how an episode
ended (only :class:`SuccessSchedule` uses it).

Example:
    >>> s = StepSchedule(episodes_per_level=2)
    >>> [s.level(e) for e in range(9)]
    ['clear', 'clear', 160.0, 160.0, 100.0, 100.0, 50.0, 50.0, 50.0]
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence

import numpy as np

from fog_gym.fog.physics import LN20, parse_fog

DEFAULT_LEVELS: tuple = ("clear", 160.0, 100.0, 50.0)


def _check_levels(levels: Sequence) -> tuple:
    if not levels:
        raise ValueError("levels must name at least one fog level")
    for lv in levels:
        parse_fog(lv)  # raises a clear error for a bad level
    return tuple(levels)


class FogSchedule:
    """Base class: ``level(episode)`` and ``record(success)``."""

    def level(self, episode: int):  # pragma: no cover - interface
        raise NotImplementedError

    def record(self, success: bool) -> None:
        pass


class StepSchedule(FogSchedule):
    """``episodes_per_level`` episodes at each of ``levels`` in turn, then the last level for ever."""

    def __init__(self, levels: Sequence = DEFAULT_LEVELS, episodes_per_level: int = 20) -> None:
        if isinstance(episodes_per_level, bool) or not isinstance(episodes_per_level, int) or episodes_per_level < 1:
            raise ValueError(f"episodes_per_level must be an integer >= 1, got {episodes_per_level!r}")
        self.levels, self.episodes_per_level = _check_levels(levels), episodes_per_level

    def level(self, episode: int):
        return self.levels[min(episode // self.episodes_per_level, len(self.levels) - 1)]


class SuccessSchedule(FogSchedule):
    """Advance to the next level once ≥ ``threshold`` of the last ``window`` episodes succeeded.

    >>> s = SuccessSchedule(levels=("clear", 50), threshold=1.0, window=2)
    >>> s.record(True); s.level(1)
    'clear'
    >>> s.record(True); s.level(2)
    50
    """

    def __init__(self, levels: Sequence = DEFAULT_LEVELS, threshold: float = 0.8, window: int = 10) -> None:
        if not 0.0 < float(threshold) <= 1.0:
            raise ValueError(f"threshold must lie in (0, 1], got {threshold!r}")
        if isinstance(window, bool) or not isinstance(window, int) or window < 1:
            raise ValueError(f"window must be an integer >= 1, got {window!r}")
        self.levels, self.threshold, self.window = _check_levels(levels), float(threshold), window
        self.stage = 0
        self._recent: deque[bool] = deque(maxlen=window)

    def record(self, success: bool) -> None:
        self._recent.append(bool(success))
        if len(self._recent) == self.window and np.mean(self._recent) >= self.threshold and self.stage < len(self.levels) - 1:
            self.stage += 1
            self._recent.clear()

    def level(self, episode: int):
        return self.levels[self.stage]


class ContinuousSchedule(FogSchedule):
    """Visibility from ``start`` to ``end`` metres over ``episodes`` episodes, linear in extinction α = ln 20 / V."""

    def __init__(self, start: float = math.inf, end: float = 50.0, episodes: int = 100) -> None:
        a0, a1 = parse_fog(start).alpha, parse_fog(end).alpha
        if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
            raise ValueError(f"episodes must be an integer >= 1, got {episodes!r}")
        self.alphas, self.episodes = (a0, a1), episodes

    def level(self, episode: int):
        f = min(episode / self.episodes, 1.0)
        alpha = self.alphas[0] + f * (self.alphas[1] - self.alphas[0])
        return math.inf if alpha == 0 else LN20 / alpha


class MixedSampler(FogSchedule):
    """A level drawn uniformly per episode; the draw for episode ``e`` depends only on (seed, e).

    >>> m = MixedSampler(seed=0)
    >>> m.level(3) == MixedSampler(seed=0).level(3)
    True
    """

    def __init__(self, levels: Sequence = DEFAULT_LEVELS, seed: int = 0) -> None:
        self.levels, self.seed = _check_levels(levels), int(seed)

    def level(self, episode: int):
        rng = np.random.default_rng(np.random.SeedSequence([self.seed, int(episode)]))
        return self.levels[int(rng.integers(len(self.levels)))]

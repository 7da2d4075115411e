"""Fog banks drawn per episode (:class:`BankConfig`): the ``FogDriveRLFogBank-v0`` preset's fog, a wall of fog on the
road ahead that the agent reaches at speed.

A bank lies across the road in the field frame of the episode (:mod:`fog_gym.fog.fields`: ``u`` along the ego's
heading from the LiDAR at reset), its near face ``start`` metres ahead, ``length`` metres deep, with edges ``edge``
metres wide, in clear air; its visibility is the meteorological visibility inside it.

Example:
    >>> bank = BankConfig().draw(np.random.default_rng(0))
    >>> type(bank).__name__, 140.0 <= bank.start <= 340.0, 25.0 <= bank.visibility <= 80.0
    ('FogBank', True, True)
    >>> BankConfig(visibility=(0.0, 50.0))
    Traceback (most recent call last):
    ...
    ValueError: visibility must be (min, max) metres with 0 < min <= max, got (0.0, 50.0)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fog_gym.checks import finite
from fog_gym.fog.fields import FogBank


#: The banks' stream in a reset's seed sequence (so they share no draws with the traffic or the fog noise).
BANK_STREAM = 0xBA4C


def bank_rng(seed: int | None) -> np.random.Generator:
    """The generator of the banks from ``reset(seed=seed)`` on (fresh entropy for None): the pixel path
    (``FogBankEpisodes``) and the perceived objects draw the same bank for the same seed."""
    return np.random.default_rng(np.random.SeedSequence(None if seed is None else [int(seed), BANK_STREAM]))


@dataclass(frozen=True)
class BankConfig:
    """The ranges (min, max) each episode's bank is drawn from, uniformly: ``start`` [m] of its near face ahead of
    the LiDAR at reset (by default beyond every sensor's clear-air reach: the FogDrive LiDAR's 120 m, and 20 m
    more), ``length`` [m], ``visibility`` [m] inside it and ``edge`` [m] (the width of its faces' ramps).

    >>> BankConfig().start, BankConfig().length
    ((140.0, 340.0), (100.0, 400.0))
    """

    start: tuple[float, float] = (140.0, 340.0)
    length: tuple[float, float] = (100.0, 400.0)
    visibility: tuple[float, float] = (25.0, 80.0)
    edge: tuple[float, float] = (5.0, 30.0)

    def __post_init__(self) -> None:
        for name, strict in (("start", False), ("length", False), ("visibility", True), ("edge", False)):
            v = getattr(self, name)
            ok = isinstance(v, (tuple, list)) and len(v) == 2
            if ok:
                lo, hi = (finite(name, x) for x in v)
                ok = (lo > 0 if strict else lo >= 0) and lo <= hi
            if not ok:
                bound = "0 < min" if strict else "0 <= min"
                raise ValueError(f"{name} must be (min, max) metres with {bound} <= max, got {v!r}")
            object.__setattr__(self, name, (float(v[0]), float(v[1])))

    def draw(self, rng: np.random.Generator) -> FogBank:
        """One bank, its start, length, visibility and edge drawn in that order from ``rng``."""
        start, length, visibility, edge = (rng.uniform(*getattr(self, k)) for k in ("start", "length", "visibility",
                                                                                  "edge"))  # fmt: skip
        return FogBank(visibility, start, length, edge=edge, name="bank")

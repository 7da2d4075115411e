"""Argument checks shared by every config: each raises a ValueError that names the argument and what it allows,
so bad input fails at construction before any work starts.

Example:
    >>> finite("speed", "2.5")
    2.5
    >>> interval("dropoff", 1.5, 0.0, 1.0)
    Traceback (most recent call last):
    ...
    ValueError: dropoff must lie in [0, 1], got 1.5
"""

from __future__ import annotations

import math
from typing import Any


def finite(name: str, value: Any) -> float:
    """``value`` as a finite float, or a ValueError naming ``name`` (booleans are not numbers here)."""
    if isinstance(value, bool):
        raise ValueError(f"{name} must be a finite number, got {value!r}")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a finite number, got {value!r}") from None
    if not math.isfinite(v):
        raise ValueError(f"{name} must be a finite number, got {value!r}")
    return v


def positive(name: str, value: Any) -> float:
    """A finite number > 0."""
    v = finite(name, value)
    if v <= 0.0:
        raise ValueError(f"{name} must be > 0, got {value!r}")
    return v


def interval(name: str, value: Any, lo: float, hi: float, open_lo: bool = False) -> float:
    """A finite number in ``[lo, hi]`` (``(lo, hi]`` with ``open_lo``)."""
    v = finite(name, value)
    if v > hi or v < lo or (open_lo and v == lo):
        bounds = f"({lo:g}, {hi:g}]" if open_lo else f"[{lo:g}, {hi:g}]"
        raise ValueError(f"{name} must lie in {bounds}, got {value!r}")
    return v


def parse_resolution(resolution: Any) -> tuple[int, int]:
    """Validate a ``(width, height)`` pair of positive integers.

    >>> parse_resolution((64, 48))
    (64, 48)
    """
    try:
        w, h = resolution
    except (TypeError, ValueError):
        raise ValueError(f"resolution must be a (width, height) pair of positive integers, got {resolution!r}") from None
    for v in (w, h):
        if isinstance(v, bool) or not isinstance(v, int) or v <= 0:
            raise ValueError(f"resolution must be a (width, height) pair of positive integers, got {resolution!r}")
    return int(w), int(h)

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

import contextlib
import contextvars
import math
from typing import Any

_COMMAND_LINE = contextvars.ContextVar("fog_gym_command_line", default=False)


@contextlib.contextmanager
def command_line():
    """Within this block (the ``fog-gym`` command's handlers), :func:`option` names command-line flags."""
    token = _COMMAND_LINE.set(True)
    try:
        yield
    finally:
        _COMMAND_LINE.reset(token)


def option(keyword: str, python: str = "True", shell: str | None = None) -> str:
    """An option as the reader of an error message passes it: ``keyword=python`` from Python, ``--keyword shell``
    (``--keyword`` for a switch) on the command line (inside :func:`command_line`).

    >>> option("save", "'FILE.rrd'", "FILE.rrd")
    "save='FILE.rrd'"
    >>> with command_line():
    ...     option("save", "'FILE.rrd'", "FILE.rrd"), option("overwrite")
    ('--save FILE.rrd', '--overwrite')
    """
    if _COMMAND_LINE.get():
        flag = "--" + keyword.replace("_", "-")
        return flag if shell is None else f"{flag} {shell}"
    return f"{keyword}={python}"


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


def json_numbers(name: str, value: Any, limit: int = 10_000_000) -> Any:
    """Parsed JSON that must be a number or nested lists of numbers (no booleans, strings, nulls or objects) as a
    float64 numpy array; a ValueError naming ``name`` otherwise (also for ragged lists). Never recurses, so
    arbitrarily deep input cannot exhaust the stack.

    >>> json_numbers("k", [[1, 2], [3, 4.5]]).tolist()
    [[1.0, 2.0], [3.0, 4.5]]
    >>> json_numbers("k", [1, True])
    Traceback (most recent call last):
    ...
    ValueError: k must be numbers
    """
    import numpy as np

    stack, seen = [value], 0
    while stack:
        v = stack.pop()
        seen += 1
        if isinstance(v, list):
            stack.extend(v)
        elif isinstance(v, bool) or not isinstance(v, (int, float)) or seen > limit:
            raise ValueError(f"{name} must be numbers")
    try:
        return np.asarray(value, np.float64)
    except (ValueError, OverflowError):
        raise ValueError(f"{name} must be a regular array of numbers") from None


def json_record(data: bytes, keys: tuple[str, ...]) -> tuple[dict | None, str | None]:
    """A small JSON file's bytes as ``(object, None)`` holding every key of ``keys``, or ``(None, problem)`` with one
    phrase (empty, corrupt, not an object, missing keys). Never raises.

    >>> json_record(b'{"a": 1}', ("a", "b"))
    (None, "missing keys ['b']")
    """
    import json

    try:
        record = json.loads(data)
    except (ValueError, RecursionError) as e:  # not UTF-8, not JSON, nested too deeply, an over-long number
        return None, f"corrupt JSON ({type(e).__name__})" if data else "empty file"
    if not isinstance(record, dict):
        return None, "expected a JSON object"
    missing = [k for k in keys if k not in record]
    if missing:
        return None, f"missing keys {missing}"
    return record, None

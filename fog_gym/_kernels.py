"""A one-line notice when fog-gym's numba kernels must be compiled (cold cache: first run, or after an upgrade).

Compilation takes about a minute on a laptop CPU and happens once: the kernels are cached next to their modules.

Example:
    >>> isinstance(cold_kernels(), list)
    True
"""

from __future__ import annotations

import sys

_announced = False


def cold_kernels() -> list[str]:
    """Names of the main numba kernels whose on-disk cache is missing or stale (empty when all are cached)."""
    from fog_gym import fog, labels, lidar
    from fog_gym.render import raster, raycast

    kernels = [raster._raster_bands, raycast._cast, fog._koschmieder, fog._hahner, labels._project_boxes,
               lidar._lidar_points]  # fmt: skip
    cold = []
    for k in kernels:
        try:
            if not k._cache._cache_file._load_index():  # numba's index of cached overloads (empty if stale)
                cold.append(k.__name__)
        except Exception:  # noqa: BLE001 - a numba without these internals: say nothing rather than guess
            continue
    return cold


def announce_compilation() -> None:
    """Print the notice to stderr once per process if some kernel must be compiled."""
    global _announced
    if _announced:
        return
    _announced = True
    if cold_kernels():
        print("fog-gym: compiling kernels (first run only, about a minute)…", file=sys.stderr, flush=True)

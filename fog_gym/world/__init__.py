"""The world: towns (highway-env scenarios), the traffic that drives them, stalled-vehicle hazards, the static scenery
around the road, and the :class:`~fog_gym.world.scene.Scene` every sensor sees.

:mod:`~fog_gym.world.towns` (the six towns, their highway-env configs and IDM profiles),
:mod:`~fog_gym.world.traffic_world` (:class:`TrafficWorld`: FogDrive classes, sizes and stable ids on highway-env
vehicles), :mod:`~fog_gym.world.traffic` (the traffic core that steps highway-env's traffic exactly, faster),
:mod:`~fog_gym.world.hazards` (:class:`HazardConfig`), :mod:`~fog_gym.world.scenery` (road surface and props),
:mod:`~fog_gym.world.primitives` (the typed boxes every sensor sees) and :mod:`~fog_gym.world.scene` (one instant:
vehicles, static world, lighting, primitives). Names load on first use (``import fog_gym.world`` imports nothing
of highway-env).

Example:
    >>> from fog_gym.world import TOWNS
    >>> TOWNS[:2]
    ('highway', 'merge')
"""

from __future__ import annotations

import importlib
from typing import Any

_LAZY = {
    "TOWNS": "towns", "TOWN_SPECS": "towns", "TIMES_OF_DAY": "towns", "TownSpec": "towns",
    "HazardConfig": "hazards", "EGO_ID": "fleet", "TrafficWorld": "traffic_world",
    "VehicleState": "fleet", "Scene": "scene", "StaticWorld": "scene", "Lighting": "scene",
    "Primitives": "primitives", "accelerate": "traffic",
}  # fmt: skip
__all__ = sorted(_LAZY)


def __getattr__(name: str) -> Any:
    if name not in _LAZY:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))

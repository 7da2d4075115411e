"""Gymnasium wrappers for FogDrive-v0, importable as ``fog_gym.wrappers`` (one wrapper per module).

As in ``gymnasium.wrappers``, a wrapper's module is imported when the wrapper is first asked for, so
``import fog_gym.wrappers`` costs nothing and loads neither the env nor the dataset writer.

Example:
    >>> from fog_gym.wrappers import FogWrapper
    >>> FogWrapper.__name__
    'FogWrapper'
"""

from __future__ import annotations

import importlib
from typing import Any

#: Public name → the module of this package that defines it.
_LAZY = {
    "FogBankEpisodes": "fog_bank_episodes",
    "FogCurriculum": "curriculum",
    "FogWrapper": "fog",
    "parse_fog_levels": "fog",
    "LidarBEV": "lidar_bev",
    "ResizeCameras": "resize_cameras",
    "SelectKeys": "select_keys",
    "StackFrames": "stack_frames",
    "RecordFogDrive": "record",
    "VectorFogCurriculum": "vector_curriculum",
}

__all__ = sorted(_LAZY)


def __getattr__(name: str) -> Any:
    if name not in _LAZY:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))

"""Gymnasium wrappers for FogDrive-v0, importable as ``fog_gym.wrappers`` (one wrapper per module).

Example:
    >>> from fog_gym.wrappers import FogWrapper
    >>> FogWrapper.__name__
    'FogWrapper'
"""

from fog_gym.wrappers.fog import FogWrapper, parse_fog_levels
from fog_gym.wrappers.record import RecordFogDrive

__all__ = ["FogWrapper", "RecordFogDrive", "parse_fog_levels"]

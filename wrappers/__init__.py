"""Gymnasium wrappers for FogDrive-v0, importable as ``fog_gym.wrappers`` (one wrapper per module).

Example:
    >>> from fog_gym.wrappers import FogWrapper
    >>> FogWrapper.__name__
    'FogWrapper'
"""

from fog_gym.wrappers.curriculum import FogCurriculum
from fog_gym.wrappers.fog import FogWrapper, parse_fog_levels
from fog_gym.wrappers.observation import LidarBEV, ResizeCameras, SelectKeys, StackFrames
from fog_gym.wrappers.record import RecordFogDrive

__all__ = ["FogCurriculum", "FogWrapper", "LidarBEV", "RecordFogDrive", "ResizeCameras", "SelectKeys", "StackFrames",
           "parse_fog_levels"]

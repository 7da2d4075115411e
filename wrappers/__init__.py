"""Gymnasium wrappers for FogDrive-v0, importable as ``fog_gym.wrappers`` (one wrapper per module).

The fog, recording, curriculum and observation-shaping wrappers live here.

Example:
    >>> import fog_gym.wrappers
    >>> fog_gym.wrappers.__name__
    'fog_gym.wrappers'
"""

__all__: list[str] = []

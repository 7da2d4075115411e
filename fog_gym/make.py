"""``gym.make("FogDrive-v0", fog=...)``: the env, wrapped in the fog wrapper when fog is asked for.

Composition sits above both :mod:`fog_gym.env` and :mod:`fog_gym.wrappers`, so neither imports the other.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym

from fog_gym.env import FogDriveEnv


def make_fogdrive(fog: Any = None, airlight: Any = "estimate", **kwargs: Any) -> gym.Env:
    """Entry point of ``FogDrive-v0``: :class:`FogDriveEnv`, wrapped in :class:`fog_gym.wrappers.FogWrapper` when
    ``fog`` is given ("clear", "light", "moderate", "dense", metres, or a list for paired mode).

    >>> env = make_fogdrive(fog="light", town="merge", resolution=(16, 12), cameras=["CAM_FRONT"])
    >>> type(env).__name__, env.unwrapped.config.town
    ('FogWrapper', 'merge')
    """
    if fog is None:
        return FogDriveEnv(**kwargs)
    from fog_gym.wrappers.fog import FogWrapper, parse_fog_levels  # lazily: the wrappers package loads on demand

    parse_fog_levels(fog)  # bad fog fails before the world is built
    return FogWrapper(FogDriveEnv(**kwargs), fog, airlight=airlight)

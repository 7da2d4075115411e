"""Named random streams: every random draw of an episode derives from its seed and one of these names.

A stream is ``numpy.random.default_rng(SeedSequence([seed, salt, *keys]))``. The salts are the values the
project has always used, so datasets recorded before they had names stay reproducible; ``WORLD`` and ``FOG``
share a salt for that reason (they draw from different seeds: the world from the seed given to
``TrafficWorld.reset``, the fog from the episode seed with the fog level as a further key; see docs/design.md).

Example:
    >>> a, b = stream(7, "scenery").random(), stream(7, "scenery").random()
    >>> a == b and a != stream(7, "sensors").random()
    True
"""

from __future__ import annotations

import numpy as np

SALTS: dict[str, int] = {
    "world": 0xF06,  # vehicle classes, sizes and colours (fog_gym.world.traffic_world)
    "scenery": 0x5CE,  # static props and lighting of an episode (fog_gym.envs.fogdrive)
    "sensors": 0x11DA,  # sensor noise (fog_gym.envs.fogdrive)
    "fog": 0xF06,  # LiDAR fog noise per level (fog_gym.wrappers.fog)
    "hazards": 0x4A2,  # stalled vehicles: distances and lanes (fog_gym.world.traffic_world, HazardConfig)
    "camera_noise": 0xCA3,  # camera sensor noise: one seed per episode, keys per frame (fog_gym.sensors.camera_effects)
}


def stream(seed: int | None, name: str, *keys: int) -> np.random.Generator:
    """The random generator of stream ``name`` for ``seed`` (``None`` counts as 0) and optional integer keys."""
    if name not in SALTS:
        raise ValueError(f"unknown random stream {name!r}; known: {sorted(SALTS)}")
    return np.random.default_rng(np.random.SeedSequence([0 if seed is None else int(seed), SALTS[name], *keys]))

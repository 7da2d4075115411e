"""Fog as one number: visibility ``V`` (meteorological optical range, 5 % contrast) ↔ extinction ``α = ln 20 / V``.

Presets (FogDrive): light 160 m, moderate 100 m, dense 50 m; "clear" is ``V = ∞``, ``α = 0``. The same α drives
the camera (:mod:`fog_gym.fog.camera`) and the LiDAR (:mod:`fog_gym.fog.lidar`). Research note ``fog_physics.md`` §0.

Example:
    >>> level = parse_fog("dense")
    >>> level.visibility_m, round(level.alpha, 6)
    (50.0, 0.059915)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

LN20 = math.log(20.0)
#: FogDrive's fog levels: visibility in metres.
FOG_PRESETS: dict[str, float] = {"light": 160.0, "moderate": 100.0, "dense": 50.0}


@dataclass(frozen=True)
class FogLevel:
    """One fog condition: a name ("clear", "light", …, or e.g. "75m"), visibility [m] and extinction α [1/m].

    >>> FogLevel.from_visibility(100.0).name, FogLevel.from_visibility(75.0).channel_suffix
    ('moderate', 'FOG_75M')
    """

    name: str
    visibility_m: float
    alpha: float

    @classmethod
    def from_visibility(cls, visibility_m: float) -> FogLevel:
        v = float(visibility_m)
        if math.isinf(v):
            return cls("clear", math.inf, 0.0)
        name = next((k for k, pv in FOG_PRESETS.items() if pv == v), f"{v:g}m")
        return cls(name, v, LN20 / v)

    @property
    def is_clear(self) -> bool:
        return self.alpha == 0.0

    @property
    def channel_suffix(self) -> str:
        """``FOG_LIGHT`` etc. as in FogDrive's channel names; ``FOG_<V>M`` for other visibilities."""
        return "FOG_" + self.name.upper().replace(".", "P")

    def info(self) -> dict[str, float]:
        return {"visibility_m": self.visibility_m, "alpha": self.alpha}


def alpha_from_visibility(visibility_m: float) -> float:
    """α = ln 20 / V (5 % contrast threshold); 0 for V = ∞.

    >>> [round(alpha_from_visibility(v), 6) for v in (50, 100, 160)]
    [0.059915, 0.029957, 0.018723]
    """
    return parse_fog(visibility_m).alpha


def parse_fog(fog: str | float | int | FogLevel) -> FogLevel:
    """A level name ("clear", "light", "moderate", "dense") or a visibility in metres (> 0, may be inf)."""
    if isinstance(fog, FogLevel):
        return fog
    if isinstance(fog, str):
        key = fog.strip().lower()
        if key == "clear":
            return FogLevel("clear", math.inf, 0.0)
        if key in FOG_PRESETS:
            return FogLevel(key, FOG_PRESETS[key], LN20 / FOG_PRESETS[key])
        raise ValueError(
            f"fog must be one of ('clear', 'light', 'moderate', 'dense') or a visibility in metres > 0, got {fog!r}"
        )
    if isinstance(fog, bool) or not isinstance(fog, (int, float, np.integer, np.floating)):
        raise ValueError(f"fog must be a level name or a visibility in metres > 0, got {fog!r}")
    v = float(fog)
    if math.isnan(v) or v <= 0.0:
        raise ValueError(f"fog visibility must be a number of metres > 0 (or inf for clear), got {fog!r}")
    return FogLevel.from_visibility(v)

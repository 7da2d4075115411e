"""The bottom of the configuration layer: the finite-number check every config uses, and sensor poses.

It imports nothing from the project, so ``config`` (the rig and the env) and the sensor models' own configs
(``labels``, ``lidar``) can all build on it without import cycles (docs/design.md).

Example:
    >>> finite("speed", "2.5")
    2.5
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any


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


@dataclass(frozen=True)
class Pose:
    """A sensor pose relative to the ego origin (ground under the vehicle centre), CARLA convention.

    Location in metres (+x forward, +y right, +z up), rotation in degrees (pitch, roll, yaw).

    >>> Pose(1.8, 0.0, 1.2).location
    (1.8, 0.0, 1.2)
    """

    x: float = 0.0
    y: float = 0.0
    z: float = 0.0
    pitch: float = 0.0
    roll: float = 0.0
    yaw: float = 0.0

    def __post_init__(self) -> None:
        for name in ("x", "y", "z", "pitch", "roll", "yaw"):
            object.__setattr__(self, name, finite(f"pose.{name}", getattr(self, name)))

    @property
    def location(self) -> tuple[float, float, float]:
        return (self.x, self.y, self.z)

    @property
    def rotation(self) -> tuple[float, float, float]:
        return (self.pitch, self.roll, self.yaw)

    @classmethod
    def coerce(cls, value: Pose | Sequence[float] | Mapping[str, float]) -> Pose:
        """Accept a Pose, a mapping of its fields, or a 3- or 6-sequence (x, y, z[, pitch, roll, yaw])."""
        if isinstance(value, Pose):
            return value
        if isinstance(value, Mapping):
            return cls(**value)
        values = list(value)
        if len(values) not in (3, 6):
            raise ValueError(f"pose must have 3 or 6 numbers (x, y, z[, pitch, roll, yaw]), got {value!r}")
        return cls(*values)

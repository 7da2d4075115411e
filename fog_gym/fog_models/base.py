"""The fog-model protocol and the registry that maps a sensor kind to its fog model.

A fog model turns one clean channel into its fogged versions, one per :class:`~fog_gym.fog.FogLevel`; the
physics stays in :mod:`fog_gym.fog`. :class:`~fog_gym.wrappers.FogWrapper` asks :func:`model_for` for the model of
each sensor of the rig (cameras → Koschmieder, LiDAR → Hahner); a kind without a model (semantic LiDAR, radar)
keeps its clean data.

>>> import fog_gym.fog_models
>>> model_for("camera").name, model_for("lidar").name, model_for("radar")
('koschmieder', 'hahner', None)
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import ClassVar, Protocol, runtime_checkable

import numpy as np

from fog_gym.fog import FogLevel


@dataclass(frozen=True)
class FogContext:
    """What a model may need beyond the observation: per-camera intrinsics and atmospheric light, one random
    generator per level name, whether the scene is at night, and the LiDAR fog's noise scale [m]."""

    intrinsics: Mapping[str, np.ndarray] = field(default_factory=dict)
    airlight: Mapping[str, np.ndarray] = field(default_factory=dict)
    rngs: Mapping[str, np.random.Generator] = field(default_factory=dict)
    night: bool = False
    lidar_noise: float = 10.0


@runtime_checkable
class FogModel(Protocol):
    """Fog for one sensor kind."""

    name: ClassVar[str]

    def apply(self, obs: Mapping[str, np.ndarray], channel: str, levels: Sequence[FogLevel],
              context: FogContext) -> dict[str, np.ndarray]:  # fmt: skip
        """``{level name: fogged array of channel}``, shaped as ``obs[channel]``; clean data are never changed."""


#: Sensor kind → fog model instance (see :func:`register_model`).
MODELS: dict[str, FogModel] = {}


def register_model(kind: str):
    """Class decorator: the model fogs every sensor of ``kind`` (``camera``, ``lidar``, …)."""
    if not isinstance(kind, str) or not kind:
        raise ValueError(f"kind must be a sensor kind such as 'camera' or 'lidar', got {kind!r}")

    def deco(cls: type) -> type:
        MODELS[kind] = cls()
        return cls

    return deco


def model_for(kind: str) -> FogModel | None:
    """The fog model of a sensor kind, or None when the kind is not fogged (the built-in models register when
    :mod:`fog_gym.fog_models` is imported)."""
    return MODELS.get(kind)

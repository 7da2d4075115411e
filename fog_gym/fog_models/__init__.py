"""Fog models behind one interface (:mod:`fog_gym.fog_models.base`), one module per model:
:mod:`~fog_gym.fog_models.koschmieder` (cameras) and :mod:`~fog_gym.fog_models.hahner` (LiDAR).

A new model is a module with a class decorated by :func:`register_model` for a sensor kind.
"""

from __future__ import annotations

from fog_gym.fog_models.base import MODELS, FogContext, FogModel, model_for, register_model
from fog_gym.fog_models.hahner import Hahner
from fog_gym.fog_models.koschmieder import Koschmieder

__all__ = ["MODELS", "FogContext", "FogModel", "Hahner", "Koschmieder", "model_for", "register_model"]

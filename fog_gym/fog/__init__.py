"""Fog: the physics (visibility and extinction, Koschmieder for cameras, Hahner et al. for LiDAR), the fog models
that apply it to a rig's sensors, and the schedules that pick an episode's fog for curricula.

:mod:`~fog_gym.fog.physics` (levels), :mod:`~fog_gym.fog.camera` (Koschmieder, night airlight),
:mod:`~fog_gym.fog.glow` (the glow of lit fog at night), :mod:`~fog_gym.fog.lidar` (Hahner),
:mod:`~fog_gym.fog.models` (the fog-model protocol and registry), :mod:`~fog_gym.fog.schedules` (curriculum schedules) and :mod:`~fog_gym.fog.curriculum` (the one curriculum
driver every adapter uses). The physics functions are re-exported here.

Example:
    >>> parse_fog("light").visibility_m, round(lidar_crossover_range(parse_fog("dense")), 1)
    (160.0, 35.6)
"""

from __future__ import annotations

from fog_gym.fog.camera import (atmospheric_light, check_fog_inputs, fog_image, fog_images, night_airlight,
                                ray_length_factor)  # fmt: skip
from fog_gym.fog.glow import add_glow, glow_sigma_px
from fog_gym.fog.lidar import fog_lidar, lidar_crossover_range, soft_response_table
from fog_gym.fog.physics import FOG_PRESETS, LN20, FogLevel, alpha_from_visibility, parse_fog

__all__ = ["FOG_PRESETS", "LN20", "FogLevel", "add_glow", "alpha_from_visibility", "atmospheric_light",
           "check_fog_inputs", "fog_image", "fog_images", "fog_lidar", "glow_sigma_px", "lidar_crossover_range",
           "night_airlight", "parse_fog", "ray_length_factor", "soft_response_table"]  # fmt: skip

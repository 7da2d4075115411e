"""fog-gym: a Gymnasium environment for driving perception under graded, physically calibrated fog.

``import fog_gym`` registers ``FogDrive-v0``.

Example:
    >>> import gymnasium as gym, fog_gym
    >>> "FogDrive-v0" in gym.registry
    True
"""

from __future__ import annotations

from gymnasium.envs.registration import register

from fog_gym._memory import tune_malloc

tune_malloc()

from fog_gym.config import CAMERA_NAMES, TIMES_OF_DAY, TOWNS, CameraConfig, FogDriveConfig, HazardConfig, Pose, RigConfig
from fog_gym.lidar import LidarConfig, RadarConfig, SemanticLidarConfig
from fog_gym.points import unpack_points

from fog_gym._version import __version__

__all__ = [
    "CAMERA_NAMES", "TIMES_OF_DAY", "TOWNS", "CameraConfig", "FogDriveConfig", "HazardConfig", "Pose", "RigConfig", "FogDriveEnv",
    "LidarConfig", "RadarConfig", "SemanticLidarConfig", "unpack_points", "accelerate",
]  # fmt: skip

register(id="FogDrive-v0", entry_point="fog_gym.make:make_fogdrive", max_episode_steps=None, disable_env_checker=False)
register(id="FogDriveRL-v0", entry_point="fog_gym.rl:make_fogdrive_rl", max_episode_steps=None)
register(id="FogDriveRLHazard-v0", entry_point="fog_gym.rl:make_fogdrive_rl_hazard", max_episode_steps=None)


def __getattr__(name: str):
    if name == "FogDriveEnv":
        from fog_gym.env import FogDriveEnv

        return FogDriveEnv
    if name == "accelerate":
        from fog_gym.traffic import accelerate

        return accelerate
    raise AttributeError(name)

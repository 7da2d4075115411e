"""The FogDrive on-disk layout (paper supplementary D2, D6, D8): writing scenes, building the index, reading.

Example:
    >>> from fog_gym.dataset import CHANNELS
    >>> len(CHANNELS)
    35
"""

from fog_gym.dataset.access import FogDrive
from fog_gym.dataset.layout import CHANNELS, channel_path, scene_folder_name
from fog_gym.dataset.writer import SceneWriter, build_index

__all__ = ["CHANNELS", "FogDrive", "SceneWriter", "build_index", "channel_path", "scene_folder_name"]

"""The channel specification (:mod:`~fog_gym.channels.spec`: names, storage, point columns) and the fixed-shape
packing of point clouds in observations (:mod:`~fog_gym.channels.packing`). The bottom of the data path: sensors,
fog, the world, the dataset layer and the exports read it; it reads none of them."""

from fog_gym.channels.packing import channel_kind, pack_points, pad_rows, unpack_points
from fog_gym.channels.spec import (
    BBOX_3D, CAMERA_NAMES, CAMERAS, COLUMNS, FOG_LEVELS, FOGDRIVE_CHANNELS, LIDAR, POINT_COLUMNS, RADAR, SEMANTIC_LIDAR,
    ChannelSpec,
)  # fmt: skip

__all__ = ["BBOX_3D", "CAMERAS", "CAMERA_NAMES", "COLUMNS", "FOGDRIVE_CHANNELS", "FOG_LEVELS", "LIDAR", "POINT_COLUMNS",
           "RADAR", "SEMANTIC_LIDAR", "ChannelSpec", "channel_kind", "pack_points", "pad_rows", "unpack_points"]  # fmt: skip

"""Observation packing of point clouds — now :mod:`fog_gym.channels.packing` (the channel specification sits below
the sensors, the fog and the dataset layer); the names stay importable from here.
"""

from fog_gym.channels.packing import (  # noqa: F401
    COLUMNS, LIDAR, RADAR, SEMANTIC_LIDAR, channel_kind, pack_points, pad_rows, unpack_points,
)

"""The channel specification: every channel's name, where and how it is stored, and the columns of every point
channel — the one definition that sensors, fog, the world, the dataset layer and the exports read. Pure, no I/O,
imports nothing of the project (the data path reads downward: this sits below all of it).

Example:
    >>> FOGDRIVE_CHANNELS["LIDAR_TOP_FOG_DENSE"], POINT_COLUMNS["LIDAR_TOP"]
    (ChannelSpec(folder='lidar_fog_dense', fileformat='npy', encoding='points', columns=4), ('x', 'y', 'z', 'intensity'))
"""

from __future__ import annotations

import re
from typing import NamedTuple

#: FogDrive camera channel names (Table 3), in the order the rig lists them: the one definition.
CAMERA_NAMES: tuple[str, ...] = ("CAM_FRONT", "CAM_BACK", "CAM_LEFT", "CAM_RIGHT")
CAMERAS = CAMERA_NAMES

FOG_LEVELS = ("LIGHT", "MODERATE", "DENSE")
DATA_ROOT = "data_root"
SPLITS = ("train", "val", "test")
TABLES = ("scene", "sample", "sample_data")  # the index tables, index/<table>.json


class ChannelSpec(NamedTuple):
    """Where and how one channel is stored: its folder inside the scene, its file format (``png``, ``npy``,
    ``json``), its encoding (``rgb``, ``depth``, ``semantic``, ``box2d``, ``points``, ``box3d``) and, for a
    point channel, its column count (what the writer encodes, ``validate`` checks and the loader decodes)."""

    folder: str
    fileformat: str
    encoding: str
    columns: int = 0


ENCODINGS = {"rgb": "png", "depth": "png", "semantic": "png", "box2d": "json", "points": "npy", "box3d": "json"}


def _channels() -> dict[str, ChannelSpec]:
    out: dict[str, ChannelSpec] = {}
    for cam in CAMERAS:
        folder = cam.lower()  # cam_front, …
        out[cam] = ChannelSpec(f"{folder}/out_rgb", "png", "rgb")
        for lv in FOG_LEVELS:
            out[f"{cam}_FOG_{lv}"] = ChannelSpec(f"{folder}/out_fog_{lv.lower()}", "png", "rgb")
        out[f"{cam}_DEPTH"] = ChannelSpec(f"{folder}/out_depth", "png", "depth")
        out[f"{cam}_SEM"] = ChannelSpec(f"{folder}/out_seg", "png", "semantic")
        out[f"{cam}_BBOX"] = ChannelSpec(f"{folder}/out_bbox", "json", "box2d")
    out["LIDAR_TOP"] = ChannelSpec("lidar", "npy", "points", 4)
    for lv in FOG_LEVELS:
        out[f"LIDAR_TOP_FOG_{lv}"] = ChannelSpec(f"lidar_fog_{lv.lower()}", "npy", "points", 4)
    out["SEM_LIDAR_TOP"] = ChannelSpec("semantic_lidar", "npy", "points", 6)
    out["RADAR_FRONT"] = ChannelSpec("radar", "npy", "points", 4)
    out["BBOX_3D"] = ChannelSpec("out_3dbbox", "json", "box3d")  # ground truth, not a sensor
    return out


#: The 35 channels of a FogDrive sample → :class:`ChannelSpec` (folder inside the scene, file format, encoding).
FOGDRIVE_CHANNELS: dict[str, ChannelSpec] = _channels()
BBOX_3D = "BBOX_3D"
_NAME_RE = re.compile(r"[A-Z][A-Z0-9_]*")
_FOLDER_RE = re.compile(r"[a-z0-9][a-z0-9_.-]*(/[a-z0-9][a-z0-9_.-]*)*")
#: Folders of a scene that hold no channel: the extrinsics and the ego poses.
RESERVED_FOLDERS = ("extrinsic_config", "ego_pose", "fog_field")


def check_layout(pairs) -> dict[str, ChannelSpec]:
    """A layout given as ``(name, spec)`` pairs (or a mapping), checked: upper-case names, each once; specs with an
    encoding/format pair of :data:`ENCODINGS` and columns only for points; each folder once; a FogDrive channel
    name keeps its FogDrive spec and a FogDrive folder its channel.

    >>> check_layout([("RADAR_BACK", ChannelSpec("radar_back", "npy", "points", 4))])["RADAR_BACK"].folder
    'radar_back'
    >>> check_layout([("LIDAR_TOP", ChannelSpec("lidar2", "npy", "points", 4))])
    Traceback (most recent call last):
    ...
    ValueError: channel 'LIDAR_TOP' is a FogDrive channel stored as ChannelSpec(folder='lidar', fileformat='npy', encoding='points', columns=4), got ChannelSpec(folder='lidar2', fileformat='npy', encoding='points', columns=4)
    """
    items = list(pairs.items()) if isinstance(pairs, dict) else list(pairs)
    out: dict[str, ChannelSpec] = {}
    folders: dict[str, str] = {}
    fogdrive_folders = {s.folder: n for n, s in FOGDRIVE_CHANNELS.items()}
    for name, spec in items:
        if not isinstance(name, str) or not _NAME_RE.fullmatch(name):
            raise ValueError(f"name must be an upper-case channel name like 'RADAR_BACK', got {name!r}")
        if (not isinstance(spec, ChannelSpec) or not all(isinstance(v, str) for v in spec[:3])
                or ENCODINGS.get(spec.encoding) != spec.fileformat):  # fmt: skip
            raise ValueError(f"spec must be a ChannelSpec with an encoding/format pair of {ENCODINGS}, got {spec!r}")
        if not _FOLDER_RE.fullmatch(spec.folder) or spec.folder.split("/")[0] in RESERVED_FOLDERS:
            raise ValueError(f"spec.folder must be a relative folder of lower-case names, not one of {RESERVED_FOLDERS}, "
                             f"got {spec.folder!r}")  # fmt: skip
        if isinstance(spec.columns, bool) or not isinstance(spec.columns, int):
            raise ValueError(f"spec.columns must be an integer, got {spec!r}")
        if (spec.encoding == "points") != (spec.columns > 0):
            raise ValueError(f"spec.columns must be > 0 for a point channel and 0 otherwise, got {spec!r}")
        if name in out:
            raise ValueError(f"channel {name!r} is declared twice")
        if name in FOGDRIVE_CHANNELS and FOGDRIVE_CHANNELS[name] != spec:
            raise ValueError(f"channel {name!r} is a FogDrive channel stored as {FOGDRIVE_CHANNELS[name]!r}, got {spec!r}")
        if spec.folder in folders or fogdrive_folders.get(spec.folder, name) != name:
            other = folders.get(spec.folder) or fogdrive_folders[spec.folder]
            raise ValueError(f"spec.folder {spec.folder!r} of channel {name!r} is already used by {other!r}")
        folders[spec.folder] = name
        out[name] = spec
    return out



LIDAR = "LIDAR_TOP"
SEMANTIC_LIDAR = "SEM_LIDAR_TOP"
RADAR = "RADAR_FRONT"
#: The named columns of each point channel (FogDrive D8 / CARLA raw layouts).
POINT_COLUMNS: dict[str, tuple[str, ...]] = {
    LIDAR: ("x", "y", "z", "intensity"),
    SEMANTIC_LIDAR: ("x", "y", "z", "cos_incidence", "object_id", "tag"),
    RADAR: ("velocity", "azimuth", "altitude", "depth"),
}
#: The LiDAR's return modes and sweep timings (:mod:`fog_gym.fog.returns`, :mod:`fog_gym.sensors.motion`).
LIDAR_RETURNS = ("strongest", "last", "dual")
LIDAR_MOTIONS = ("instant", "continuous")


def lidar_channel(name: str = LIDAR, returns: str = "strongest", motion: str = "instant") -> str:
    """The channel of a LiDAR named ``name``: FogDrive's ``name`` for strongest returns and an instantaneous sweep;
    ``name_LAST`` / ``name_DUAL`` for the other return modes and a ``_MOTION`` suffix for a sweep that takes time
    (their data are not FogDrive's: other echoes, a time column).

    >>> lidar_channel(), lidar_channel(returns="dual"), lidar_channel(returns="last", motion="continuous")
    ('LIDAR_TOP', 'LIDAR_TOP_DUAL', 'LIDAR_TOP_LAST_MOTION')
    """
    if returns not in LIDAR_RETURNS:
        raise ValueError(f"returns must be one of {LIDAR_RETURNS}, got {returns!r}")
    if motion not in LIDAR_MOTIONS:
        raise ValueError(f"motion must be one of {LIDAR_MOTIONS}, got {motion!r}")
    return name + ("" if returns == "strongest" else f"_{returns.upper()}") + ("_MOTION" if motion == "continuous" else "")


def lidar_columns(returns: str = "strongest", motion: str = "instant") -> tuple[str, ...]:
    """The columns of a LiDAR's points: x, y, z, intensity, then ``time`` (seconds from the keyframe, a sweep that
    takes time) and ``return`` (dual: 0 a beam's strongest echo, 1 its last where it differs).

    >>> lidar_columns("dual", "continuous")
    ('x', 'y', 'z', 'intensity', 'time', 'return')
    """
    lidar_channel(LIDAR, returns, motion)  # checks both
    return POINT_COLUMNS[LIDAR] + (("time",) if motion == "continuous" else ()) + (("return",) if returns == "dual" else ())


POINT_COLUMNS.update({lidar_channel(LIDAR, r, m): lidar_columns(r, m) for r in LIDAR_RETURNS for m in LIDAR_MOTIONS})
#: Column counts of the point channels.
COLUMNS: dict[str, int] = {k: len(v) for k, v in POINT_COLUMNS.items()}

"""Channel names, folders and file names of the FogDrive layout (supplementary D2, D8). Pure, no I/O.

A scene lives in ``data_root/data_collection_T<town>_<day|night>_run<i>_<id>/``; each sample's files are named by
the sample's index in the scene (``000000.png``, …), so a timestamp is ``index × 100 000`` µs at 10 Hz.

Example:
    >>> channel_path("CAM_LEFT_FOG_DENSE", "data_collection_T3_night_run2_ab12cd34", 7)
    'data_root/data_collection_T3_night_run2_ab12cd34/cam_left/out_fog_dense/000007.png'
"""

from __future__ import annotations

import hashlib
import re
from typing import NamedTuple

from fog_gym.config import CAMERA_NAMES as CAMERAS  # the FogDrive cameras, one definition (Table 2)
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
    out["BBOX_3D"] = ChannelSpec("out_3dbbox", "json", "box3d")
    return out


#: The 35 channels of a FogDrive sample → :class:`ChannelSpec` (folder inside the scene, file format, encoding).
FOGDRIVE_CHANNELS: dict[str, ChannelSpec] = _channels()
#: Every known channel: the 35 FogDrive channels and those of sensors added with :func:`register_channel`.
CHANNELS: dict[str, ChannelSpec] = dict(FOGDRIVE_CHANNELS)


def register_channel(name: str, spec: ChannelSpec) -> None:
    """Add a sensor's channel to :data:`CHANNELS` (done by :mod:`fog_gym.sensors` for every sensor of a rig).

    Registering the same spec again is a no-op; another spec under a known name or a folder already used raises.

    >>> register_channel("LIDAR_TOP", CHANNELS["LIDAR_TOP"])  # unchanged
    >>> register_channel("LIDAR_TOP", ChannelSpec("lidar2", "npy", "points", 4))
    Traceback (most recent call last):
    ...
    ValueError: channel 'LIDAR_TOP' is already registered as ChannelSpec(folder='lidar', fileformat='npy', encoding='points', columns=4)
    """
    if not isinstance(name, str) or not re.fullmatch(r"[A-Z][A-Z0-9_]*", name):
        raise ValueError(f"name must be an upper-case channel name like 'RADAR_BACK', got {name!r}")
    if not isinstance(spec, ChannelSpec) or ENCODINGS.get(spec.encoding) != spec.fileformat:
        raise ValueError(f"spec must be a ChannelSpec with an encoding/format pair of {ENCODINGS}, got {spec!r}")
    if (spec.encoding == "points") != (spec.columns > 0):
        raise ValueError(f"spec.columns must be > 0 for a point channel and 0 otherwise, got {spec!r}")
    if name in CHANNELS:
        if CHANNELS[name] != spec:
            raise ValueError(f"channel {name!r} is already registered as {CHANNELS[name]!r}")
        return
    if any(s.folder == spec.folder for s in CHANNELS.values()):
        raise ValueError(f"spec.folder {spec.folder!r} is already used by another channel")
    CHANNELS[name] = spec


def unregister_channel(name: str) -> None:
    """Remove a channel added with :func:`register_channel` (the 35 FogDrive channels stay)."""
    if name in FOGDRIVE_CHANNELS:
        raise ValueError(f"name must not be a FogDrive channel, got {name!r}")
    CHANNELS.pop(name, None)


#: Channel sets ``fog-gym generate`` can write: everything, or the LiDAR, its fog variants, the semantic LiDAR and
#: the 3D boxes (no cameras, no radar) — the data of the 3D detection experiment, far faster to generate.
MODALITIES: dict[str, tuple[str, ...]] = {
    "full": tuple(FOGDRIVE_CHANNELS),
    "lidar": ("LIDAR_TOP", *(f"LIDAR_TOP_FOG_{lv}" for lv in FOG_LEVELS), "SEM_LIDAR_TOP", "BBOX_3D"),
}
EXTRINSIC_FILE = "extrinsic_config/extrinsic_config.json"
SAMPLE_PERIOD_US = 100_000  # 10 Hz keyframes
_SCENE_RE = re.compile(r"^data_collection_T(\d+)_(day|night)_run(\d+)_([0-9a-f]+)$")


def scene_id(town_number: int, time_of_day: str, run: int, seed: int) -> str:
    """The 8-hex-digit id of a scene folder, derived from its town, time of day, run and episode seed.

    >>> scene_id(1, "day", 1, 0)
    '1f31afbd'
    """
    return hashlib.sha256(f"{town_number}|{time_of_day}|{run}|{seed}".encode()).hexdigest()[:8]


def scene_folder_name(town_number: int, time_of_day: str, run: int, scene_id: str) -> str:
    """``data_collection_T<town>_<tod>_run<i>_<id>``."""
    return f"data_collection_T{town_number}_{time_of_day}_run{run}_{scene_id}"


def parse_scene_folder(name: str) -> tuple[int, str, int, str] | None:
    """(town number, time of day, run, id) of a scene folder name, or None if it is not one."""
    m = _SCENE_RE.match(name)
    return None if m is None else (int(m.group(1)), m.group(2), int(m.group(3)), m.group(4))


def scene_name(town_number: int, time_of_day: str, run: int) -> str:
    """The human-readable scene name of D6: ``T<town>_<day|night>_scene<NNN>``."""
    return f"T{town_number}_{time_of_day}_scene{run:03d}"


def channel_path(channel: str, scene_folder: str, index: int) -> str:
    """A sample file's path relative to the dataset root (starts with ``data_root/``)."""
    if channel not in CHANNELS:
        raise ValueError(f"channel must be one of the 35 FogDrive channels or a registered one, got {channel!r}")
    folder, ext = CHANNELS[channel][:2]
    return f"{DATA_ROOT}/{scene_folder}/{folder}/{index:06d}.{ext}"

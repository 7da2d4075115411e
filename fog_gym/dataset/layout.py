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

CAMERAS = ("CAM_FRONT", "CAM_BACK", "CAM_LEFT", "CAM_RIGHT")
FOG_LEVELS = ("LIGHT", "MODERATE", "DENSE")
DATA_ROOT = "data_root"
SPLITS = ("train", "val", "test")
TABLES = ("scene", "sample", "sample_data")  # the index tables, index/<table>.json


def _channels() -> dict[str, tuple[str, str]]:
    out: dict[str, tuple[str, str]] = {}
    for cam in CAMERAS:
        folder = cam.lower()  # cam_front, …
        out[cam] = (f"{folder}/out_rgb", "png")
        for lv in FOG_LEVELS:
            out[f"{cam}_FOG_{lv}"] = (f"{folder}/out_fog_{lv.lower()}", "png")
        out[f"{cam}_DEPTH"] = (f"{folder}/out_depth", "png")
        out[f"{cam}_SEM"] = (f"{folder}/out_seg", "png")
        out[f"{cam}_BBOX"] = (f"{folder}/out_bbox", "json")
    out["LIDAR_TOP"] = ("lidar", "npy")
    for lv in FOG_LEVELS:
        out[f"LIDAR_TOP_FOG_{lv}"] = (f"lidar_fog_{lv.lower()}", "npy")
    out["SEM_LIDAR_TOP"] = ("semantic_lidar", "npy")
    out["RADAR_FRONT"] = ("radar", "npy")
    out["BBOX_3D"] = ("out_3dbbox", "json")
    return out


#: The 35 channels of a FogDrive sample → (folder inside the scene, file format).
CHANNELS: dict[str, tuple[str, str]] = _channels()
#: Channel sets ``fog-gym generate`` can write: everything, or the LiDAR, its fog variants, the semantic LiDAR and
#: the 3D boxes (no cameras, no radar) — the data of the 3D detection experiment, far faster to generate.
MODALITIES: dict[str, tuple[str, ...]] = {
    "full": tuple(CHANNELS),
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
        raise ValueError(f"channel must be one of the 35 FogDrive channels, got {channel!r}")
    folder, ext = CHANNELS[channel]
    return f"{DATA_ROOT}/{scene_folder}/{folder}/{index:06d}.{ext}"

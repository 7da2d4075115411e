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
from fog_gym.channels.spec import (  # noqa: F401  (re-exported: the dataset layer's names for them)
    BBOX_3D, CAMERA_NAMES, CAMERAS, DATA_ROOT, ENCODINGS, FOG_LEVELS, FOGDRIVE_CHANNELS, RESERVED_FOLDERS, SPLITS, TABLES,
    ChannelSpec, check_layout,
)

#: The FogDrive channels (the name predates per-dataset layouts). A dataset's own channels, those of the rig that
#: recorded it, are ``FogDrive(root).channels`` (:func:`read_layout`); a rig's are ``fog_gym.sensors.rig_layout``.
CHANNELS: dict[str, ChannelSpec] = FOGDRIVE_CHANNELS
#: A scene's layout when it is not FogDrive's (a rig with added sensors), inside the scene folder, and the
#: dataset's layout (every scene's channels) beside the index tables. Absent: the FogDrive channels.
SCENE_LAYOUT_FILE = "channels.json"
LAYOUT_FILE = "index/channels.json"
def is_fogdrive_layout(layout: dict[str, ChannelSpec]) -> bool:
    """Whether every channel of ``layout`` is a FogDrive channel (then the dataset carries no layout file)."""
    return all(FOGDRIVE_CHANNELS.get(n) == s for n, s in layout.items())


def layout_to_json(layout: dict[str, ChannelSpec]) -> dict:
    """``{"channels": {name: {folder, fileformat, encoding, columns}}}`` in layout order (JSON-ready)."""
    return {"channels": {n: s._asdict() for n, s in layout.items()}}


def layout_from_json(data) -> dict[str, ChannelSpec]:
    """The layout of :func:`layout_to_json`'s output, checked with :func:`check_layout`; ``ValueError`` if bad."""
    chans = data.get("channels") if isinstance(data, dict) else None
    if not isinstance(chans, dict):
        raise ValueError('expected {"channels": {name: {"folder", "fileformat", "encoding", "columns"}}}')
    pairs = []
    for name, spec in chans.items():
        try:
            pairs.append((name, ChannelSpec(**spec)))
        except TypeError:
            raise ValueError(f"channel {name!r}: expected folder, fileformat, encoding, columns, got {spec!r}") from None
    return check_layout(pairs)


def extrinsic_key(camera: str) -> str:
    """The key of a camera's LiDAR→camera matrix in ``extrinsic_config.json``: FogDrive's ``extrinsic_front`` …
    for ``CAM_FRONT`` …, and the same rule for an added camera.

    >>> extrinsic_key("CAM_RIGHT"), extrinsic_key("CAM_FRONT_NARROW")
    ('extrinsic_right', 'extrinsic_front_narrow')
    """
    return "extrinsic_" + camera.lower().removeprefix("cam_")


def modality_channels(modality: str, cameras: tuple[str, ...] = ()) -> tuple[str, ...]:
    """The channels of a :data:`MODALITIES` set, keeping only the named ``cameras``' channels when given.

    >>> modality_channels("cameras", ("CAM_FRONT",))
    ('CAM_FRONT', 'CAM_FRONT_FOG_LIGHT', 'CAM_FRONT_FOG_MODERATE', 'CAM_FRONT_FOG_DENSE', 'CAM_FRONT_DEPTH', 'CAM_FRONT_BBOX', 'BBOX_3D')
    """
    if modality not in MODALITIES:
        raise ValueError(f"modality must be one of {tuple(MODALITIES)}, got {modality!r}")
    bad = [c for c in cameras if c not in CAMERAS]
    if bad:
        raise ValueError(f"cameras must be FogDrive cameras {CAMERAS}, got {bad}")
    if not cameras:
        return MODALITIES[modality]
    dropped = [c for c in CAMERAS if c not in cameras]
    return tuple(ch for ch in MODALITIES[modality] if not any(ch == c or ch.startswith(c + "_") for c in dropped))


def layout_cameras(layout: dict[str, ChannelSpec]) -> list[str]:
    """The cameras of a layout: each camera ``C`` stores its 2D boxes as ``C_BBOX``."""
    return [n.removesuffix("_BBOX") for n, s in layout.items() if s.encoding == "box2d"]


#: Channel sets ``fog-gym generate`` can write: everything; the LiDAR, its fog variants, the semantic LiDAR and
#: the 3D boxes (no cameras, no radar) — the data of the 3D detection experiment, far faster to generate; or the
#: cameras' RGB, its three fog variants, depth and 2D boxes, with the 3D boxes (no LiDAR, no radar, no semantics) —
#: the data of the 2D experiment.
MODALITIES: dict[str, tuple[str, ...]] = {
    "full": tuple(FOGDRIVE_CHANNELS),
    "lidar": ("LIDAR_TOP", *(f"LIDAR_TOP_FOG_{lv}" for lv in FOG_LEVELS), "SEM_LIDAR_TOP", "BBOX_3D"),
    "cameras": (*(f"{cam}{suffix}" for cam in CAMERAS
                  for suffix in ("", *(f"_FOG_{lv}" for lv in FOG_LEVELS), "_DEPTH", "_BBOX")), "BBOX_3D"),
}
EXTRINSIC_FILE = "extrinsic_config/extrinsic_config.json"
#: The ego pose of each sample (an extra file beside the channels; readers that only know FogDrive ignore it):
#: ``data_root/<scene>/ego_pose/000000.json`` (:func:`ego_pose_path`).
EGO_POSE_FOLDER = "ego_pose"
#: The fog field of each sample of a set generated with fog fields (:mod:`fog_gym.dataset.fog_record`), likewise:
#: ``data_root/<scene>/fog_field/000000.json``.
FOG_FIELD_FOLDER = "fog_field"
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


def ego_pose_path(scene_folder: str, index: int) -> str:
    """The ego-pose file of a sample, relative to the dataset root.

    >>> ego_pose_path("data_collection_T1_day_run1_00ab", 3)
    'data_root/data_collection_T1_day_run1_00ab/ego_pose/000003.json'
    """
    return side_file_path(scene_folder, index, EGO_POSE_FOLDER)


def fog_field_path(scene_folder: str, index: int) -> str:
    """The fog-field file of a sample (sets generated with fog fields), relative to the dataset root.

    >>> fog_field_path("data_collection_T1_day_run1_00ab", 3)
    'data_root/data_collection_T1_day_run1_00ab/fog_field/000003.json'
    """
    return side_file_path(scene_folder, index, FOG_FIELD_FOLDER)


def side_file_path(scene_folder: str, index: int, folder: str) -> str:
    """A sample's extra JSON file in ``folder`` of its scene (not a channel: the index does not list it)."""
    return f"{DATA_ROOT}/{scene_folder}/{folder}/{index:06d}.json"


def channel_path(channel: str, scene_folder: str, index: int, layout: dict[str, ChannelSpec] | None = None) -> str:
    """A sample file's path relative to the dataset root (starts with ``data_root/``); ``layout`` defaults to the
    FogDrive channels."""
    layout = FOGDRIVE_CHANNELS if layout is None else layout
    if channel not in layout:
        raise ValueError(f"channel must be one of the layout's channels (default: the 35 FogDrive ones), got {channel!r}")
    folder, ext = layout[channel][:2]
    return f"{DATA_ROOT}/{scene_folder}/{folder}/{index:06d}.{ext}"

"""What every exporter shares: the source set read through :class:`~fog_gym.dataset.FogDrive` at one fog level,
and the sink that writes the export's files atomically (and keeps those of an interrupted run on ``--resume``).

Example:
    >>> fog_channel("CAM_FRONT", "dense"), fog_channel("LIDAR_TOP", "clear")
    ('CAM_FRONT_FOG_DENSE', 'LIDAR_TOP')
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from fog_gym.dataset.access import DatasetError, FogDrive
from fog_gym.dataset.decode import load_channel
from fog_gym.dataset.export.frames import class_from_height
from fog_gym.channels.spec import LIDAR_MOTIONS, LIDAR_RETURNS, lidar_channel
from fog_gym.dataset.layout import CAMERA_NAMES, layout_cameras
from fog_gym.dataset.poses import EgoPose
from fog_gym.dataset.writer import WriteError, _atomic_write, atomic_write_all

FORMATS = ("nuscenes", "kitti", "coco")
FOG_CHOICES = ("clear", "light", "moderate", "dense")
SPLIT_CHOICES = ("train", "val", "test", "all")
LIDAR = "LIDAR_TOP"


class ExportError(ValueError):
    """An export that cannot start: bad arguments, an invalid source set, an output folder it must not touch."""


def fog_channel(channel: str, fog: str) -> str:
    """The channel holding ``channel`` (a camera or ``LIDAR_TOP``) at fog level ``fog`` (``clear``: the clean one)."""
    return channel if fog == "clear" else f"{channel}_FOG_{fog.upper()}"


class Boxes(NamedTuple):
    """One sample's 3D boxes (FogDrive's LiDAR frame, left-handed) with their vehicle ids and FogDrive classes."""

    corners: np.ndarray  # (N, 8, 3)
    ids: np.ndarray  # (N,)
    classes: np.ndarray  # (N,)


class Source:
    """A FogDrive set read for an export: the scenes of ``split`` (``all``: every scene, in index order), the LiDAR
    and the ``cameras`` at fog level ``fog``, boxes with their classes, extrinsics and ego poses."""

    def __init__(self, root: str | Path, fog: str, split: str, cameras: tuple[str, ...] = ()) -> None:
        self.ds = FogDrive(root)
        self.fog = fog
        self.split = split
        self._have = set(self.ds.list_channels())
        self.all_cameras = tuple(c for c in layout_cameras(self.ds.channels) if c in self._have)
        # FogDrive's LiDAR, or a last- / dual-return LiDAR's or a sweep-in-time LiDAR's own channels
        # (fog_gym.fog.returns, fog_gym.sensors.motion; the exports write x, y, z, intensity of every point)
        variants = [lidar_channel(LIDAR, r, m) for m in LIDAR_MOTIONS for r in LIDAR_RETURNS]
        lidar = next((c for c in variants if c in self._have), LIDAR)
        self.lidar_channel = fog_channel(lidar, fog)
        self.cameras: tuple[str, ...] = ()
        self.select_cameras(cameras)
        self.scenes = self.ds.scene if split == "all" else self.ds.get_scenes_for_split(split)
        self.scene_number = {sc["token"]: k for k, sc in enumerate(self.ds.scene)}  # stable across split exports
        self._split_of = {n: s for s, names in (self.ds.splits or {}).items() for n in names}
        self.boxes_from_cameras = bool(self.all_cameras)
        self._fog_fields: dict[str, dict[str, Any] | None] = {}

    def select_cameras(self, cameras: tuple[str, ...]) -> None:
        """Export these cameras; ``ExportError`` if the set lacks one of them (at the fog level) or the LiDAR."""
        missing = [c for c in (*(fog_channel(c, self.fog) for c in cameras), self.lidar_channel) if c not in self._have]
        if missing:
            raise ExportError(f"the set has no {', '.join(missing)} channel (its channels: {', '.join(sorted(self._have))})")
        self.cameras = tuple(cameras)

    # -- structure ------------------------------------------------------------------------------------------------
    def samples(self, scene: dict) -> list[dict]:
        return self.ds.get_samples_for_scene(scene["token"])

    def sample_count(self) -> int:
        return sum(sc["nbr_samples"] for sc in self.scenes)

    def split_of(self, scene: dict) -> str:
        """The FogDrive split of a scene (``train``, ``val`` or ``test``; ``train`` if the set has no splits)."""
        return self._split_of.get(scene["name"], "train")

    @staticmethod
    def folder(scene: dict) -> str:
        """The scene's folder name (``data_collection_T…``)."""
        return Path(scene["extrinsic_config_path"]).parts[1]

    # -- data -----------------------------------------------------------------------------------------------------
    def load(self, token: str, channel: str) -> Any:
        """One channel of a sample, decoded as the set stores it."""
        path = self.ds.get_sample_paths(token, [channel])[channel]
        return load_channel(channel, path, self.ds.channels[channel])

    def path(self, token: str, channel: str) -> Path:
        return Path(self.ds.get_sample_paths(token, [channel])[channel])

    def record(self, token: str, channel: str) -> dict:
        return self.ds.get_sample_data_for_sample(token, [channel])[0]

    def lidar(self, token: str) -> np.ndarray:
        """The sample's LiDAR sweep at the export's fog level: (N, 4) float32 x, y, z, intensity (left-handed). A
        dual-return sweep gives every echo as a point (the formats have no return column: its fifth column is
        dropped, as a dual-return sensor's cloud holds both echoes)."""
        return np.ascontiguousarray(self.load(token, self.lidar_channel)[:, :4])

    def image_path(self, token: str, camera: str) -> Path:
        return self.path(token, fog_channel(camera, self.fog))

    def image_size(self, token: str, camera: str) -> tuple[int, int]:
        rec = self.record(token, fog_channel(camera, self.fog))
        if "width" not in rec:
            raise DatasetError(f"{self.ds.dataroot / rec['filename']}: the index gives no width/height for it")
        return rec["width"], rec["height"]

    def depth(self, token: str, camera: str) -> np.ndarray | None:
        """The camera's planar depth [m] (never fogged), or None where the set has no depth channel."""
        channel = f"{camera}_DEPTH"
        return self.load(token, channel) if channel in self.ds.get_sample_paths(token, [channel]) else None

    def boxes_2d(self, token: str, camera: str) -> dict[str, np.ndarray]:
        """``bboxes`` (M, 2, 2) ``[[x0, y0], [x1, y1]]`` inclusive pixels, ``vehicle_ids``, ``vehicle_class``."""
        return self.load(token, f"{camera}_BBOX")

    def radar_counts(self, token: str) -> np.ndarray | None:
        """The radar detections inside each 3D box (``num_radar_pts``) where the set's ``BBOX_3D`` file records them
        (fog-gym's sets since its visibility labels), else None."""
        import json

        try:
            data = json.loads(self.path(token, "BBOX_3D").read_bytes())
            counts = np.asarray(data["num_radar_pts"], np.int64).reshape(-1)
        except (KeyError, ValueError, TypeError, OSError):
            return None
        return counts if len(counts) == len(data.get("vehicle_ids", ())) else None

    def boxes(self, token: str) -> Boxes:
        """The sample's 3D boxes with classes from the cameras' 2D boxes (every 3D box is annotated in some
        camera), or from box heights in a set without cameras (:func:`~.frames.class_from_height`)."""
        b3 = self.load(token, "BBOX_3D")
        corners, ids = b3["bboxes_3d"].astype(np.float64), b3["vehicle_ids"]
        if self.boxes_from_cameras:
            known: dict[int, int] = {}
            for cam in self.all_cameras:
                b2 = self.boxes_2d(token, cam)
                known.update(zip(b2["vehicle_ids"].tolist(), b2["vehicle_class"].tolist()))
            heights = corners[:, 4, 2] - corners[:, 0, 2] if len(corners) else np.zeros(0)
            fallback = class_from_height(heights)
            classes = np.array([known.get(int(i), int(f)) for i, f in zip(ids, fallback)], np.int64)
        else:
            classes = class_from_height(corners[:, 4, 2] - corners[:, 0, 2]) if len(corners) else np.zeros(0, np.int64)
        return Boxes(corners, ids, classes)

    def extrinsic(self, scene: dict, camera: str) -> np.ndarray:
        """The camera's FogDrive extrinsic: 4×4 LiDAR (left-handed) → camera (x right, y down, z forward)."""
        from fog_gym.dataset.layout import extrinsic_key

        data = self.ds.load_extrinsic_config(scene["token"])
        return np.asarray(data[extrinsic_key(camera)], np.float64)

    def ego_pose(self, token: str) -> EgoPose | None:
        return self.ds.get_ego_pose(token)

    def fog_field(self, token: str) -> dict[str, Any] | None:
        """The fog field of the exported level at this sample (:mod:`fog_gym.dataset.fog_record`), JSON-ready:
        ``{"frame": [x0, y0, heading], "time": t, "field": {...}}`` (world frame, CARLA's axes); None for the clean
        data and for a set of homogeneous fog (the manifest's visibilities say all)."""
        if self.fog == "clear":
            return None
        if token not in self._fog_fields:  # (read once: the writers and fog_fields.json both ask)
            record = self.ds.get_fog_field(token)
            self._fog_fields[token] = None if record is None else {"frame": record.frame.tolist(), "time": record.time,
                                                                   "field": record.fields[self.fog]}  # fmt: skip
        return self._fog_fields[token]

    def fog_fields(self) -> dict[str, dict[str, Any]]:
        """:meth:`fog_field` of every exported sample that has one, by FogDrive sample token."""
        out = {}
        for scene in self.scenes:
            for sample in self.samples(scene):
                record = self.fog_field(sample["token"])
                if record is not None:
                    out[sample["token"]] = record
        return out


class Sink:
    """Writes an export's files under ``out``, each atomically. With ``resume`` a file that is already there
    (written whole by an interrupted run with the same settings) is kept: the bytes would be the same."""

    def __init__(self, out: Path, resume: bool) -> None:
        self.out = out
        self.resume = resume
        self.files = 0

    def write(self, rel: str, data: bytes | Callable[[], bytes]) -> None:
        """Write ``data`` (or what it returns: skipped when the file is kept) to ``out/rel``."""
        path = self.out / rel
        self.files += 1
        if self.resume and path.is_file():
            return
        try:
            _atomic_write(path, data() if callable(data) else data)
        except WriteError as e:
            raise e.with_what("cannot write the export") from None

    def copy(self, rel: str, src: Path) -> None:
        """Copy a source file byte for byte."""
        self.write(rel, lambda: _read(src))

    def write_all(self, files: Mapping[str, bytes]) -> None:
        """Write several files all or none (the tables of an export)."""
        self.files += len(files)
        try:
            atomic_write_all({self.out / rel: data for rel, data in files.items()})
        except WriteError as e:
            raise e.with_what("cannot write the export") from None


def _read(path: Path) -> bytes:
    try:
        return Path(path).read_bytes()
    except OSError as e:
        raise DatasetError(f"{path}: unreadable ({e.strerror or e})") from None


def default_cameras(fmt: str, source_cameras: tuple[str, ...]) -> tuple[str, ...]:
    """KITTI: the front camera; nuScenes and COCO: every camera of the set (none in a LiDAR-only set)."""
    if fmt == "kitti":
        return ("CAM_FRONT",)
    return tuple(c for c in CAMERA_NAMES if c in source_cameras) + tuple(c for c in source_cameras if c not in CAMERA_NAMES)

"""``FogDrive``: the dataset access class of supplementary D4 (nuScenes-devkit style, token-indexed tables).

The four index tables are loaded into RAM at construction; token → index maps and two joins (sample →
its sample_data per channel, scene → its samples in order) make the training-time lookups dictionary lookups.
``field2token`` is the only method that scans a table.

Example:
    >>> import tempfile
    >>> from fog_gym.dataset.writer import build_index
    >>> root = tempfile.mkdtemp(); _ = build_index(root)
    >>> FogDrive(root).list_scene_names()
    []
"""

from __future__ import annotations

import json
from pathlib import Path, PurePosixPath
from typing import Any

from fog_gym.dataset.layout import (
    EGO_POSE_FOLDER, FOG_FIELD_FOLDER, FOGDRIVE_CHANNELS, LAYOUT_FILE, SPLITS, TABLES, ChannelSpec, layout_from_json,
    side_file_path,
)  # fmt: skip
from fog_gym.dataset.fog_record import FogRecord, decode_fog_record
from fog_gym.dataset.poses import EgoPose, decode_ego_pose


class DatasetError(ValueError):
    """A dataset file that cannot be used: unreadable, corrupt, or an index entry pointing outside the root."""


def safe_relative_path(filename: object) -> PurePosixPath:
    """``filename`` from an index as a relative path that stays inside the dataset root, or :class:`DatasetError`.

    A dataset from elsewhere must not make the reader open other files: absolute paths, ``..`` components and
    backslashes are refused.

    >>> safe_relative_path("data_root/x/lidar/000000.npy").parts[0]
    'data_root'
    >>> safe_relative_path("../etc/passwd")
    Traceback (most recent call last):
    ...
    fog_gym.dataset.access.DatasetError: index file name '../etc/passwd' escapes the dataset root
    """
    if not isinstance(filename, str) or not filename:
        raise DatasetError(f"index file name must be a non-empty string, got {filename!r}")
    path = PurePosixPath(filename)
    if path.is_absolute() or "\\" in filename or filename.startswith("~") or ":" in path.parts[0]:
        raise DatasetError(f"index file name {filename!r} is absolute; it must be relative to the dataset root")
    if ".." in path.parts:
        raise DatasetError(f"index file name {filename!r} escapes the dataset root")
    return path


def read_json(path: Path) -> Any:
    """Parse a JSON file; a missing, unreadable or corrupt file raises :class:`DatasetError` naming it."""
    try:
        return json.loads(Path(path).read_bytes())
    except FileNotFoundError:
        raise DatasetError(f"{path}: missing") from None
    except OSError as e:
        raise DatasetError(f"{path}: unreadable ({e.strerror or e})") from None
    except ValueError as e:  # not UTF-8, not JSON, or a number too long to convert
        raise DatasetError(f"{path}: not valid JSON ({e})") from None
    except RecursionError:
        raise DatasetError(f"{path}: not valid JSON (nested too deeply)") from None


def read_layout(root: str | Path) -> dict[str, ChannelSpec]:
    """A dataset's channels → :class:`~fog_gym.dataset.layout.ChannelSpec`: ``index/channels.json`` (written by
    :func:`~fog_gym.dataset.writer.build_index` for a rig with added sensors), else the 35 FogDrive channels.
    A corrupt file raises :class:`DatasetError` naming it."""
    path = Path(root) / LAYOUT_FILE
    if not path.exists():
        return dict(FOGDRIVE_CHANNELS)
    try:
        return layout_from_json(read_json(path))
    except DatasetError:
        raise
    except ValueError as e:
        raise DatasetError(f"{path}: {e}") from None


_STR, _INT, _NUMBER = (str,), (int,), (int, float)
#: The D6 fields of each index table and their JSON types (``width``/``height`` are optional).
_REQUIRED: dict[str, dict[str, tuple[type, ...]]] = {
    "scene": {"token": _STR, "name": _STR, "nbr_samples": _INT, "first_sample_token": _STR, "last_sample_token": _STR,
              "extrinsic_config_path": _STR},  # fmt: skip
    "sample": {"token": _STR, "timestamp": _NUMBER, "scene_token": _STR, "prev": _STR, "next": _STR},
    "sample_data": {"token": _STR, "sample_token": _STR, "channel": _STR, "filename": _STR, "fileformat": _STR},
}
_OPTIONAL: dict[str, tuple[type, ...]] = {"width": _INT, "height": _INT}


def load_table(index: Path, name: str) -> list[dict]:
    """One index table, checked to be a list of records with the D6 fields of the right JSON types and unique
    tokens; :class:`DatasetError` naming the file and the record otherwise."""
    path = index / f"{name}.json"
    table = read_json(path)
    if not isinstance(table, list) or not all(isinstance(r, dict) for r in table):
        raise DatasetError(f"{path}: expected a list of records")
    tokens: set[str] = set()
    for i, rec in enumerate(table):
        missing = [k for k in _REQUIRED[name] if k not in rec]
        if missing:
            raise DatasetError(f"{path}: record {i} lacks {missing}")
        for key, types in (*_REQUIRED[name].items(), *_OPTIONAL.items()):
            value = rec.get(key, 0)
            if isinstance(value, bool) or not isinstance(value, types):
                raise DatasetError(f"{path}: record {i}: {key} must be a JSON {' or '.join(t.__name__ for t in types)}, "
                                   f"got {type(value).__name__}")  # fmt: skip
        if rec["token"] in tokens:
            raise DatasetError(f"{path}: record {i}: token {rec['token']!r} appears twice")
        tokens.add(rec["token"])
    return table


class FogDrive:
    """Read a FogDrive dataset (made by fog-gym or by the original pipeline: the layout is the same).

    >>> # ds = FogDrive("out/fogdrive"); ds.get_sample_paths(ds.sample[0]["token"])["CAM_FRONT"]
    """

    def __init__(self, dataroot: str | Path, verbose: bool = False) -> None:
        self.dataroot = Path(dataroot)
        index = self.dataroot / "index"
        if not self.dataroot.is_dir():
            raise FileNotFoundError(f"{self.dataroot} is not a folder: not a FogDrive dataset root")
        for name in TABLES:
            if not (index / f"{name}.json").exists():
                raise FileNotFoundError(f"{index / (name + '.json')} is missing: not a FogDrive dataset root")
        self.scene: list[dict] = load_table(index, "scene")
        self.sample: list[dict] = load_table(index, "sample")
        self.sample_data: list[dict] = load_table(index, "sample_data")
        for rec in self.sample_data:
            safe_relative_path(rec["filename"])
        for rec in self.scene:
            safe_relative_path(rec["extrinsic_config_path"])
        #: The dataset's channels and where and how each is stored (:func:`read_layout`).
        self.channels: dict[str, ChannelSpec] = read_layout(self.dataroot)
        splits_path = index / "splits.json"
        self.splits: dict[str, list[str]] | None = read_json(splits_path) if splits_path.exists() else None
        if self.splits is not None and not (isinstance(self.splits, dict) and set(SPLITS) <= set(self.splits) and all(
                isinstance(v, list) and all(isinstance(n, str) for n in v) for v in self.splits.values())):  # fmt: skip
            raise DatasetError(f"{splits_path}: expected an object with scene-name lists {list(SPLITS)}")
        self._index = {name: {rec["token"]: i for i, rec in enumerate(getattr(self, name))} for name in TABLES}
        self._scene_by_name = {rec["name"]: rec for rec in self.scene}
        # joins: sample token → {channel: sample_data record}; scene token → sample records in time order
        self._sample_channels: dict[str, dict[str, dict]] = {rec["token"]: {} for rec in self.sample}
        for rec in self.sample_data:
            if rec["sample_token"] not in self._sample_channels:
                raise DatasetError(f"{index / 'sample_data.json'}: {rec['filename']} belongs to unknown sample "
                                   f"{rec['sample_token']!r}")
            self._sample_channels[rec["sample_token"]][rec["channel"]] = rec
        self._scene_samples: dict[str, list[dict]] = {rec["token"]: [] for rec in self.scene}
        self._sample_scene: dict[str, str] = {}
        for rec in self.scene:
            tok, seen = rec["first_sample_token"], set()
            while tok:
                if tok in seen or tok not in self._index["sample"]:
                    raise DatasetError(f"{index / 'sample.json'}: the prev/next chain of scene {rec['name']!r} "
                                       f"{'loops' if tok in seen else 'links to unknown sample ' + repr(tok)}")
                seen.add(tok)
                s = self.sample[self._index["sample"][tok]]
                self._scene_samples[rec["token"]].append(s)
                self._sample_scene[tok] = rec["token"]
                tok = s["next"]
        if verbose:
            print(f"FogDrive: {len(self.scene)} scenes, {len(self.sample)} samples, {len(self.sample_data)} files")

    # -- O(1) lookups -----------------------------------------------------------------------------------------
    def _table(self, table_name: str) -> list[dict]:
        if table_name not in TABLES:
            raise ValueError(f"table_name must be one of {TABLES}, got {table_name!r}")
        return getattr(self, table_name)

    def get(self, table_name: str, token: str) -> dict:
        """The record of ``token`` in ``scene`` / ``sample`` / ``sample_data``."""
        return self._table(table_name)[self.get_idx(table_name, token)]

    def get_idx(self, table_name: str, token: str) -> int:
        self._table(table_name)
        try:
            return self._index[table_name][token]
        except KeyError:
            raise KeyError(f"no {table_name} with token {token!r}") from None

    def get_scene_by_name(self, name: str) -> dict:
        try:
            return self._scene_by_name[name]
        except KeyError:
            raise KeyError(f"no scene named {name!r}") from None

    def get_sample_data_path(self, sample_data_token: str) -> Path:
        return self.dataroot / self.get("sample_data", sample_data_token)["filename"]

    def get_extrinsic_config_path(self, scene_token: str) -> Path:
        return self.dataroot / self.get("scene", scene_token)["extrinsic_config_path"]

    def load_extrinsic_config(self, scene_token: str) -> dict[str, Any]:
        return read_json(self.get_extrinsic_config_path(scene_token))

    def get_ego_pose_path(self, sample_token: str) -> Path:
        """Where a sample's ego pose is stored (:mod:`fog_gym.dataset.poses`): beside its files, named as they
        are (the sample's index in its scene). The file exists only for sets recorded with ego poses."""
        return self._side_file_path(sample_token, EGO_POSE_FOLDER)

    def get_ego_pose(self, sample_token: str) -> EgoPose | None:
        """A sample's ego pose (world frame, CARLA's axes), or None where the set has none (recorded before
        ego poses were kept, or by the original pipeline). A corrupt file raises :class:`DatasetError`."""
        return self._side_file(self.get_ego_pose_path(sample_token), decode_ego_pose)

    def get_fog_field_path(self, sample_token: str) -> Path:
        """Where a sample's fog fields are stored (:mod:`fog_gym.dataset.fog_record`), likewise. The file exists
        only for sets generated with fog fields."""
        return self._side_file_path(sample_token, FOG_FIELD_FOLDER)

    def get_fog_field(self, sample_token: str) -> FogRecord | None:
        """The fog field of each level of a sample (:class:`~fog_gym.dataset.fog_record.FogRecord`: the field
        frame in the world, the field time, the fields by level name), or None where the set's fog is homogeneous
        (the levels' visibilities are the manifest's ``fog_levels``). A corrupt file raises :class:`DatasetError`."""
        return self._side_file(self.get_fog_field_path(sample_token), decode_fog_record)

    def _side_file_path(self, sample_token: str, folder: str) -> Path:
        sample = self.get("sample", sample_token)
        recs = self._sample_channels[sample["token"]]
        rec = recs.get("BBOX_3D") or next(iter(recs.values()), None)
        if rec is None:
            raise DatasetError(f"{self.dataroot / 'index' / 'sample_data.json'}: sample {sample_token!r} has no files")
        parts = PurePosixPath(rec["filename"]).parts
        if len(parts) < 3 or not PurePosixPath(parts[-1]).stem.isdigit():
            raise DatasetError(f"{self.dataroot / 'index' / 'sample_data.json'}: {rec['filename']!r} is not named "
                               "data_root/<scene>/…/<index>.<ext>")  # fmt: skip
        return self.dataroot / side_file_path(parts[1], int(PurePosixPath(parts[-1]).stem), folder)

    @staticmethod
    def _side_file(path: Path, decode) -> Any:
        try:
            data = path.read_bytes()
        except FileNotFoundError:
            return None
        except OSError as e:
            raise DatasetError(f"{path}: unreadable ({e.strerror or e})") from None
        try:
            return decode(data)
        except ValueError as e:
            raise DatasetError(f"{path}: {e}") from None

    def get_scene_for_sample(self, sample_token: str) -> dict:
        """The scene record a sample belongs to."""
        self.get("sample", sample_token)
        if sample_token not in self._sample_scene:
            index = self.dataroot / "index"
            raise DatasetError(f"{index / 'sample.json'}: sample {sample_token!r} is in the prev/next chain of no scene "
                               f"of {index / 'scene.json'}")  # fmt: skip
        return self.get("scene", self._sample_scene[sample_token])

    # -- linear in the output -----------------------------------------------------------------------------
    def get_sample_data_for_sample(self, sample_token: str, channels: list[str] | None = None) -> list[dict]:
        by_channel = self._sample_channels[self.get("sample", sample_token)["token"]]
        if channels is None:
            return list(by_channel.values())
        return [by_channel[c] for c in channels if c in by_channel]

    def get_sample_paths(self, sample_token: str, channels: list[str] | None = None,
                         absolute: bool = True) -> dict[str, Path | str]:  # fmt: skip
        """``{channel: path}`` for one sample — the fast path for training loaders."""
        recs = self.get_sample_data_for_sample(sample_token, channels)
        return {r["channel"]: (self.dataroot / r["filename"]) if absolute else r["filename"] for r in recs}

    def get_samples_for_scene(self, scene_token: str) -> list[dict]:
        self.get("scene", scene_token)
        return list(self._scene_samples[scene_token])

    def _split_names(self, split: str) -> list[str]:
        if self.splits is None:
            raise FileNotFoundError(f"{self.dataroot / 'index' / 'splits.json'} is missing")
        if split not in SPLITS:
            raise ValueError(f"split must be one of {SPLITS}, got {split!r}")
        return self.splits[split]

    def get_scenes_for_split(self, split: str) -> list[dict]:
        return [self._scene_by_name[n] for n in self._split_names(split) if n in self._scene_by_name]

    def get_samples_for_split(self, split: str) -> list[dict]:
        return [s for scene in self.get_scenes_for_split(split) for s in self._scene_samples[scene["token"]]]

    def get_sample_tokens_for_split(self, split: str) -> list[str]:
        return [s["token"] for s in self.get_samples_for_split(split)]

    def list_channels(self) -> list[str]:
        return sorted({c for chans in self._sample_channels.values() for c in chans})

    def list_scene_names(self) -> list[str]:
        return sorted(self._scene_by_name)

    # -- linear in the table (inspection only) --------------------------------------------------------------
    def field2token(self, table_name: str, field: str, query: Any) -> list[str]:
        """Tokens of the records whose ``field`` equals ``query`` (scans the table)."""
        return [rec["token"] for rec in self._table(table_name) if rec.get(field) == query]

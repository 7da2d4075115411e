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
from pathlib import Path
from typing import Any

TABLES = ("scene", "sample", "sample_data")
SPLITS = ("train", "val", "test")


class FogDrive:
    """Read a FogDrive dataset (made by fog-gym or by the original pipeline: the layout is the same).

    >>> # ds = FogDrive("out/fogdrive"); ds.get_sample_paths(ds.sample[0]["token"])["CAM_FRONT"]
    """

    def __init__(self, dataroot: str | Path, verbose: bool = False) -> None:
        self.dataroot = Path(dataroot)
        index = self.dataroot / "index"
        for name in TABLES:
            if not (index / f"{name}.json").exists():
                raise FileNotFoundError(f"{index / (name + '.json')} is missing: not a FogDrive dataset root")
        self.scene: list[dict] = json.loads((index / "scene.json").read_text())
        self.sample: list[dict] = json.loads((index / "sample.json").read_text())
        self.sample_data: list[dict] = json.loads((index / "sample_data.json").read_text())
        splits_path = index / "splits.json"
        self.splits: dict[str, list[str]] | None = json.loads(splits_path.read_text()) if splits_path.exists() else None
        self._index = {name: {rec["token"]: i for i, rec in enumerate(getattr(self, name))} for name in TABLES}
        self._scene_by_name = {rec["name"]: rec for rec in self.scene}
        # joins: sample token → {channel: sample_data record}; scene token → sample records in time order
        self._sample_channels: dict[str, dict[str, dict]] = {rec["token"]: {} for rec in self.sample}
        for rec in self.sample_data:
            self._sample_channels[rec["sample_token"]][rec["channel"]] = rec
        self._scene_samples: dict[str, list[dict]] = {rec["token"]: [] for rec in self.scene}
        for rec in self.scene:
            tok = rec["first_sample_token"]
            while tok:
                s = self.sample[self._index["sample"][tok]]
                self._scene_samples[rec["token"]].append(s)
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
        return json.loads(self.get_extrinsic_config_path(scene_token).read_text())

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

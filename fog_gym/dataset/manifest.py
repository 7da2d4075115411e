"""The generation manifest: the settings a dataset was generated with, written at the start of ``fog-gym generate``.

``index/manifest.json`` holds the scene count, resolution, scene length, base seed, towns, fog levels (name and
visibility), the channel set and the fog-gym version, and for a set generated with fog fields their kind
(``fog_fields``: banks, height or mixed). ``generate --resume`` refuses settings that differ from it
(a resumed run must not mix resolutions or scene plans), and ``validate`` checks the files against it.

Example:
    >>> m = make_manifest(scenes=2, resolution=(64, 48), seconds=1.0, seed=0, towns=("highway",),
    ...                   fog_levels={"light": 160.0, "moderate": 100.0, "dense": 50.0})
    >>> differences(m, {**m, "resolution": [32, 24]})
    ['resolution: [64, 48] in the dataset, [32, 24] now']
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from fog_gym.dataset.access import DatasetError, read_json
from fog_gym.dataset.layout import FOG_LEVELS, FOGDRIVE_CHANNELS

MANIFEST_FILE = "index/manifest.json"
FORMAT = 1
#: The settings that must agree between a run and the run it resumes.
SETTINGS = ("scenes", "resolution", "seconds", "seed", "towns", "fog_levels", "channels", "fog_fields", "camera_noise")
#: Settings a manifest may leave out, and what their absence means (``fog_fields``: written only for fog fields, so
#: a homogeneous set's manifest is what it always was).
DEFAULTS = {"fog_fields": "levels", "camera_noise": None}
#: What ``--fog-fields`` may ask for (``fog-gym generate``): FogDrive's homogeneous levels, or each level's
#: visibility as a fog bank, as ground fog, or a mix of homogeneous, bank, ground fog and a bank over ground fog.
FOG_FIELD_KINDS = ("levels", "banks", "height", "mixed")


def make_manifest(scenes: int, resolution: Sequence[int], seconds: float, seed: int, towns: Sequence[str],
                  fog_levels: Mapping[str, float], channels: Sequence[str] | None = None,
                  fog_fields: str = "levels", camera_noise: str | None = None) -> dict[str, Any]:  # fmt: skip
    """The manifest of a generation run (JSON-ready); ``fog_levels`` maps each FogDrive level name (light,
    moderate, dense) to the visibility [m] the run fogs it with; ``fog_fields`` (one of :data:`FOG_FIELD_KINDS`)
    how those levels are laid out in space (recorded only when not ``levels``)."""
    from fog_gym._version import __version__

    if fog_fields not in FOG_FIELD_KINDS:
        raise ValueError(f"fog_fields must be one of {FOG_FIELD_KINDS}, got {fog_fields!r}")
    missing = [lv.lower() for lv in FOG_LEVELS if lv.lower() not in fog_levels]
    if missing:
        raise ValueError(f"fog_levels must give a visibility for every FogDrive level, missing {missing}")

    manifest = {
        "format": FORMAT,
        "fog_gym_version": __version__,
        "scenes": int(scenes),
        "resolution": [int(v) for v in resolution],
        "seconds": float(seconds),
        "seed": int(seed),
        "towns": list(towns),
        "fog_levels": {lv.lower(): float(fog_levels[lv.lower()]) for lv in FOG_LEVELS},
        "channels": list(channels if channels is not None else FOGDRIVE_CHANNELS),
    }
    if fog_fields != DEFAULTS["fog_fields"]:
        manifest["fog_fields"] = fog_fields
    if camera_noise is not None:  # the cameras' sensor noise preset (fog_gym.sensors.camera_noise)
        manifest["camera_noise"] = camera_noise
    return manifest


def differences(stored: dict[str, Any], current: dict[str, Any]) -> list[str]:
    """One line per setting in which ``current`` differs from ``stored``."""
    old, new = ({k: m.get(k, DEFAULTS.get(k)) for k in SETTINGS} for m in (stored, current))
    return [f"{k}: {old[k]} in the dataset, {new[k]} now" for k in SETTINGS if old[k] != new[k]]


def read_manifest(root: str | Path) -> dict[str, Any] | None:
    """The manifest of a dataset, None if it has none (datasets recorded by hand or by the original pipeline).

    A manifest that is unreadable or lacks a setting raises :class:`DatasetError` naming it.
    """
    path = Path(root) / MANIFEST_FILE
    if not path.exists():
        return None
    data = read_json(path)
    missing = [k for k in SETTINGS if k not in DEFAULTS and (not isinstance(data, dict) or k not in data)]
    if missing:
        raise DatasetError(f"{path}: lacks {missing}")
    res = data["resolution"]
    if not (isinstance(res, list) and len(res) == 2 and all(_count(v) and v > 0 for v in res)):
        raise DatasetError(f"{path}: resolution must be [width, height], got {res!r}")
    if not _count(data["scenes"]):
        raise DatasetError(f"{path}: scenes must be a whole number, got {data['scenes']!r}")
    for key in ("channels", "towns"):
        if not (isinstance(data[key], list) and all(isinstance(v, str) for v in data[key])):
            raise DatasetError(f"{path}: {key} must be a list of names, got {data[key]!r}")
    if data.get("fog_fields", DEFAULTS["fog_fields"]) not in FOG_FIELD_KINDS:
        raise DatasetError(f"{path}: fog_fields must be one of {FOG_FIELD_KINDS}, got {data['fog_fields']!r}")
    return data


def _count(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value >= 0


def write_manifest(root: str | Path, manifest: dict[str, Any]) -> None:
    """Write ``index/manifest.json`` atomically."""
    from fog_gym.dataset.writer import WriteError, _atomic_write

    try:
        _atomic_write(Path(root) / MANIFEST_FILE, (json.dumps(manifest, indent=1) + "\n").encode())
    except WriteError as e:
        raise e.with_what("cannot write the generation manifest") from None

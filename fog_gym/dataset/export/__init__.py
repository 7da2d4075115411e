"""Exports of a FogDrive set to the formats detectors already read: nuScenes v1.0, KITTI object and COCO, one fog
level per export (``fog-gym export ROOT OUT --format …``; docs/exports.md).

:func:`export` checks everything before writing: the arguments (each error names the argument and the allowed
values), the source set (``validate`` must find no problem) and the output folder (it must be empty, or hold an
earlier export to replace with ``overwrite`` or an interrupted one to complete with ``resume``). The exporters read
the set through :class:`~fog_gym.dataset.FogDrive`; every file is written atomically, so an export stopped by a
full disk leaves no temporary file and ``resume`` completes it byte for byte as an uninterrupted run.

Example:
    >>> import tempfile
    >>> export(tempfile.mkdtemp(), tempfile.mkdtemp(), "yolo")
    Traceback (most recent call last):
    ...
    fog_gym.dataset.export.common.ExportError: format must be one of ('nuscenes', 'kitti', 'coco'), got 'yolo'
"""

from __future__ import annotations

import json
import shutil
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from fog_gym.dataset.export.common import (
    FOG_CHOICES, FORMATS, SPLIT_CHOICES, ExportError, Sink, Source, default_cameras,
)  # fmt: skip
from fog_gym.dataset.layout import CAMERA_NAMES
from fog_gym.dataset.lock import LOCK_FILE, DatasetLock
from fog_gym.checks import option

MANIFEST = "fog_gym_export.json"  # in OUT: the export's settings, whether it is complete, and its notes
FOG_FIELDS = "fog_fields.json"  # in OUT, for a source set of fog fields: each sample's field at the exported level

__all__ = ["FOG_CHOICES", "FORMATS", "MANIFEST", "SPLIT_CHOICES", "ExportError", "export"]


def _check_arguments(fmt: str, fog: str, split: str, cameras: Sequence[str] | None) -> None:
    for name, value, allowed in (("format", fmt, FORMATS), ("fog", fog, FOG_CHOICES), ("split", split, SPLIT_CHOICES)):
        if value not in allowed:
            raise ExportError(f"{name} must be one of {allowed}, got {value!r}")
    if cameras is not None:
        if isinstance(cameras, str) or not all(isinstance(c, str) for c in cameras) or not cameras:
            raise ExportError(f"cameras must be a non-empty list of camera names like {list(CAMERA_NAMES)}, got {cameras!r}")
        if len(set(cameras)) != len(cameras):
            raise ExportError(f"cameras must name each camera once, got {list(cameras)}")


def _check_output_folder(root: Path, out: Path, overwrite: bool, resume: bool) -> None:
    """What can be refused about the output folder without reading the set: inside the set (or holding it), not a
    folder, not empty without ``overwrite``/``resume``, or holding no earlier export to replace or resume."""
    if overwrite and resume:
        raise ExportError(f"{option('overwrite')} and {option('resume')} exclude each other: replace an export, or "
                          "complete one")  # fmt: skip
    r, o = root.resolve(), out.resolve()
    if o == r or r in o.parents or o in r.parents:
        raise ExportError(f"the output folder {out} must lie outside the dataset root {root} (and not contain it)")
    if out.exists() and not out.is_dir():
        raise ExportError(f"the output folder {out} exists and is not a folder")
    if not out.is_dir() or not _entries(out):
        return
    if not overwrite and not resume:
        raise ExportError(f"the output folder {out} is not empty; pass {option('overwrite')} to replace an earlier export "
                          f"or {option('resume')} to complete an interrupted one")  # fmt: skip
    if not isinstance(_stored_manifest(out), dict):
        if resume:
            raise ExportError(f"{out} holds no fog-gym export ({MANIFEST}) to resume")
        raise ExportError(f"the output folder {out} is not empty and holds no fog-gym export ({MANIFEST}): refusing to "
                          "delete it; choose an empty or new folder")  # fmt: skip


def _entries(out: Path) -> list[Path]:
    """What the output folder holds, but the lock of the export writing it."""
    return [p for p in out.iterdir() if p.name != LOCK_FILE]


def _stored_manifest(out: Path) -> Any:
    manifest = out / MANIFEST
    if manifest.is_file():
        try:
            return json.loads(manifest.read_bytes())
        except (OSError, ValueError, RecursionError):
            return None
    return None


def _check_output(root: Path, out: Path, settings: dict[str, Any], overwrite: bool, resume: bool) -> None:
    """:func:`_check_output_folder`, then refuse resuming an export made with other settings; with ``overwrite``,
    empty the folder of the earlier export."""
    _check_output_folder(root, out, overwrite, resume)
    if not out.is_dir() or not _entries(out):
        return
    stored = _stored_manifest(out)  # a dict: _check_output_folder refused anything else
    if resume:
        diff = [f"{k}: {stored.get(k)!r} there, {v!r} now" for k, v in settings.items() if stored.get(k) != v]
        if diff:
            raise ExportError(f"{out} holds an export with other settings ({'; '.join(diff)}); pass "
                              f"{option('overwrite')} to replace it")  # fmt: skip
        return
    for child in _entries(out):
        shutil.rmtree(child) if child.is_dir() and not child.is_symlink() else child.unlink()


def export(root: str | Path, out: str | Path, format: str, fog: str = "clear", split: str = "all",
           cameras: Sequence[str] | None = None, overwrite: bool = False, resume: bool = False,
           progress: bool = True) -> dict[str, Any]:  # fmt: skip
    """Export the FogDrive set at ``root`` to ``out`` in ``format`` (``nuscenes``, ``kitti``, ``coco``) with the
    cameras and LiDAR at fog level ``fog`` (``clear``, ``light``, ``moderate``, ``dense``), for FogDrive's ``split``
    (``train``, ``val``, ``test`` or ``all``) and ``cameras`` (default: every camera for nuScenes and COCO, the front
    one for KITTI). Returns ``{"format", "fog", "samples", "files", "seconds", "validate_seconds", "notes"}`` (the
seconds include the ``validate`` pass, ``validate_seconds`` long).

    Raises :class:`ExportError` (a ``ValueError``) before writing anything for bad arguments, an invalid set or an
    output folder it must not use, and :class:`~fog_gym.dataset.writer.WriteError` (an ``OSError``) when a file
    cannot be written (no temporary file is left; ``resume=True`` completes the export later). The export holds the
    output folder's lock (:class:`~fog_gym.dataset.lock.DatasetLock`): a second writer there meanwhile gets
    :class:`~fog_gym.dataset.lock.DatasetLocked`.
    """
    from fog_gym.dataset.validate import dataset_root_problem

    t0 = time.perf_counter()
    _check_arguments(format, fog, split, cameras)
    root, out = Path(root), Path(out)
    problem = dataset_root_problem(root)
    if problem is not None:
        raise ExportError(problem)
    _check_output_folder(root, out, overwrite, resume)  # before the validate pass: a refusal costs nothing
    with DatasetLock(out, "export"):  # one writer per output folder
        return _export_locked(root, out, format, fog, split, cameras, overwrite, resume, progress, t0)


def _export_locked(root: Path, out: Path, format: str, fog: str, split: str, cameras: Sequence[str] | None,
                   overwrite: bool, resume: bool, progress: bool, t0: float) -> dict[str, Any]:  # fmt: skip
    from tqdm import tqdm

    from fog_gym._version import __version__
    from fog_gym.dataset.validate import validate

    problems = validate(root, progress=progress)
    validate_seconds = time.perf_counter() - t0
    if problems:
        raise ExportError(f"{root} is not a valid FogDrive set ({len(problems)} problem{'s' * (len(problems) > 1)}, "
                          f"the first: {problems[0]}); `fog-gym validate {root}` lists them")  # fmt: skip
    src = Source(root, fog, split)
    cams = tuple(cameras) if cameras is not None else default_cameras(format, src.all_cameras)
    unknown = [c for c in cams if c not in src.all_cameras]
    if unknown or (format != "nuscenes" and not cams):
        raise ExportError(f"cameras must be cameras of the set {list(src.all_cameras)}, got {unknown or list(cams)}"
                          + (" (a LiDAR-only set: KITTI and COCO need camera images)" if not src.all_cameras else ""))
    src.select_cameras(cams)
    settings = {"format": format, "fog": fog, "split": split, "cameras": list(cams), "source": str(root.resolve()),
                "fog_gym_version": __version__}  # fmt: skip
    _check_output(root, out, settings, overwrite, resume)
    sink = Sink(out, resume)
    manifest = {**settings, "complete": False, "notes": []}
    sink.write_all({MANIFEST: (json.dumps(manifest, indent=1) + "\n").encode()})
    from fog_gym.dataset.export.coco import write_coco
    from fog_gym.dataset.export.kitti import write_kitti
    from fog_gym.dataset.export.nuscenes import write_nuscenes

    writer = {"nuscenes": write_nuscenes, "kitti": write_kitti, "coco": write_coco}[format]
    with tqdm(total=src.sample_count(), desc=f"export {format} ({fog})", unit="sample", disable=not progress) as bar:
        notes = writer(src, sink, bar)
    fields = src.fog_fields()
    if fields:  # a set of fog fields: each exported sample's field of the exported level, by FogDrive sample token
        sink.write_all({FOG_FIELDS: (json.dumps({"fog": fog, "samples": fields}, indent=1) + "\n").encode()})
        notes.append(f"{FOG_FIELDS}: the fog field of each sample at level {fog} (the source set was generated with "
                     "fog fields), by FogDrive sample token")  # fmt: skip
    manifest.update(complete=True, notes=notes)
    sink.write_all({MANIFEST: (json.dumps(manifest, indent=1) + "\n").encode()})
    return {"format": format, "fog": fog, "samples": src.sample_count(), "files": sink.files,
            "seconds": time.perf_counter() - t0, "validate_seconds": validate_seconds, "notes": notes}  # fmt: skip

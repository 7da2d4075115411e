"""Checking a FogDrive dataset (``fog-gym validate``) and measuring its footprint (``fog-gym stats``).

:func:`validate` never raises on a bad dataset: every unreadable, truncated, empty or wrongly shaped file (RGB,
depth and semantic PNG, ``.npy`` point clouds, box JSON, extrinsics, ego poses, fog fields, index JSON) and every index entry
that points at a missing file or outside the root becomes one line naming the file and the problem. Where the dataset has a
generation manifest (``index/manifest.json``, written by ``fog-gym generate``) the files are also checked against
it: image sizes, channel set and scene count. Channels are checked as the set's layout stores them
(``index/channels.json``, written for a rig with added sensors; the FogDrive channels otherwise).

Example:
    >>> import tempfile
    >>> validate(tempfile.mkdtemp())[0].endswith("not a FogDrive dataset (no index/ folder)")
    True
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Iterable
from pathlib import Path

import cv2
import numpy as np

from fog_gym.dataset.access import TABLES, DatasetError, FogDrive, load_table, read_json, safe_relative_path
from fog_gym.checks import json_numbers
from fog_gym.dataset.decode import box_json_problem, decode_png, png_problem, read_npy
from fog_gym.dataset.layout import (
    DATA_ROOT, FOGDRIVE_CHANNELS, LAYOUT_FILE, ChannelSpec, extrinsic_key, layout_cameras,
)  # fmt: skip
from fog_gym.dataset.fog_record import fog_record_problem
from fog_gym.dataset.poses import ego_pose_problem
from fog_gym.dataset.manifest import MANIFEST_FILE, read_manifest

EXTRINSIC_KEYS = ("extrinsic_front", "extrinsic_right", "extrinsic_left", "extrinsic_back")


def dataset_root_problem(root: str | Path) -> str | None:
    """Why ``root`` is not a FogDrive dataset root (one line), or None if it looks like one."""
    root = Path(root)
    if not root.exists():
        return f"{root}: no such folder"
    if not root.is_dir():
        return f"{root}: not a folder; a FogDrive dataset root holds data_root/ and index/"
    if not (root / "index").is_dir():
        return f"{root}: not a FogDrive dataset (no index/ folder)"
    missing = [f"index/{t}.json" for t in TABLES if not (root / "index" / f"{t}.json").is_file()]
    if missing:
        return f"{root}: not a FogDrive dataset (missing {', '.join(missing)})"
    return None


def check_png(path: Path, width: int | None = None, height: int | None = None) -> str | None:
    """The problem with one PNG of the layout (intact, 8-bit, 3 channels, the expected size), or None."""
    try:
        data = np.fromfile(path, np.uint8)
    except OSError as e:
        return f"unreadable ({e.strerror or e})"
    if data.size == 0:
        return "empty file"
    img = decode_png(data, cv2.IMREAD_UNCHANGED)
    if img is None:
        return png_problem(data) or "corrupt PNG (the decoder refused it)"
    if img.dtype != np.uint8 or img.ndim != 3 or img.shape[2] != 3:
        return f"expected an 8-bit RGB PNG without alpha, got {img.dtype} with shape {img.shape}"
    if width is not None and (img.shape[1], img.shape[0]) != (width, height):
        return f"image is {img.shape[1]}×{img.shape[0]}, expected {width}×{height}"
    return None


def check_npy(path: Path, columns: int) -> str | None:
    """The problem with one point-cloud ``.npy`` (float32, (N, columns), finite), or None."""
    try:
        read_npy(path, columns)
    except OSError as e:
        return f"unreadable ({e.strerror or e})"
    except ValueError as e:
        return str(e)
    return None


def check_box_json(path: Path, three_d: bool) -> str | None:
    """The problem with one box JSON (2D: ``bboxes`` (M, 2, 2), ``vehicle_ids``, ``vehicle_class``; 3D:
    ``bboxes_3d`` (N, 8, 3), ``vehicle_ids``), or None."""
    try:
        data = Path(path).read_bytes()
    except OSError as e:
        return f"unreadable ({e.strerror or e})"
    return box_json_problem(data, three_d)


def check_extrinsics(path: Path, keys: Iterable[str] = EXTRINSIC_KEYS) -> str | None:
    """The problem with one ``extrinsic_config.json`` (a finite 4×4 matrix under each of ``keys``: FogDrive's
    four by default), or None."""
    try:
        data = read_json(path)
    except DatasetError as e:
        return str(e).removeprefix(f"{path}: ")
    if not isinstance(data, dict):
        return "expected a JSON object"
    for key in keys:
        try:
            m = json_numbers(key, data[key]) if key in data else None
        except ValueError:
            return f"{key} is not a 4×4 matrix"
        if m is None or m.shape != (4, 4) or not np.isfinite(m).all():
            return f"{key} is missing or not a finite 4×4 matrix"
    return None


def _check_file(root: Path, rec: dict, size: tuple[int, int] | None, layout: dict[str, ChannelSpec]) -> str | None:
    """The problem with one indexed file, checked as its channel is stored (the set's layout), or None."""
    channel = rec["channel"]
    spec = layout[channel]
    path = root / rec["filename"]
    if rec["fileformat"] != spec.fileformat:
        return f"index/sample_data.json says fileformat {rec['fileformat']!r}, channel {channel} is stored as {spec.fileformat!r}"
    if not path.is_file():
        return "missing file"
    if spec.fileformat == "png":
        w, h = size if size is not None else (rec.get("width"), rec.get("height"))
        found = check_png(path, w, h)
        source = MANIFEST_FILE if size is not None else "index/sample_data.json"
        return f"{found} (as {source} says)" if found and found.startswith("image is") else found
    if spec.fileformat == "npy":
        return check_npy(path, spec.columns)  # the column count its sensor declared
    return check_box_json(path, spec.encoding == "box3d")


def validate(root: str | Path, progress: bool = False) -> list[str]:
    """Every problem found in a dataset, one line each (empty list = valid); never raises on a bad dataset.

    Checks: the index tables parse and have the D6 fields; file names stay inside the root; scenes' sample chains
    and counts; every sample has the expected channels; every file exists and decodes with the right shape and
    size; extrinsics; ego poses and fog fields where the set has them; the split rules (coverage, 50/50 day/night). With a manifest: image sizes, channel set and
    scene count as generated.
    """
    root = Path(root)
    problem = dataset_root_problem(root)
    if problem is not None:
        return [problem]
    index = root / "index"
    problems: list[str] = []
    for name in TABLES:
        try:
            load_table(index, name)
        except DatasetError as e:
            problems.append(str(e))
    try:
        manifest = read_manifest(root)
    except DatasetError as e:
        problems.append(str(e))
        manifest = None
    if problems:
        return problems
    problems += _path_problems(index)
    if problems:
        return problems
    try:
        ds = FogDrive(root)
    except (DatasetError, FileNotFoundError) as e:
        return [str(e)]
    # the set's layout is its rig's (index/channels.json; the FogDrive channels where it has none); without a
    # manifest every sample must have every channel of that layout — and, where the rig keeps FogDrive's LiDAR
    # (not a last- or dual-return one, whose channels are its own), the 35 FogDrive channels
    layout = ds.channels
    own_lidar = (root / LAYOUT_FILE).exists() and "LIDAR_TOP" not in layout
    channels = set(manifest["channels"]) if manifest else set(layout) if own_lidar else set(FOGDRIVE_CHANNELS) | set(layout)
    extrinsic_keys = list(dict.fromkeys((*EXTRINSIC_KEYS, *(extrinsic_key(c) for c in layout_cameras(layout)))))
    size = tuple(manifest["resolution"]) if manifest else None
    # a set generated with fog fields has one fog-field file per sample naming every fog level of its layout
    fields = bool(manifest) and manifest.get("fog_fields", "levels") != "levels"
    levels = sorted({c.split("_FOG_", 1)[1].lower() for c in layout if "_FOG_" in c})
    if manifest and manifest["scenes"] != len(ds.scene):
        problems.append(f"{index / 'scene.json'}: {len(ds.scene)} scenes, the manifest ({MANIFEST_FILE}) says "
                        f"{manifest['scenes']}")
    for sc in ds.scene:
        samples = ds.get_samples_for_scene(sc["token"])
        if len(samples) != sc["nbr_samples"]:
            problems.append(f"{index / 'scene.json'}: scene {sc['name']!r} has nbr_samples {sc['nbr_samples']} but "
                            f"{len(samples)} samples are linked in {index / 'sample.json'}")  # fmt: skip
        if samples and (samples[0]["token"] != sc["first_sample_token"] or samples[-1]["token"] != sc["last_sample_token"]):
            problems.append(f"{index / 'scene.json'}: scene {sc['name']!r}: first/last sample tokens do not match the "
                            f"prev/next chain of {index / 'sample.json'}")  # fmt: skip
        ext = ds.get_extrinsic_config_path(sc["token"])
        found = "missing file" if not ext.is_file() else check_extrinsics(ext, extrinsic_keys)
        if found:
            problems.append(f"{sc['extrinsic_config_path']}: {found}")
        problems += _side_file_problems(ds, samples, ds.get_ego_pose_path, ego_pose_problem, "ego poses")
        problems += _side_file_problems(ds, samples, ds.get_fog_field_path, lambda data: fog_record_problem(data, levels),
                                        "fog fields", required=fields)  # fmt: skip
    orphans = [s["token"] for s in ds.sample if s["token"] not in ds._sample_scene]
    if orphans:
        problems.append(f"{index / 'sample.json'}: {len(orphans)} samples are in the prev/next chain of no scene of "
                        f"{index / 'scene.json'}, the first {orphans[0]!r}")  # fmt: skip
    records: Iterable[dict] = ds.sample_data
    if progress:
        from tqdm import tqdm

        records = tqdm(records, desc="files", unit="file", total=len(ds.sample_data))
    for rec in records:
        if rec["channel"] not in layout:
            problems.append(f"{index / 'sample_data.json'}: {rec['filename']} has unknown channel {rec['channel']!r} "
                            "(not in the set's layout)")  # fmt: skip
            continue
        found = _check_file(root, rec, size, layout)
        if found:
            problems.append(f"{rec['filename']}: {found}")
    for s in ds.sample:
        have = {r["channel"] for r in ds.get_sample_data_for_sample(s["token"])}
        if have != channels:
            missing, extra = sorted(channels - have), sorted(have - channels)
            source = f" (expected: {root / MANIFEST_FILE})" if manifest else ""
            problems.append(f"{index / 'sample_data.json'}: sample {s['token']} has {len(have)} channels"
                            + (f", missing {missing}" if missing else "") + (f", unexpected {extra}" if extra else "")
                            + source)  # fmt: skip
    problems += _split_problems(ds)
    return problems


def _side_file_problems(ds: FogDrive, samples: list[dict], path_of, problem_of, what: str,
                        required: bool = False) -> list[str]:  # fmt: skip
    """A scene's extra files of one kind (ego poses, :mod:`fog_gym.dataset.poses`; fog fields,
    :mod:`fog_gym.dataset.fog_record`): one per sample, each valid. A scene without their folder (recorded before
    poses were kept, by the original pipeline, or with homogeneous fog) is fine unless they are ``required``."""
    problems: list[str] = []
    for k, s in enumerate(samples):
        try:
            path = path_of(s["token"])
        except DatasetError as e:
            return [str(e)]
        if k == 0 and not path.parent.is_dir():
            rel = path.parent.relative_to(ds.dataroot)
            return [f"{rel}: missing folder (the manifest says the set has {what})"] if required else []
        rel = path.relative_to(ds.dataroot)
        try:
            data = path.read_bytes()
        except FileNotFoundError:
            problems.append(f"{rel}: missing file (the scene has {what} for other samples)")
            continue
        except OSError as e:
            problems.append(f"{rel}: unreadable ({e.strerror or e})")
            continue
        found = problem_of(data)
        if found:
            problems.append(f"{rel}: {found}")
    return problems


def _path_problems(index: Path) -> list[str]:
    """Index entries whose file names are absolute or escape the root (one line each)."""
    problems = []
    for table, key in (("sample_data", "filename"), ("scene", "extrinsic_config_path")):
        for rec in load_table(index, table):
            try:
                safe_relative_path(rec[key])
            except DatasetError as e:
                problems.append(f"{index / (table + '.json')}: {e}")
    return problems


def _split_problems(ds: FogDrive) -> list[str]:
    from fog_gym.dataset.splits import SPLITS, check_splits

    where = ds.dataroot / "index" / "splits.json"
    if ds.splits is None:
        return [f"{where}: missing"]
    if not isinstance(ds.splits, dict) or not all(isinstance(ds.splits.get(k, []), list) for k in SPLITS):
        return [f"{where}: expected an object with lists {list(SPLITS)}"]
    try:
        checks = check_splits(ds.splits, [sc["name"] for sc in ds.scene])
    except (ValueError, TypeError) as e:
        return [f"{where}: {e}"]
    files = f" ({where}, against {ds.dataroot / 'index' / 'scene.json'})"
    problems = [f"splits: {key}: {checks[key]}{files}" for key in
                ("duplicate_assignments", "scenes_in_no_split", "scenes_in_split_but_not_in_index") if checks[key]]  # fmt: skip
    for split, share in checks["day_share"].items():
        if ds.splits.get(split) and share != 0.5:
            problems.append(f"splits: {split} is {share:.0%} day, not 50 %{files}")
    return problems


def stats(root: str | Path) -> list[tuple[str, int, float]]:
    """(modality, files, MB) per folder kind of the layout, as the paper's disk table (D7), largest first.

    Raises ``ValueError`` when ``root`` is not a FogDrive dataset.
    """
    root = Path(root)
    problem = dataset_root_problem(root)
    if problem is not None:
        raise ValueError(problem)
    acc: dict[str, list[float]] = defaultdict(lambda: [0, 0.0])
    for path in (root / DATA_ROOT).rglob("*"):
        if path.is_file() and not path.name.startswith("."):
            rel = path.relative_to(root / DATA_ROOT).parts[1:]
            if len(rel) < 2:
                continue
            kind = "/".join(rel[1:-1]) if rel[0].startswith("cam_") else rel[0]  # out_rgb etc., all cameras together
            acc[kind][0] += 1
            acc[kind][1] += path.stat().st_size / 1e6
    return sorted(((k, int(v[0]), v[1]) for k, v in acc.items()), key=lambda r: -r[2])


__all__ = ["check_box_json", "check_extrinsics", "check_npy", "check_png", "dataset_root_problem", "safe_relative_path",
           "stats", "validate"]

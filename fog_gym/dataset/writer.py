"""Write FogDrive scenes atomically and build the index (D6) from what is on disk.

Every file is written to a temporary name and renamed into place, and a sample's ``BBOX_3D`` file is written
last, so a sample is complete exactly when its ``BBOX_3D`` file exists. Tokens are uuid4-formatted but derived
from the scene folder, sample index and channel, so the index can be rebuilt from the files alone (after a
crash, or on a copy) and is identical every time.

Example:
    >>> token_for("scene", "data_collection_T1_day_run1_00ab")[14]  # the uuid version digit
    '4'
"""

from __future__ import annotations

import contextlib
import errno as errno_module
import hashlib
import json
import os
import struct
import uuid
from collections.abc import Callable, Mapping
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from fog_gym.dataset.layout import (
    BBOX_3D, DATA_ROOT, FOGDRIVE_CHANNELS, EXTRINSIC_FILE, LAYOUT_FILE, SAMPLE_PERIOD_US, SCENE_LAYOUT_FILE, ChannelSpec,
    channel_path, check_layout, ego_pose_path, fog_field_path, is_fogdrive_layout, layout_from_json, layout_to_json,
    parse_scene_folder, scene_name,
)  # fmt: skip
from fog_gym.dataset.png import encode_png
from fog_gym.dataset.fog_record import encode_fog_record
from fog_gym.dataset.poses import encode_ego_pose
from fog_gym.encoding import encode_depth, semantic_to_carla_rgb

EGO_POSE = "EGO_POSE"  # the key of a sample's ego-pose file among its encoded files (not a channel)
FOG_FIELD = "FOG_FIELD"  # the key of a sample's fog-field file among its encoded files (not a channel)


def token_for(*parts: object) -> str:
    """A deterministic uuid4-formatted token for ``parts``."""
    digest = hashlib.sha256("|".join(str(p) for p in parts).encode()).digest()
    return str(uuid.UUID(bytes=digest[:16], version=4))


class WriteError(OSError):
    """A file of the data path could not be written (disk full, permission lost, …): ``what`` failed at ``path``
    because of ``reason``. ``str()`` is the one line the commands print: ``<what> (<path>): <reason>``. Its
    temporary file is already removed."""

    def __init__(self, what: str, path: str | Path, reason: str, errno: int | None = None) -> None:
        super().__init__(errno, reason, str(path))
        self.what, self.path, self.reason = what, str(path), reason

    def __str__(self) -> str:
        return f"{self.what} ({self.path}): {self.reason}"

    def __reduce__(self):  # picklable across worker processes despite the custom signature
        return (WriteError, (self.what, self.path, self.reason, self.errno))

    def with_what(self, what: str) -> WriteError:
        """The same failure described as ``what`` (the caller knows what the file was)."""
        return WriteError(what, self.path, self.reason, self.errno)

    @classmethod
    def from_os_error(cls, what: str, path: str | Path, error: OSError) -> WriteError:
        if isinstance(error, WriteError):
            return error
        return cls(what, getattr(error, "filename", None) or path, error.strerror or str(error), error.errno)


#: Fault injection for tests: ``FOG_GYM_FAIL_WRITES="<ERRNO NAME>:<n>"`` (e.g. ``ENOSPC:40``) makes every file write
#: of this process from its n-th on (counting from 0) fail half-way with that error, as a full disk or a lost
#: permission would. Worker processes inherit the variable and count their own writes. Unset: no effect.
FAULT_VARIABLE = "FOG_GYM_FAIL_WRITES"
_fault_state = {"spec": None, "count": 0}


def _injected_fault() -> OSError | None:
    spec = os.environ.get(FAULT_VARIABLE)
    if spec != _fault_state["spec"]:
        _fault_state.update(spec=spec, count=0)
    if not spec:
        return None
    name, _, after = spec.partition(":")
    number = getattr(errno_module, name, None)
    if not isinstance(number, int) or not after.isdigit():
        raise ValueError(f"{FAULT_VARIABLE} must look like ENOSPC:40, got {spec!r}")
    _fault_state["count"] += 1
    return OSError(number, os.strerror(number)) if _fault_state["count"] > int(after) else None


def _write_temporary(path: Path, data: bytes) -> Path:
    """Write ``data`` beside ``path`` under a temporary name; return that name. On failure nothing is left."""
    tmp = path.with_name(f".{path.name}.tmp")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fault = _injected_fault()
        with open(tmp, "wb") as f:
            if fault is not None:
                f.write(data[: len(data) // 2])
                raise fault
            f.write(data)
    except BaseException as e:
        with contextlib.suppress(OSError):
            tmp.unlink()
        if isinstance(e, OSError):
            raise WriteError.from_os_error("cannot write a file", path, e) from None
        raise
    return tmp


def _replace(tmp: Path, path: Path) -> None:
    try:
        os.replace(tmp, path)
    except OSError as e:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise WriteError.from_os_error("cannot write a file", path, e) from None


def _extra(boxes: Mapping[str, Any], keys: tuple[str, ...]) -> dict[str, Any]:
    """The visibility labels a box file carries beside FogDrive's keys (:mod:`fog_gym.labels.visibility`): each of
    ``keys`` the boxes have, as a list, or as ``{fog level: list}`` where the env gave one per level. A reader that
    only knows FogDrive's keys ignores them."""
    out: dict[str, Any] = {}
    for k in keys:
        if k in boxes:
            v = boxes[k]
            out[k] = {lv: np.asarray(a).tolist() for lv, a in v.items()} if isinstance(v, Mapping) else np.asarray(v).tolist()
    return out


def _atomic_write(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file renamed into place; on any failure the temporary file
    is removed and :class:`WriteError` raised (an interrupt is re-raised after the same clean-up)."""
    path = Path(path)
    _replace(_write_temporary(path, data), path)


def atomic_write_all(files: Mapping[Path, bytes]) -> None:
    """Write several files so that either all are replaced or none: every temporary file is written first, then
    all are renamed into place. On a failure no temporary file is left and no file has changed."""
    done: list[tuple[Path, Path]] = []
    try:
        for path, data in files.items():
            done.append((_write_temporary(Path(path), data), Path(path)))
    except BaseException:
        for tmp, _ in done:
            with contextlib.suppress(OSError):
                tmp.unlink()
        raise
    for k, (tmp, path) in enumerate(done):
        try:
            _replace(tmp, path)
        except BaseException:
            for later, _ in done[k + 1 :]:
                with contextlib.suppress(OSError):
                    later.unlink()
            raise


def encode_npy(array: np.ndarray) -> bytes:
    import io

    buf = io.BytesIO()
    np.save(buf, np.ascontiguousarray(array, np.float32))
    return buf.getvalue()


def default_workers() -> int:
    """Threads for encoding one sample's files: the cores this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


class SceneWriter:
    """Writes one scene's samples in the FogDrive layout under ``root``.

    ``write_sample`` takes a paired-fog observation (clean + ``*_FOG_{LIGHT,MODERATE,DENSE}``), the env's
    ``info`` (``boxes_2d``, ``boxes_3d``) and, where known, the ego pose (``translation``, ``yaw``, ``velocity``,
    ``lidar_to_ego``: :mod:`fog_gym.dataset.poses`; written as ``ego_pose/<index>.json`` before ``BBOX_3D``) and,
    for fog fields, the fog record (``frame``, ``time``, ``fields``: :mod:`fog_gym.dataset.fog_record`; written as
    ``fog_field/<index>.json`` before ``BBOX_3D``);
    ``write_extrinsics`` the ``info["extrinsics"]`` dict. A file that cannot be written raises
    :class:`WriteError` naming the sample, the file and the reason, with no temporary file left behind.

    ``channels`` is the scene's layout: a ``{channel: ChannelSpec}`` mapping (a rig's,
    :func:`fog_gym.sensors.rig_layout`) or FogDrive channel names (default: all 35). A layout with channels that
    are not FogDrive's is recorded in the scene folder (``channels.json``), from which :func:`build_index` builds
    the dataset's ``index/channels.json``; a FogDrive layout writes no such file (the set stays FogDrive's format).

    A sample's files are encoded and written by ``workers`` threads (default: one per core; the PNG compressor
    and file I/O release the GIL). ``BBOX_3D`` is still written alone after every other file of the sample has
    been renamed into place. ``workers=1`` encodes and writes one file after another.
    """

    def __init__(self, root: str | Path, folder: str, channels: Any = None, workers: int | None = None) -> None:
        if parse_scene_folder(folder) is None:
            raise ValueError(f"not a FogDrive scene folder name: {folder!r}")
        if isinstance(channels, Mapping):
            layout = check_layout(dict(channels))
        else:
            names = tuple(FOGDRIVE_CHANNELS) if channels is None else tuple(channels)
            unknown = [c for c in names if c not in FOGDRIVE_CHANNELS]
            if unknown:
                raise ValueError(f"channels must be FogDrive channel names or a {{channel: ChannelSpec}} layout, "
                                 f"got unknown {unknown}")  # fmt: skip
            layout = {c: FOGDRIVE_CHANNELS[c] for c in names}
        if BBOX_3D not in layout:
            raise ValueError(f"channels must include BBOX_3D, got {list(layout)}")
        if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
            raise ValueError(f"workers must be a positive integer or None, got {workers!r}")
        self.root = Path(root)
        self.folder = folder
        self.layout: dict[str, ChannelSpec] = layout
        self.channels = tuple(layout)
        self._layout_written = is_fogdrive_layout(layout)  # FogDrive's own layout needs no file
        self.workers = default_workers() if workers is None else workers
        self._pool: ThreadPoolExecutor | None = None

    def close(self) -> None:
        """Stop the encoding threads (a later write starts them again)."""
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None

    def _path(self, channel: str, index: int) -> Path:
        if channel == EGO_POSE:
            return self.root / ego_pose_path(self.folder, index)
        if channel == FOG_FIELD:
            return self.root / fog_field_path(self.folder, index)
        return self.root / channel_path(channel, self.folder, index, self.layout)

    def _write_layout(self) -> None:
        if not self._layout_written:
            data = json.dumps(layout_to_json(self.layout), indent=1).encode()
            try:
                _atomic_write(self.root / DATA_ROOT / self.folder / SCENE_LAYOUT_FILE, data)
            except WriteError as e:
                raise e.with_what(f"cannot write the channel layout of scene {self.folder}") from None
            self._layout_written = True

    def write_extrinsics(self, extrinsics: dict[str, np.ndarray]) -> None:
        self._write_layout()
        data = {k: np.asarray(v).tolist() for k, v in extrinsics.items()}
        try:
            _atomic_write(self.root / DATA_ROOT / self.folder / EXTRINSIC_FILE, json.dumps(data).encode())
        except WriteError as e:
            raise e.with_what(f"cannot write the extrinsics of scene {self.folder}") from None

    def encode_jobs(self, obs: dict[str, np.ndarray], info: dict[str, Any], ego_pose: Mapping[str, Any] | None = None,
                    fog_field: Mapping[str, Any] | None = None) -> dict[str, Callable[[], bytes]]:  # fmt: skip
        """One zero-argument encoder per channel of the writer (and ``EGO_POSE``, ``FOG_FIELD`` where ``ego_pose``,
        ``fog_field`` are given), in write order (``BBOX_3D`` last); each returns the file's bytes."""
        from fog_gym.dataset.packing import unpack_points

        def png(key: str, convert: Callable[[np.ndarray], np.ndarray] | None = None) -> Callable[[], bytes]:
            return lambda: encode_png(obs[key] if convert is None else convert(obs[key]))

        def npy(key: str) -> Callable[[], bytes]:
            return lambda: encode_npy(unpack_points(obs, key))

        def box2d(cam: str) -> Callable[[], bytes]:
            b = info["boxes_2d"][cam]
            return lambda: json.dumps({
                "bboxes": np.asarray(b["bboxes"]).tolist(), "vehicle_ids": np.asarray(b["vehicle_ids"]).tolist(),
                "vehicle_class": np.asarray(b["vehicle_class"]).tolist(), **_extra(b, ("perceivable",)),
            }).encode()  # fmt: skip

        jobs: dict[str, Callable[[], bytes]] = {}
        for channel in self.channels:
            encoding = self.layout[channel].encoding
            if encoding == "box3d":
                continue
            if encoding == "points":
                jobs[channel] = npy(channel)
            elif encoding == "depth":
                jobs[channel] = png(channel, encode_depth)
            elif encoding == "semantic":
                jobs[channel] = png(channel, semantic_to_carla_rgb)
            elif encoding == "box2d":
                jobs[channel] = box2d(channel.removesuffix("_BBOX"))
            else:  # clean or fogged RGB
                jobs[channel] = png(channel)
        if ego_pose is not None:
            pose = encode_ego_pose(**ego_pose)  # checked now, before any file of the sample is written
            jobs[EGO_POSE] = lambda: pose
        if fog_field is not None:
            record = encode_fog_record(**fog_field)  # checked now, likewise
            jobs[FOG_FIELD] = lambda: record
        b3 = info["boxes_3d"]
        jobs["BBOX_3D"] = lambda: json.dumps({
            "bboxes_3d": np.asarray(b3["corners"]).tolist(), "vehicle_ids": np.asarray(b3["vehicle_ids"]).tolist(),
            **_extra(b3, ("num_lidar_pts", "num_radar_pts")),
        }).encode()  # fmt: skip
        return jobs

    def encode_sample(self, obs: dict[str, np.ndarray], info: dict[str, Any], ego_pose: Mapping[str, Any] | None = None,
                      fog_field: Mapping[str, Any] | None = None) -> dict[str, bytes]:  # fmt: skip
        """The file contents of the writer's channels for one sample (no I/O, one after another), ``BBOX_3D``
        last."""
        return {channel: job() for channel, job in self.encode_jobs(obs, info, ego_pose, fog_field).items()}

    def write_files(self, index: int, files: dict[str, bytes]) -> None:
        """Write encoded files; ``BBOX_3D`` goes last so its presence marks the sample complete."""
        self._write_layout()
        try:
            for channel, data in files.items():
                if channel != "BBOX_3D":
                    _atomic_write(self._path(channel, index), data)
            _atomic_write(self._path("BBOX_3D", index), files["BBOX_3D"])
        except WriteError as e:
            raise e.with_what(f"cannot write sample {index} of scene {self.folder}") from None

    def write_sample(self, index: int, obs: dict[str, np.ndarray], info: dict[str, Any],
                     ego_pose: Mapping[str, Any] | None = None, fog_field: Mapping[str, Any] | None = None) -> None:  # fmt: skip
        """Encode and write one sample; with ``workers > 1`` its files in parallel, ``BBOX_3D`` after all.
        Every thread's failed file is cleaned up before the first error is raised."""
        self._write_layout()
        if self.workers == 1:
            self.write_files(index, self.encode_sample(obs, info, ego_pose, fog_field))
            return
        if self._pool is None:
            self._pool = ThreadPoolExecutor(self.workers, thread_name_prefix="fogdrive-writer")
        jobs = self.encode_jobs(obs, info, ego_pose, fog_field)
        last = jobs.pop("BBOX_3D")

        def write(channel: str, job: Callable[[], bytes]) -> None:
            _atomic_write(self._path(channel, index), job())

        futures = [self._pool.submit(write, channel, job) for channel, job in jobs.items()]
        errors = [e for e in (f.exception() for f in futures) if e is not None]  # waits for every file
        try:
            if errors:
                raise errors[0]  # the sample stays incomplete: BBOX_3D is not written
            _atomic_write(self._path("BBOX_3D", index), last())
        except WriteError as e:
            raise e.with_what(f"cannot write sample {index} of scene {self.folder}") from None


def _png_size(path: Path) -> tuple[int, int]:
    with open(path, "rb") as f:
        head = f.read(24)
    if head[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError(f"not a PNG file: {path}")
    return struct.unpack(">II", head[16:24])


def complete_samples(root: Path, folder: str) -> int:
    """How many samples (0, 1, …, n−1 without gaps) of a scene are complete on disk."""
    n = 0
    while (root / channel_path("BBOX_3D", folder, n)).exists():
        n += 1
    return n


def scene_layout(root: str | Path, folder: str) -> dict[str, ChannelSpec]:
    """The layout a scene was written with: its ``channels.json``, or the FogDrive channels where it has none.
    An unreadable or bad file raises ``ValueError`` naming it."""
    path = Path(root) / DATA_ROOT / folder / SCENE_LAYOUT_FILE
    if not path.exists():
        return dict(FOGDRIVE_CHANNELS)
    try:
        return layout_from_json(json.loads(path.read_bytes()))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, ValueError) as e:
        raise ValueError(f"{path}: {e}") from None


def build_index(root: str | Path, split_seed: int = 0) -> dict[str, Any]:
    """Rebuild ``index/{scene,sample,sample_data,splits}.json`` from the scene folders on disk; returns the tables.

    Only complete samples count; scenes with none are left out. A scene's channels are those of its layout
    (:func:`scene_layout`) that its first sample has (all 35, a subset such as
    :data:`fog_gym.dataset.layout.MODALITIES` ``["lidar"]``, or a rig's with added sensors). Where the channels
    are not all FogDrive's, ``index/channels.json`` records every channel's storage for ``validate`` and the
    loaders; two scenes that store one channel differently raise ``ValueError``. Scenes are ordered
    by (town, time of day, run). Splits come from :func:`fog_gym.dataset.splits.make_splits` over the scene names.
    """
    root = Path(root)
    data_root = root / DATA_ROOT
    folders = sorted(
        (p.name for p in data_root.iterdir() if p.is_dir() and parse_scene_folder(p.name)) if data_root.exists() else [],
        key=lambda n: parse_scene_folder(n)[:3],
    )
    scenes, samples, sample_data = [], [], []
    dataset_layout: dict[str, ChannelSpec] = {}
    size_cache: dict[tuple[str, str], tuple[int, int]] = {}
    for folder in folders:
        town, tod, run, _ = parse_scene_folder(folder)
        n = complete_samples(root, folder)
        if n == 0:
            continue
        layout = scene_layout(root, folder)
        present = [c for c in layout if (root / channel_path(c, folder, 0, layout)).exists()]  # the scene's channels
        for c in present:
            if dataset_layout.setdefault(c, layout[c]) != layout[c]:
                raise ValueError(f"{root / DATA_ROOT / folder / SCENE_LAYOUT_FILE}: channel {c!r} is stored as "
                                 f"{layout[c]!r} here and as {dataset_layout[c]!r} in an earlier scene")  # fmt: skip
        scene_token = token_for("scene", folder)
        tokens = [token_for("sample", folder, i) for i in range(n)]
        scenes.append({
            "token": scene_token, "name": scene_name(town, tod, run),
            "description": f"town=T{town}, time_of_day={tod}, run={run}",
            "extrinsic_config_path": f"{DATA_ROOT}/{folder}/{EXTRINSIC_FILE}", "nbr_samples": n,
            "first_sample_token": tokens[0], "last_sample_token": tokens[-1],
        })  # fmt: skip
        for i, tok in enumerate(tokens):
            samples.append({"token": tok, "timestamp": float(i * SAMPLE_PERIOD_US), "scene_token": scene_token,
                            "prev": tokens[i - 1] if i else "", "next": tokens[i + 1] if i + 1 < n else ""})  # fmt: skip
            for channel in present:
                ext = layout[channel][1]
                rel = channel_path(channel, folder, i, layout)
                rec = {"token": token_for("sample_data", folder, i, channel), "sample_token": tok, "channel": channel,
                       "filename": rel, "fileformat": ext}  # fmt: skip
                if ext == "png":
                    key = (folder, channel)
                    if key not in size_cache:  # every image of a channel in a scene has one size
                        size_cache[key] = _png_size(root / rel)
                    rec["width"], rec["height"] = size_cache[key]
                sample_data.append(rec)
    from fog_gym.dataset.splits import make_splits

    tables = {"scene": scenes, "sample": samples, "sample_data": sample_data}
    splits = make_splits([sc["name"] for sc in scenes], seed=split_seed)
    files = {root / "index" / f"{name}.json": json.dumps(table).encode() for name, table in tables.items()}
    files[root / "index" / "splits.json"] = json.dumps(splits).encode()
    layout_path = root / LAYOUT_FILE
    fogdrive_layout = is_fogdrive_layout(dataset_layout)
    if not fogdrive_layout:
        check_layout(dataset_layout)
        files[layout_path] = (json.dumps(layout_to_json(dataset_layout), indent=1) + "\n").encode()
    try:
        atomic_write_all(files)  # all tables or none: a full disk cannot leave a mixed index
        if fogdrive_layout:  # FogDrive's own channels: no layout file, the format's default
            try:
                layout_path.unlink(missing_ok=True)
            except OSError as e:
                raise WriteError.from_os_error("cannot write the index", layout_path, e) from None
    except WriteError as e:
        raise e.with_what(f"cannot write the index of {root}") from None
    return {**tables, "splits": splits}

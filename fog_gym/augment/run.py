"""``fog-gym augment``: a fogged copy of a data set, file for file (:mod:`~fog_gym.augment.layouts` reads it).

* **Mirror**: every fogged file keeps its name, dtype and encoding (a ``.bin`` stays float32 with its columns, a PNG
  stays a lossless PNG of the same bit depth, a JPEG is re-encoded as JPEG at ``jpeg_quality``), so every loader of
  the source reads the copy unchanged; every other file is hard-linked (copied where a link cannot be made).
* **Deterministic**: a file's fog draws come from (``seed``, its path), whatever worker runs it and in whatever
  order; a run killed at any point and resumed (``resume=True``) ends with the same bytes as one that was not.
* **Records**: each finished file leaves a record (fog, profile, seed, the source file's SHA-256, or why it was
  skipped) under ``.fog-gym-augment/``; the end of the run gathers them, sorted, into
  :data:`MANIFEST` at the output root.
* **One writer per output root** (:class:`fog_gym.dataset.lock.DatasetLock`); a full disk or a lost permission is
  one line (:class:`fog_gym.dataset.writer.WriteError`); a bad input file (a truncated ``.bin``, a missing
  calibration, an image that does not decode) is named and skipped (``on_error="skip"``, listed in the manifest)
  or stops the run (``"stop"``).
* Several fogs: one mirror per fog under ``DST/<fog name>/``; one fog: ``DST`` itself.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import zlib
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from fog_gym.augment.layouts import FORMATS, PLANNERS, LayoutError, Task
from fog_gym.augment.profiles import get_profile, profile_info

MANIFEST = "fog_gym_augment.json"
RECORDS = ".fog-gym-augment"
SENSORS = ("lidar", "cameras")
PROFILE_OF = {"kitti": "kitti", "nuscenes": "nuscenes", "fogdrive": "fogdrive"}
COLUMNS = {"kitti": 4, "nuscenes": 5}


class AugmentError(ValueError):
    """A run that cannot go on: one line naming the file and the reason."""


def _seed_for(seed: int, rel: str) -> list[int]:
    return [int(seed) & 0xFFFFFFFF, zlib.crc32(rel.encode())]


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def read_points(path: Path, columns: int | None) -> np.ndarray:
    """A float32 point file: KITTI / nuScenes ``.bin`` (``columns`` per point) or fog-gym's ``.npy``."""
    if path.suffix == ".npy":
        from fog_gym.dataset.decode import read_npy

        return read_npy(path, 4)
    data = np.fromfile(path, np.float32)
    if columns is None or data.size % columns:
        raise ValueError(f"truncated or wrong-shaped point file ({data.size * 4} bytes is not a whole number of "
                         f"{columns}-column float32 points)")  # fmt: skip
    pts = data.reshape(-1, columns)
    if not np.isfinite(pts).all():
        raise ValueError("point file holds NaN or inf values")
    return pts


def encode_points(path: Path, points: np.ndarray) -> bytes:
    if path.suffix == ".npy":
        import io

        buf = io.BytesIO()
        np.save(buf, np.ascontiguousarray(points, np.float32))
        return buf.getvalue()
    return np.ascontiguousarray(points, np.float32).tobytes()


def read_image(path: Path) -> np.ndarray:
    data = np.fromfile(path, np.uint8)
    img = cv2.imdecode(data, cv2.IMREAD_COLOR) if len(data) else None
    if img is None:
        raise ValueError("not a decodable image")
    return img[..., ::-1].copy()


def encode_image(path: Path, rgb: np.ndarray, jpeg_quality: int) -> bytes:
    bgr = np.ascontiguousarray(rgb[..., ::-1])
    if path.suffix.lower() in (".jpg", ".jpeg"):
        ok, buf = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, int(jpeg_quality)])
    else:
        ok, buf = cv2.imencode(".png", bgr, [cv2.IMWRITE_PNG_COMPRESSION, 3])
    if not ok:
        raise ValueError("the image could not be encoded")
    return buf.tobytes()


_AIRLIGHT: dict[str, np.ndarray] = {}
#: How a KITTI or nuScenes image gets its depth (recorded in the settings, so that a resume by a version that completes
#: depth otherwise is refused rather than mixed into the same output).
CAMERA_DEPTH = "scan completed by Ku et al. (CRV 2018); above the scan the image's sky, the rest carried up its column"


def fog_file(src: Path, task: Task, fog: Any, seed: int, profile: Any, jpeg_quality: int) -> bytes:
    """The fogged bytes of one file (module docstring); a bad input raises ``ValueError`` naming what is wrong."""
    from fog_gym.augment import fog_image, fog_points

    info = task.info
    path = src / task.rel
    rng = np.random.default_rng(_seed_for(seed, task.rel))
    if task.kind == "lidar":
        pts = read_points(path, COLUMNS.get(info["format"]))
        s2f = np.asarray(info["sensor_to_field"], np.float64) if "sensor_to_field" in info else None
        return encode_points(path, fog_points(pts, fog, profile, rng, sensor_to_field=s2f))
    rgb = read_image(path)
    h, w = rgb.shape[:2]
    fmt = info["format"]
    if fmt == "kitti":
        from fog_gym.augment.layouts import kitti_camera, read_kitti_calib

        calib_path = src / info["calib"]
        if not calib_path.exists():
            raise ValueError(f"its calibration {info['calib']} is missing")
        K, T = kitti_camera(read_kitti_calib(calib_path), info["camera"])
        scan_path = src / info["scan"]
        if not scan_path.exists():
            raise ValueError(f"its scan {info['scan']} (needed for depth) is missing")
        pts = read_points(scan_path, 4)
        return encode_image(path, fog_image(rgb, K, fog, points=pts, T_cam_lidar=T, profile=profile), jpeg_quality)
    if fmt == "nuscenes":
        from fog_gym.augment import image_depth

        scan_path = src / info["scan"]
        if not scan_path.exists():
            raise ValueError(f"its LiDAR scan {info['scan']} (needed for depth) is missing")
        pts = read_points(scan_path, 5)
        K, T = np.asarray(info["K"], np.float64), np.asarray(info["T"], np.float64)
        depth = image_depth((w, h), K, pts, T, tuple(info["up"]), rgb=rgb)
        out = fog_image(rgb, K, fog, depth=depth, camera_to_field=np.asarray(info["camera_to_field"]), profile=profile)
        return encode_image(path, out, jpeg_quality)
    # fog-gym's own layout: exact depth, and the airlight fog-gym made the set's fog with
    from fog_gym.dataset.decode import load_channel
    from fog_gym.dataset.export.frames import camera_intrinsic as intrinsic

    depth = load_channel(f"{info['camera']}_DEPTH", src / info["depth"])
    key = str(src / info["first"])
    if key not in _AIRLIGHT:
        from fog_gym.fog import atmospheric_light, night_airlight

        first = read_image(src / info["first"])
        if info.get("night"):
            _AIRLIGHT[key] = night_airlight(first, load_channel(f"{info['camera']}_DEPTH", src / info["first_depth"]))
        else:
            _AIRLIGHT[key] = atmospheric_light(first)
    T = info.get("T")
    c2f = None if T is None else get_profile(profile).sensor_to_field() @ np.linalg.inv(np.asarray(T, np.float64))
    out = fog_image(rgb, intrinsic(w, h), fog, depth=depth, airlight=_AIRLIGHT[key], camera_to_field=c2f, profile=profile,
                    glow=bool(info.get("night")))  # fmt: skip
    return encode_image(path, out, jpeg_quality)


def _record_path(dst: Path, rel: str) -> Path:
    return dst / RECORDS / hashlib.sha1(rel.encode()).hexdigest()[:2] / (hashlib.sha1(rel.encode()).hexdigest() + ".json")


def _link(src: Path, out: Path) -> None:
    out.parent.mkdir(parents=True, exist_ok=True)
    if out.exists():
        return
    tmp = out.with_name(f".{out.name}.{os.getpid()}.link")
    try:
        os.link(src, tmp)
    except OSError:
        shutil.copy2(src, tmp)
    os.replace(tmp, out)


def run_tasks(src: str, dst: str, tasks: list[dict], fog_info: dict, seed: int, profile: dict, on_error: str,
              jpeg_quality: int) -> list[dict]:  # fmt: skip
    """Fog (or link) ``tasks`` from ``src`` into ``dst``; each leaves its record. Runs in a worker or a Ray task."""
    from fog_gym.augment.profiles import LidarProfile
    from fog_gym.dataset.access import DatasetError
    from fog_gym.dataset.writer import WriteError, _atomic_write
    from fog_gym.fog.fields import field_from_info

    fog = field_from_info(fog_info)
    prof = LidarProfile(**profile)
    s, d = Path(src), Path(dst)
    out = []
    for t in tasks:
        task = Task(**t)
        target = d / task.rel
        rec_path = _record_path(d, task.rel)
        if rec_path.exists() and (target.exists() or json.loads(rec_path.read_text()).get("skipped")):
            out.append(json.loads(rec_path.read_text()))
            continue
        if task.kind == "link":
            try:
                _link(s / task.rel, target)
            except OSError as e:
                raise WriteError.from_os_error(f"cannot link {task.rel}", target, e) from None
            continue
        record: dict[str, Any] = {"file": task.rel, "kind": task.kind, "seed": seed}
        try:
            record["source_sha256"] = _sha256(s / task.rel)
            data = fog_file(s, task, fog, seed, prof, jpeg_quality)
        except (ValueError, DatasetError, FileNotFoundError) as e:
            reason = str(e).split("\n")[0]
            if on_error == "stop":
                raise AugmentError(f"{s / task.rel}: {reason} (pass --on-error skip to skip such files)") from None
            record["skipped"] = reason
        else:
            target.parent.mkdir(parents=True, exist_ok=True)
            _atomic_write(target, data)
            record["output_sha256"] = hashlib.sha256(data).hexdigest()
        rec_path.parent.mkdir(parents=True, exist_ok=True)
        _atomic_write(rec_path, json.dumps(record, sort_keys=True).encode())
        out.append(record)
    return out


def fog_info(fog: Any) -> dict[str, Any]:
    """A fog level's or field's parameters, JSON-ready (:func:`fog_gym.fog.fields.field_from_info` reads them)."""
    from fog_gym.fog.fields import field_info

    return json.loads(json.dumps(field_info(fog), default=str))


def augment(src: str | Path, dst: str | Path, fmt: str, fogs: Sequence[Any], sensors: Sequence[str] = SENSORS,
            seed: int = 0, workers: int = 1, ray_address: str | None = None, resume: bool = False,
            on_error: str = "stop", jpeg_quality: int = 95, profile: Any = None, progress: bool = True) -> dict[str, Any]:  # fmt: skip
    """Write a fogged mirror of the data set at ``src`` (format ``fmt``) into ``dst`` for each fog (module
    docstring); returns ``{fog name: manifest}``. Bad options fail before any work."""
    from tqdm import tqdm

    from fog_gym.augment import as_fog
    from fog_gym.dataset.lock import DatasetLock

    if fmt not in FORMATS:
        raise ValueError(f"format must be one of {FORMATS}, got {fmt!r}")
    bad = [s for s in sensors if s not in SENSORS]
    if bad or not sensors:
        raise ValueError(f"sensors must be a non-empty subset of {SENSORS}, got {list(sensors)}")
    if on_error not in ("stop", "skip"):
        raise ValueError(f"on_error must be stop or skip, got {on_error!r}")
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers must be a positive integer, got {workers!r}")
    if not (isinstance(jpeg_quality, int) and 1 <= jpeg_quality <= 100):
        raise ValueError(f"jpeg_quality must be an integer in 1–100, got {jpeg_quality!r}")
    levels = [as_fog(f) for f in fogs]
    if not levels:
        raise ValueError("give at least one fog")
    if len({lv.name for lv in levels}) < len(levels):
        raise ValueError(f"the fogs must have distinct names, got {[lv.name for lv in levels]}")
    prof = get_profile(profile or PROFILE_OF[fmt])
    src, dst = Path(src), Path(dst)
    if not src.is_dir():
        raise ValueError(f"source {src} is not a folder")
    if dst.resolve() == src.resolve() or src.resolve() in dst.resolve().parents:
        raise ValueError(f"the output {dst} must lie outside the source {src}")
    tasks = PLANNERS[fmt](src, tuple(sensors))
    from fog_gym.dataset.lock import LOCK_FILE

    if dst.exists() and any(p.name != LOCK_FILE for p in dst.iterdir()) and not resume:
        raise ValueError(f"output root {dst} is not empty; pass --resume to continue an interrupted run")
    results = {}
    with DatasetLock(dst, "augment"):
        for level in levels:
            root = dst / level.name if len(levels) > 1 else dst
            settings = {"format": fmt, "fog": fog_info(level), "seed": seed, "profile": profile_info(prof),
                        "sensors": sorted(sensors), "jpeg_quality": jpeg_quality, "source": str(src.resolve()),
                        "camera_depth": "the set's depth channel" if fmt == "fogdrive" else CAMERA_DEPTH}  # fmt: skip
            _check_settings(root, settings, resume)
            chunks = [tasks[i:i + 16] for i in range(0, len(tasks), 16)]
            payload = [[asdict(t) for t in c] for c in chunks]
            args = (str(src), str(root), fog_info(level), seed, asdict(prof), on_error, jpeg_quality)
            records: list[dict] = []
            with tqdm(total=len(tasks), desc=f"augment {level.name}", unit="file", disable=not progress) as bar:
                if ray_address is not None:
                    try:
                        import ray
                    except ImportError:
                        raise ValueError("--ray needs the optional 'ray' extra: pip install 'fog-gym[ray]'") from None
                    if not ray.is_initialized():
                        ray.init(address=ray_address)
                    remote = ray.remote(run_tasks)
                    refs = {remote.remote(args[0], args[1], c, *args[2:]): len(c) for c in payload}
                    pending = list(refs)
                    while pending:
                        done, pending = ray.wait(pending)
                        for ref in done:
                            records += ray.get(ref)
                            bar.update(refs[ref])
                elif workers == 1:
                    for c in payload:
                        records += run_tasks(args[0], args[1], c, *args[2:])
                        bar.update(len(c))
                else:
                    import multiprocessing as mp
                    from concurrent.futures import ProcessPoolExecutor, as_completed

                    with ProcessPoolExecutor(workers, mp_context=mp.get_context("spawn")) as pool:
                        futures = {pool.submit(run_tasks, args[0], args[1], c, *args[2:]): len(c) for c in payload}
                        try:
                            for fut in as_completed(futures):
                                records += fut.result()
                                bar.update(futures[fut])
                        except BaseException:
                            for f in futures:
                                f.cancel()
                            raise
            manifest = {**settings, "files": sorted((r for r in records if "skipped" not in r), key=lambda r: r["file"]),
                        "skipped": sorted((r for r in records if "skipped" in r), key=lambda r: r["file"]),
                        "linked": sum(t.kind == "link" for t in tasks)}  # fmt: skip
            from fog_gym.dataset.writer import _atomic_write

            _atomic_write(root / MANIFEST, json.dumps(manifest, indent=1, sort_keys=True).encode())
            results[level.name] = manifest
    return results


def _check_settings(root: Path, settings: dict[str, Any], resume: bool) -> None:
    """Keep a run's settings beside its records; a resume with other settings is refused, naming them."""
    from fog_gym.dataset.writer import _atomic_write

    path = root / RECORDS / "settings.json"
    if path.exists():
        kept = json.loads(path.read_text())
        diff = sorted(k for k in set(kept) | set(settings) if kept.get(k) != json.loads(json.dumps(settings)).get(k))
        if diff:
            raise ValueError(f"{root} holds an augment run with other settings ({', '.join(diff)}); use another output "
                             "or the same settings to resume")  # fmt: skip
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    _atomic_write(path, json.dumps(settings, sort_keys=True).encode())


__all__ = ["MANIFEST", "AugmentError", "LayoutError", "augment", "fog_file", "read_points"]

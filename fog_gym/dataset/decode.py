"""Decoding FogDrive files (no torch): PNG → RGB / depth metres / tag ids, ``.npy`` → float32 points, box JSON →
arrays. A missing or corrupt file raises :class:`~fog_gym.dataset.access.DatasetError` naming its path.

The checks here are the ones ``validate`` applies, so a file ``validate`` accepts always decodes and a file the
loader refuses is always one ``validate`` reports. They parse untrusted bytes without trusting them: a PNG's chunk
structure and CRCs and its header's size are checked before the image decoder sees it (no decoder noise, no huge
allocation), a ``.npy`` header's dtype and shape are checked against the file size before any data is read, and
box JSON is checked for types and shapes before it becomes arrays.

Example:
    >>> decode_bbox_json(b'{"bboxes": [[[1, 2], [3, 4]]], "vehicle_ids": [7], "vehicle_class": [0]}')["bboxes"].shape
    (1, 2, 2)
    >>> box_json_problem(b'{"bboxes_3d": "x", "vehicle_ids": []}', three_d=True)
    'wrongly shaped boxes (bboxes_3d must be numbers)'
"""

from __future__ import annotations

import json
import zlib
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from fog_gym.checks import json_numbers
from fog_gym.dataset.access import DatasetError
from fog_gym.dataset.layout import FOGDRIVE_CHANNELS, ChannelSpec
from fog_gym.encoding import decode_depth

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
PNG_END = b"\x00\x00\x00\x00IEND\xaeB`\x82"  # the IEND chunk every complete PNG ends with
#: The largest image decoded (pixels): far above FogDrive's 1280×960; a corrupt header cannot make us allocate more.
MAX_PIXELS = 1 << 26


def png_problem(data: Any) -> str | None:
    """The structural problem with PNG bytes (signature, chunk lengths and CRCs, IHDR first with a sane size,
    IEND last), or None. Never raises.

    >>> png_problem(PNG_SIGNATURE + b" truncated")
    'truncated or corrupt PNG'
    """
    view = memoryview(np.ascontiguousarray(np.frombuffer(data, np.uint8)) if not isinstance(data, bytes) else data)
    n = len(view)
    if n < 57 or bytes(view[:8]) != PNG_SIGNATURE or bytes(view[-12:]) != PNG_END:
        return "truncated or corrupt PNG"
    pos = 8
    while pos + 12 <= n:
        length = int.from_bytes(view[pos : pos + 4], "big")
        kind = bytes(view[pos + 4 : pos + 8])
        end = pos + 12 + length
        if length > 0x7FFFFFFF or end > n:
            return "truncated or corrupt PNG (a chunk runs past the end)"
        if zlib.crc32(view[pos + 4 : pos + 8 + length]) != int.from_bytes(view[end - 4 : end], "big"):
            return f"corrupt PNG (CRC error in a {kind!r} chunk)"
        if pos == 8:
            if kind != b"IHDR" or length != 13:
                return "corrupt PNG (no IHDR header first)"
            width, height = int.from_bytes(view[16:20], "big"), int.from_bytes(view[20:24], "big")
            if not (0 < width and 0 < height and width * height <= MAX_PIXELS):
                return f"corrupt PNG (header says {width}×{height} pixels)"
        if kind == b"IEND":
            return None if end == n else "corrupt PNG (data after IEND)"
        pos = end
    return "truncated or corrupt PNG"


def decode_png(data: np.ndarray, flags: int = cv2.IMREAD_COLOR) -> np.ndarray | None:
    """Decode PNG bytes (a uint8 array) with OpenCV ``flags``, or None if they are not a complete, intact PNG.

    A truncated or bit-flipped file is caught before libpng sees it (no stray ``libpng error`` on stderr).

    >>> decode_png(np.frombuffer(b"\\x89PNG\\r\\n\\x1a\\n truncated", np.uint8)) is None
    True
    """
    data = np.asarray(data, np.uint8)
    if png_problem(data) is not None:
        return None
    try:
        return cv2.imdecode(data, flags)
    except cv2.error:
        return None


def read_npy(path: str | Path, columns: int) -> np.ndarray:
    """A point cloud ``.npy``: float32, C order, (N, ``columns``), finite, exactly as long as its header says.
    ``ValueError`` with the problem otherwise (``OSError`` if unreadable); never allocates more than the file."""
    with open(path, "rb") as f:
        size = Path(path).stat().st_size
        if size == 0:
            raise ValueError("empty file")
        try:
            major, _ = np.lib.format.read_magic(f)
            read_header = np.lib.format.read_array_header_1_0 if major == 1 else np.lib.format.read_array_header_2_0
            shape, fortran, dtype = read_header(f)
        except Exception as e:  # noqa: BLE001 - numpy's header parser can raise many kinds on arbitrary bytes
            raise ValueError(f"truncated or corrupt .npy ({type(e).__name__})") from None
        if dtype != np.dtype("<f4") or fortran or len(shape) != 2 or shape[1] != columns:
            raise ValueError(f"expected float32 (N, {columns}), got {dtype} {shape}" + (" in Fortran order" if fortran else ""))
        if f.tell() + shape[0] * columns * 4 != size:
            raise ValueError(f"truncated or corrupt .npy (the header's {shape} does not match the file size)")
        a = np.fromfile(f, "<f4", shape[0] * columns).reshape(shape)
    if not np.isfinite(a).all():
        raise ValueError("contains NaN or infinite values")
    return a


def _box_arrays(data: Any, three_d: bool) -> dict[str, np.ndarray]:
    """The checked arrays of a parsed box JSON; ``ValueError`` with the problem otherwise."""
    if not isinstance(data, dict):
        raise ValueError("expected a JSON object")
    keys = ("bboxes_3d", "vehicle_ids") if three_d else ("bboxes", "vehicle_ids", "vehicle_class")
    missing = [k for k in keys if k not in data]
    if missing:
        raise ValueError(f"missing keys {missing}")
    try:
        boxes = json_numbers(keys[0], data[keys[0]])
        per_box = [json_numbers(k, data[k]) for k in keys[1:]]
    except ValueError as e:
        raise ValueError(f"wrongly shaped boxes ({e})") from None
    tail = (8, 3) if three_d else (2, 2)
    if boxes.size == 0:
        boxes = boxes.reshape((0, *tail))
    if boxes.shape[1:] != tail:
        raise ValueError(f"wrongly shaped boxes ({keys[0]} has shape {boxes.shape}, expected (N, {', '.join(map(str, tail))}))")
    if any(a.ndim != 1 or len(a) != len(boxes) for a in per_box if a.size or len(boxes)):
        raise ValueError(f"{', '.join(keys)} must have one entry per box")
    if not np.isfinite(boxes).all():
        raise ValueError("boxes contain NaN or infinite values")
    if (np.abs(boxes) > 1e9).any():
        raise ValueError("boxes contain values beyond 1e9")
    ints = [a.reshape(-1) for a in per_box]
    if any(not np.isfinite(a).all() or (a != np.round(a)).any() or (np.abs(a) > 2**53).any() for a in ints):
        raise ValueError(f"{', '.join(keys[1:])} must be integers")
    out = {"bboxes_3d": boxes.astype(np.float32)} if three_d else {"bboxes": boxes.astype(np.int64)}
    for k, a in zip(keys[1:], ints):
        out[k] = a.astype(np.int64)
    return out


def _parse_json(data: bytes) -> Any:
    try:
        return json.loads(data)
    except (ValueError, RecursionError) as e:  # not UTF-8, not JSON, nested too deeply, an over-long number
        raise ValueError(f"corrupt JSON ({type(e).__name__})" if data else "empty file") from None


def box_json_problem(data: bytes, three_d: bool) -> str | None:
    """The problem with one box JSON's bytes (2D: ``bboxes`` (M, 2, 2) ints, ``vehicle_ids``, ``vehicle_class``;
    3D: ``bboxes_3d`` (N, 8, 3), ``vehicle_ids``; one id per box, finite), or None. Never raises."""
    try:
        _box_arrays(_parse_json(data), three_d)
    except ValueError as e:
        return str(e)
    return None


def decode_bbox_json(data: bytes) -> dict[str, np.ndarray]:
    """Box JSON bytes → arrays (3D if it has ``bboxes_3d``); ``ValueError`` with the problem if they are not one."""
    parsed = _parse_json(data)
    return _box_arrays(parsed, isinstance(parsed, dict) and "bboxes_3d" in parsed)


def load_channel(channel: str, path: str | Path, spec: ChannelSpec | None = None) -> Any:
    """Decode one file of ``channel`` stored as ``spec`` (default: the FogDrive channel's; a dataset's own specs
    are ``FogDrive(root).channels``); a missing or corrupt file raises :class:`DatasetError` naming its path."""
    if spec is None:
        if channel not in FOGDRIVE_CHANNELS:
            raise ValueError(f"channel {channel!r} is not a FogDrive channel: pass its spec, FogDrive(root).channels[{channel!r}]")
        spec = FOGDRIVE_CHANNELS[channel]
    fmt, encoding = spec.fileformat, spec.encoding
    try:
        if fmt == "npy":
            return read_npy(path, spec.columns)
        if fmt == "json":
            return _box_arrays(_parse_json(Path(path).read_bytes()), encoding == "box3d")
        data = np.fromfile(path, np.uint8)
    except FileNotFoundError:
        raise DatasetError(f"{path}: missing") from None
    except OSError as e:
        raise DatasetError(f"{path}: unreadable {channel} file ({e.strerror or e})") from None
    except ValueError as e:
        raise DatasetError(f"{path}: corrupt {channel} file ({e})") from None
    img = decode_png(data)
    if img is None:
        raise DatasetError(f"{path}: corrupt {channel} file (not a decodable PNG)")
    rgb = img[..., ::-1]
    if encoding == "depth":
        return decode_depth(rgb)
    if encoding == "semantic":
        return np.ascontiguousarray(rgb[..., 0])
    return np.ascontiguousarray(rgb)

"""Decoding FogDrive files (no torch): PNG → RGB / depth metres / tag ids, ``.npy`` → float32 points, box JSON →
arrays. A missing or corrupt file raises :class:`~fog_gym.dataset.access.DatasetError` naming its path.

Example:
    >>> decode_bbox_json(b'{"bboxes": [[[1, 2], [3, 4]]], "vehicle_ids": [7], "vehicle_class": [0]}')["bboxes"].shape
    (1, 2, 2)
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from fog_gym.dataset.access import DatasetError
from fog_gym.dataset.layout import FOGDRIVE_CHANNELS, ChannelSpec
from fog_gym.encoding import decode_depth


def decode_png(data: np.ndarray, flags: int = cv2.IMREAD_COLOR) -> np.ndarray | None:
    """Decode PNG bytes (a uint8 array) with OpenCV ``flags``, or None if they are not a complete PNG.

    A truncated file is caught before libpng sees it (no stray ``libpng error`` on stderr).

    >>> decode_png(np.frombuffer(b"\\x89PNG\\r\\n\\x1a\\n truncated", np.uint8)) is None
    True
    """
    data = np.asarray(data, np.uint8)
    if len(data) < 57 or bytes(data[:8]) != PNG_SIGNATURE or bytes(data[-12:]) != PNG_END:
        return None
    return cv2.imdecode(data, flags)


PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
PNG_END = b"\x00\x00\x00\x00IEND\xaeB`\x82"  # the IEND chunk every complete PNG ends with


def decode_bbox_json(data: bytes) -> dict[str, np.ndarray]:
    d = json.loads(data)
    if "bboxes_3d" in d:
        return {"bboxes_3d": np.asarray(d["bboxes_3d"], np.float32).reshape(-1, 8, 3),
                "vehicle_ids": np.asarray(d["vehicle_ids"], np.int64)}  # fmt: skip
    return {"bboxes": np.asarray(d["bboxes"], np.int64).reshape(-1, 2, 2),
            "vehicle_ids": np.asarray(d["vehicle_ids"], np.int64),
            "vehicle_class": np.asarray(d["vehicle_class"], np.int64)}  # fmt: skip


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
            return np.load(path, allow_pickle=False).astype(np.float32, copy=False)
        if fmt == "json":
            return decode_bbox_json(Path(path).read_bytes())
        data = np.fromfile(path, np.uint8)
    except FileNotFoundError:
        raise DatasetError(f"{path}: missing") from None
    except (OSError, ValueError, EOFError, KeyError, TypeError) as e:  # truncated .npy, corrupt JSON, bad shapes
        raise DatasetError(f"{path}: corrupt {channel} file ({type(e).__name__}: {e})") from None
    img = decode_png(data)
    if img is None:
        raise DatasetError(f"{path}: corrupt {channel} file (not a decodable PNG)")
    rgb = img[..., ::-1]
    if encoding == "depth":
        return decode_depth(rgb)
    if encoding == "semantic":
        return np.ascontiguousarray(rgb[..., 0])
    return np.ascontiguousarray(rgb)

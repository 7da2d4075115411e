"""Lossless PNG for the FogDrive layout's images (RGB, fogged RGB, CARLA-encoded depth, CARLA semantic colours).

A sample writes 24 PNGs, so their encoding sets the pace of dataset writing. :func:`encode_png` writes the smallest
valid PNG container itself (signature, ``IHDR`` for 8-bit RGB, one ``IDAT``, ``IEND``) around a zlib stream of the
unfiltered scanlines made by zlib-ng at level 1, through ``imagecodecs`` (a well-kept binding of the image and
compression libraries). Every PNG reader decodes it (tested with Pillow and OpenCV).

Measured on one full-rig frame (1280 × 960 RGB, colour-encoded depth; 2-core CPU, the median of 10 encodings): zlib-ng
level 1 without filter about 4 ms per image against about 16 ms for OpenCV's encoder at zlib level 1 without filter
(the previous writer), with files about 1.25× as large; libdeflate level 1 was 2× faster than OpenCV with smaller
files, the PNG encoders of imagecodecs (libpng, libspng) 1.5× at best. The Sub and Up filters shrank files by under
10 % for 25 % more time.

Example:
    >>> import zlib
    >>> png = encode_png(np.arange(24, dtype=np.uint8).reshape(2, 4, 3))
    >>> png[:8] == PNG_SIGNATURE, png[12:16], int.from_bytes(png[16:20], "big"), int.from_bytes(png[20:24], "big")
    (True, b'IHDR', 4, 2)
"""

from __future__ import annotations

import struct
import zlib

import numpy as np

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: zlib-ng's level: 1, the fastest that still compresses (0 stores the pixels: 20× larger files).
LEVEL = 1


def _chunk(tag: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(data, zlib.crc32(tag)))


def encode_png(rgb: np.ndarray) -> bytes:
    """Lossless PNG of an ``(H, W, 3)`` uint8 RGB image: 8-bit truecolour, no alpha, no interlace, filter type 0
    (None) on every scanline, compressed by zlib-ng at :data:`LEVEL`."""
    import imagecodecs

    a = np.asarray(rgb)
    if a.ndim != 3 or a.shape[2] != 3 or a.dtype != np.uint8 or not a.shape[0] or not a.shape[1]:
        raise ValueError(f"expected a non-empty uint8 (H, W, 3) RGB image, got {a.dtype} {a.shape}")
    h, w = a.shape[:2]
    rows = np.empty((h, 1 + 3 * w), np.uint8)  # each scanline: its filter type (0), then its pixels
    rows[:, 0] = 0
    rows[:, 1:] = a.reshape(h, 3 * w)
    ihdr = struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)  # 8 bits per sample, truecolour, deflate, filter 0, no interlace
    idat = bytes(imagecodecs.zlibng_encode(rows, level=LEVEL))
    return PNG_SIGNATURE + _chunk(b"IHDR", ihdr) + _chunk(b"IDAT", idat) + _chunk(b"IEND", b"")

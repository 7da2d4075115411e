"""CARLA depth encoding, semantic tags (CARLA ≥ 0.9.14) and the Cityscapes palette. Pure numpy.

Example:
    >>> import numpy as np
    >>> rgb = encode_depth(np.array([[12.345]], dtype=np.float32))
    >>> float(decode_depth(rgb)[0, 0]).__round__(3)
    12.345
"""

from __future__ import annotations

import numpy as np

#: CARLA ≥ 0.9.14 semantic tag ids (``carla.CityObjectLabel``).
SEMANTIC_TAGS: dict[str, int] = {
    "Unlabeled": 0, "Road": 1, "SideWalk": 2, "Building": 3, "Wall": 4, "Fence": 5, "Pole": 6,
    "TrafficLight": 7, "TrafficSign": 8, "Vegetation": 9, "Terrain": 10, "Sky": 11, "Pedestrian": 12,
    "Rider": 13, "Car": 14, "Truck": 15, "Bus": 16, "Train": 17, "Motorcycle": 18, "Bicycle": 19,
    "Static": 20, "Dynamic": 21, "Other": 22, "Water": 23, "RoadLine": 24, "Ground": 25, "Bridge": 26,
    "RailTrack": 27, "GuardRail": 28,
}  # fmt: skip
TAG_NAMES: dict[int, str] = {v: k for k, v in SEMANTIC_TAGS.items()}

#: Cityscapes palette as CARLA's ``CityScapesPalette`` (index = tag id).
CITYSCAPES_PALETTE = np.array(
    [
        (0, 0, 0), (128, 64, 128), (244, 35, 232), (70, 70, 70), (102, 102, 156), (190, 153, 153),
        (153, 153, 153), (250, 170, 30), (220, 220, 0), (107, 142, 35), (152, 251, 152), (70, 130, 180),
        (220, 20, 60), (255, 0, 0), (0, 0, 142), (0, 0, 70), (0, 60, 100), (0, 80, 100), (0, 0, 230),
        (119, 11, 32), (110, 190, 160), (170, 120, 50), (55, 90, 80), (45, 60, 150), (157, 234, 50),
        (81, 0, 81), (150, 100, 100), (230, 150, 140), (180, 165, 180),
    ],
    dtype=np.uint8,
)  # fmt: skip

DEPTH_MAX_M = 1000.0
_DEPTH_SCALE = 256**3 - 1


def encode_depth(depth_m: np.ndarray) -> np.ndarray:
    """Planar depth in metres ``(H, W)`` → CARLA 24-bit RGB ``(H, W, 3)`` uint8.

    ``metres = 1000 · (R + 256 G + 256² B) / (256³ − 1)``; values are clipped to [0, 1000] m and rounded
    to the nearest code (≈ 0.06 mm steps).
    """
    d = np.asarray(depth_m, dtype=np.float64)
    if not np.all(np.isfinite(d)):
        raise ValueError("depth must be finite (sky is 1000 m, not inf)")
    code = np.rint(np.clip(d, 0.0, DEPTH_MAX_M) / DEPTH_MAX_M * _DEPTH_SCALE).astype(np.uint32)
    out = np.empty(d.shape + (3,), dtype=np.uint8)
    out[..., 0] = code & 0xFF
    out[..., 1] = (code >> 8) & 0xFF
    out[..., 2] = (code >> 16) & 0xFF
    return out


def decode_depth(rgb: np.ndarray) -> np.ndarray:
    """CARLA 24-bit RGB ``(H, W, 3)`` (R, G, B order) → planar depth in metres, float32."""
    a = np.asarray(rgb)
    if a.ndim < 1 or a.shape[-1] < 3:
        raise ValueError(f"expected (..., 3) RGB depth image, got shape {a.shape}")
    r, g, b = (a[..., i].astype(np.float64) for i in range(3))
    return (DEPTH_MAX_M * (r + 256.0 * g + 65536.0 * b) / _DEPTH_SCALE).astype(np.float32)


def colorize_semantic(tags: np.ndarray) -> np.ndarray:
    """Tag ids ``(H, W)`` → Cityscapes RGB ``(H, W, 3)`` uint8 (ids wrap modulo the palette, as in CARLA)."""
    t = np.asarray(tags)
    return CITYSCAPES_PALETTE[t.astype(np.int64) % len(CITYSCAPES_PALETTE)]


def semantic_to_carla_rgb(tags: np.ndarray) -> np.ndarray:
    """Tag ids → the raw CARLA semantic image layout as RGB: tag in the red channel, zeros elsewhere."""
    t = np.asarray(tags, dtype=np.uint8)
    out = np.zeros(t.shape + (3,), dtype=np.uint8)
    out[..., 0] = t
    return out


def colorize_depth(depth_m: np.ndarray, max_m: float = 100.0) -> np.ndarray:
    """A logarithmic grey visualisation of depth (near = white), uint8 RGB, for humans only."""
    d = np.clip(np.asarray(depth_m, dtype=np.float64), 0.5, max_m)
    g = 255.0 * (1.0 - np.log(d / 0.5) / np.log(max_m / 0.5))
    g = g.astype(np.uint8)
    return np.repeat(g[..., None], 3, axis=-1)

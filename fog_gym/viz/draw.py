"""Pictures for people: camera contact sheets, LiDAR panels, fog-level strips, exposure previews (OpenCV).

Example:
    >>> import numpy as np
    >>> sheet = contact_sheet({"CAM_FRONT": [np.zeros((4, 6, 3), np.uint8)]}, tile_width=6)
    >>> sheet.shape[2]
    3
"""

from __future__ import annotations

import cv2
import numpy as np

from fog_gym.render.birds_eye import fit_width


def exposure_preview(rgb: np.ndarray, target: float = 0.8, percentile: float = 99.0) -> tuple[np.ndarray, float]:
    """A display copy of a (dark) image scaled so its ``percentile`` luminance sits at ``target``; returns (image, gain).

    The gain is never below 1. fog-gym's night frames are auto-exposed by the renderer
    (:mod:`fog_gym.render.lights`), so on them this is (close to) a no-op; it remains for other dark images.

    >>> img, gain = exposure_preview(np.full((2, 2, 3), 20, np.uint8))
    >>> int(img[0, 0, 0]), round(gain, 1)
    (204, 10.2)
    """
    lum = rgb.astype(np.float32) @ np.array([0.2126, 0.7152, 0.0722], np.float32)
    level = float(np.percentile(lum, percentile))
    gain = max(1.0, target * 255.0 / max(level, 1.0))
    return np.clip(rgb.astype(np.float32) * gain, 0, 255).astype(np.uint8), gain


def _caption(img: np.ndarray, text: str, y: int, x: int = 6) -> None:
    cv2.putText(img, text, (x, y), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 3, cv2.LINE_AA)
    cv2.putText(img, text, (x, y), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 255, 255), 1, cv2.LINE_AA)


def contact_sheet(
    rows: dict[str, list[np.ndarray]], tile_width: int = 320, label: bool = True, captions: list[str] | None = None
) -> np.ndarray:
    """A grid of images: one row per key, tiles scaled to ``tile_width``; each row's tiles share its height.

    Each row is labelled with its key on the first tile; ``captions`` (one per column) label every tile.
    """
    tiles = [[fit_width(t if t.ndim == 3 else np.repeat(t[..., None], 3, -1), tile_width) for t in row] for row in rows.values()]
    heights = [max(t.shape[0] for t in row) for row in tiles]
    ncol = max(len(r) for r in tiles)
    sheet = np.full((sum(heights), tile_width * ncol, 3), 255, np.uint8)
    top = 0
    for name, row, h in zip(rows, tiles, heights):
        for col, t in enumerate(row):
            sheet[top : top + t.shape[0], col * tile_width : col * tile_width + t.shape[1]] = t
            if captions is not None and col < len(captions):
                _caption(sheet, captions[col], top + h - 10, col * tile_width + 6)
        if label:
            _caption(sheet, name, top + 18)
        top += h
    return sheet


def points_bev(points: np.ndarray, colors: np.ndarray, metres: float = 120.0, size_px: int = 720) -> np.ndarray:
    """Top-down image of sensor-frame points (+x up, +y right), ``metres`` across, on a dark canvas."""
    img = np.full((size_px, size_px, 3), 40, np.uint8)
    scale = size_px / metres
    for r in range(20, int(metres / 2) + 1, 20):  # range rings every 20 m
        cv2.circle(img, (size_px // 2, size_px // 2), int(r * scale), (60, 60, 60), 1, cv2.LINE_AA)
    if len(points):
        order = np.argsort(-np.hypot(points[:, 0], points[:, 1]))
        points, colors = points[order], np.asarray(colors)[order]
        col = np.round(points[:, 1] * scale + size_px / 2).astype(np.int64)
        row = np.round(-points[:, 0] * scale + size_px / 2).astype(np.int64)
        for dr, dc in ((0, 0), (0, 1), (1, 0), (1, 1)):  # 2×2 dots, far points drawn first, near on top
            r, c = row + dr, col + dc
            ok = (c >= 0) & (c < size_px) & (r >= 0) & (r < size_px)
            img[r[ok], c[ok]] = colors[ok]
    cv2.drawMarker(img, (size_px // 2, size_px // 2), (255, 255, 255), cv2.MARKER_TRIANGLE_UP, 10, 2)
    return img


def lidar_panels(lidar: np.ndarray | None, semantic: np.ndarray | None, metres: float = 120.0) -> np.ndarray:
    """LiDAR coloured by intensity beside semantic LiDAR coloured by tag (Cityscapes palette), top-down."""
    from fog_gym.encoding import colorize_semantic

    panels = []
    if lidar is not None:
        grey = (np.clip(lidar[:, 3], 0, 1) * 255).astype(np.uint8)
        panels.append(points_bev(lidar, cv2.applyColorMap(grey[:, None], cv2.COLORMAP_VIRIDIS)[:, 0, ::-1], metres))
    if semantic is not None:
        panels.append(points_bev(semantic, colorize_semantic(semantic[:, 5].astype(np.int64)), metres))
    return np.concatenate(panels, axis=1) if panels else np.zeros((1, 1, 3), np.uint8)


def night_fog_levels(
    day: dict[str, np.ndarray] | None, night: dict[str, np.ndarray], tile_width: int = 480, zoom: float = 3.0
) -> np.ndarray:
    """The night fog-levels picture: one column per fog level (``{caption: front image}``, clear first).

    Rows: the day images (when given, for comparison), the night images, and the night images magnified
    ``zoom``× around the brightest source of the clear night frame (a lamp or headlights), where the glow of
    lit fog shows. Night frames are auto-exposed by the renderer, so nothing is brightened here.

    >>> img = np.zeros((40, 60, 3), np.uint8); img[10, 30] = 255
    >>> night_fog_levels(None, {"clear": img, "dense": img}, tile_width=60).shape
    (80, 120, 3)
    """
    names = list(night)
    first = night[names[0]]
    lum = first.astype(np.float32) @ np.array([0.2126, 0.7152, 0.0722], np.float32)
    lum = cv2.GaussianBlur(lum, (0, 0), 2.0)
    cy, cx = np.unravel_index(int(np.argmax(lum)), lum.shape)
    h, w = first.shape[:2]
    ch, cw = max(2, int(h / zoom)), max(2, int(w / zoom))
    y0, x0 = int(np.clip(cy - ch // 2, 0, h - ch)), int(np.clip(cx - cw // 2, 0, w - cw))
    rows: dict[str, list[np.ndarray]] = {}
    if day is not None:
        rows["day"] = [day[n] for n in names if n in day]
    rows["night"] = [night[n] for n in names]
    rows[f"night, {zoom:g}x around the brightest source"] = [
        cv2.resize(night[n][y0 : y0 + ch, x0 : x0 + cw], (w, h), interpolation=cv2.INTER_NEAREST) for n in names
    ]
    return contact_sheet(rows, tile_width=tile_width, captions=names)

"""Figures that explain themselves (matplotlib): what ``fog-gym demo`` and the docs' sensor figures show.

Every figure has a title and labelled panels; every colour-coded quantity has its key: a colour bar for LiDAR
intensity and depth (with units), a legend naming the semantic classes a figure shows; top-down views carry range
rings with their distances and metre axes. The pictures are the sensors' own arrays (nothing is retouched); night
frames are shown as the renderer auto-exposed them.

Example:
    >>> import numpy as np
    >>> rgb = np.zeros((24, 32, 3), np.uint8)
    >>> fig = cameras_figure({"CAM_FRONT": (rgb, np.full((24, 32), 20.0, np.float32), np.ones((24, 32), np.uint8))},
    ...                      "cameras")
    >>> [ax.get_title() for ax in fig.axes[:3]]
    ['RGB', 'depth', 'semantic tags']
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only; no display needed  # noqa: E402

import cv2  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.colors import ListedColormap, LogNorm, Normalize  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402

from fog_gym.encoding import CITYSCAPES_PALETTE, TAG_NAMES  # noqa: E402

#: Depth shown from 0.5 m to 100 m on a log scale (near = light); farther (sky: 1000 m) is the darkest colour.
DEPTH_RANGE_M = (0.5, 100.0)
INTENSITY_CMAP = "viridis"
DEPTH_CMAP = "magma"
DPI = 100


def points_bev(points: np.ndarray, colors: np.ndarray, metres: float = 120.0, size_px: int = 720,
               rings: bool = True) -> np.ndarray:  # fmt: skip
    """Top-down image of sensor-frame points (+x up, +y right), ``metres`` across, on a dark canvas; ``rings``: range
    rings every 20 m (figures with metre axes draw labelled ones instead, :mod:`fog_gym.viz.figures`)."""
    img = np.full((size_px, size_px, 3), 40, np.uint8)
    scale = size_px / metres
    for r in range(20, int(metres / 2) + 1, 20) if rings else ():  # range rings every 20 m
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


def save(fig, path: str | Path) -> Path:
    """Write ``fig`` as a PNG at ``path`` atomically (a temporary file renamed), then close it."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    fig.savefig(tmp, dpi=DPI, format="png")
    plt.close(fig)
    tmp.replace(path)
    return path


def _image(ax, img: np.ndarray, title: str | None = None) -> None:
    ax.imshow(img, interpolation="antialiased")
    ax.set_xticks([])
    ax.set_yticks([])
    if title is not None:
        ax.set_title(title, fontsize=10)


def _semantic_legend(fig, tags: np.ndarray, loc: str = "lower center", ncol: int = 8) -> None:
    """A legend of the semantic classes present in ``tags``: colour, name and CARLA tag id."""
    present = [int(t) for t in np.unique(np.asarray(tags).astype(np.int64))]
    handles = [Patch(facecolor=CITYSCAPES_PALETTE[t % len(CITYSCAPES_PALETTE)] / 255.0, edgecolor="0.3",
                     label=f"{t} {TAG_NAMES.get(t, '?')}") for t in present]  # fmt: skip
    fig.legend(handles=handles, loc=loc, ncol=min(ncol, len(handles)), fontsize=8, frameon=False,
               title="semantic classes (CARLA tag id, name)", title_fontsize=8)  # fmt: skip


def _bev(ax, points: np.ndarray | None, colors: np.ndarray | None, metres: float, title: str | None = None,
         ring_step: float = 20.0) -> None:  # fmt: skip
    """Sensor-frame points from above on ``ax`` in metres: +x (forward) up, +y (right) to the right, the sensor at the
    origin, range rings every ``ring_step`` metres labelled with their distance."""
    size = 720
    pts = np.zeros((0, 3)) if points is None else points
    cols = np.zeros((0, 3), np.uint8) if colors is None else colors
    img = points_bev(pts, cols, metres, size, rings=False)
    half = metres / 2
    ax.imshow(img, extent=(-half, half, -half, half), interpolation="nearest")
    for r in np.arange(ring_step, half + 1e-9, ring_step):
        ax.add_patch(plt.Circle((0, 0), r, fill=False, color="0.75", lw=0.6, ls="--"))
        a = np.radians(40.0)
        ax.text(r * np.sin(a), r * np.cos(a), f"{r:g} m", color="0.9", fontsize=7, ha="left", va="bottom")
    ax.set_xlim(-half, half)
    ax.set_ylim(-half, half)
    ax.set_xlabel("y, right [m]", fontsize=8)
    ax.set_ylabel("x, forward [m]", fontsize=8)
    ax.tick_params(labelsize=7)
    if title is not None:
        ax.set_title(title, fontsize=10)


def intensity_colors(intensity: np.ndarray) -> np.ndarray:
    """LiDAR intensity in [0, 1] → RGB uint8 on :data:`INTENSITY_CMAP` (the colour bar's mapping)."""
    cmap = matplotlib.colormaps[INTENSITY_CMAP]
    return (cmap(np.clip(intensity, 0.0, 1.0))[:, :3] * 255).astype(np.uint8)


def _intensity_bar(fig, axes, label: str = "LiDAR intensity (CARLA: exp(−0.004 · d))") -> None:
    sm = plt.cm.ScalarMappable(norm=Normalize(0.0, 1.0), cmap=INTENSITY_CMAP)
    bar = fig.colorbar(sm, ax=axes, fraction=0.025, pad=0.01)
    bar.set_label(label, fontsize=8)
    bar.ax.tick_params(labelsize=7)


def fog_levels_figure(columns: dict[str, dict[str, np.ndarray]], title: str, metres: float = 100.0,
                      zoom_row: bool = False) -> plt.Figure:  # fmt: skip
    """One column per fog level (``{"clear": {"rgb": …, "lidar": (N, 4)}, "light (160 m)": …}``): the front camera
    and the LiDAR from above (each fogged panel counts the points the fog moved: returns from the fog itself), a
    colour bar for the LiDAR's intensity. ``zoom_row`` (night) adds the camera magnified
    3× around the clear frame's brightest light, where the glow of lit fog shows."""
    names = list(columns)
    first = columns[names[0]]["rgb"]
    h, w = first.shape[:2]
    rows = ["rgb", "zoom", "lidar"] if zoom_row else ["rgb", "lidar"]
    panel_w = 3.2
    heights = [panel_w * h / w if r != "lidar" else panel_w for r in rows]
    fig, axes = plt.subplots(len(rows), len(names), figsize=(panel_w * len(names) + 1.4, sum(heights) + 1.0),
                             gridspec_kw={"height_ratios": heights}, squeeze=False, layout="constrained")  # fmt: skip
    y0 = x0 = 0
    ch, cw = h, w
    if zoom_row:
        ch, cw = max(2, h // 3), max(2, w // 3)
        lum = first.astype(np.float32) @ np.array([0.2126, 0.7152, 0.0722], np.float32)
        cy, cx = np.unravel_index(int(np.argmax(lum)), lum.shape)
        y0, x0 = int(np.clip(cy - ch // 2, 0, h - ch)), int(np.clip(cx - cw // 2, 0, w - cw))
    for col, name in enumerate(names):
        data = columns[name]
        for row, kind in enumerate(rows):
            ax = axes[row, col]
            if kind == "rgb":
                _image(ax, data["rgb"], name)
            elif kind == "zoom":
                _image(ax, data["rgb"][y0 : y0 + ch, x0 : x0 + cw])
            else:
                pts = data.get("lidar")
                colors = None if pts is None else intensity_colors(pts[:, 3])
                clear = columns[names[0]].get("lidar")
                moved = ""
                if col and pts is not None and clear is not None and len(clear) == len(pts):
                    moved = f", {int(np.any(pts[:, :3] != clear[:, :3], axis=1).sum()):,} fog returns"
                _bev(ax, pts, colors, metres, f"{0 if pts is None else len(pts):,} points{moved}")
            if col == 0:
                label = {"rgb": "CAM_FRONT (RGB)", "zoom": "CAM_FRONT, 3× around\nthe brightest light",
                         "lidar": "LIDAR_TOP from above"}[kind]  # fmt: skip
                if kind == "lidar":
                    ax.set_ylabel(f"{label}\nx, forward [m]", fontsize=9)
                else:
                    ax.set_ylabel(label, fontsize=9)
    _intensity_bar(fig, axes[-1, :].tolist())
    fig.suptitle(title, fontsize=12)
    return fig


def cameras_figure(rows: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]], title: str) -> plt.Figure:
    """Every camera (rows) as RGB, planar depth (log colour scale in metres, with its bar) and semantic tags (with a
    legend of the classes shown)."""
    names = list(rows)
    h, w = rows[names[0]][0].shape[:2]
    panel_w = 3.6
    fig, axes = plt.subplots(len(names), 3, figsize=(3 * panel_w + 1.6, len(names) * panel_w * h / w + 1.8),
                             squeeze=False, layout="constrained")  # fmt: skip
    norm = LogNorm(*DEPTH_RANGE_M, clip=True)
    tags = []
    depth_im = None
    for r, name in enumerate(names):
        rgb, depth, sem = rows[name]
        _image(axes[r, 0], rgb, "RGB" if r == 0 else None)
        depth_im = axes[r, 1].imshow(np.clip(depth, *DEPTH_RANGE_M), cmap=f"{DEPTH_CMAP}_r", norm=norm,
                                     interpolation="antialiased")  # fmt: skip
        axes[r, 1].set_xticks([])
        axes[r, 1].set_yticks([])
        if r == 0:
            axes[r, 1].set_title("depth", fontsize=10)
        palette = ListedColormap(CITYSCAPES_PALETTE / 255.0)
        axes[r, 2].imshow(np.asarray(sem) % len(CITYSCAPES_PALETTE), cmap=palette, vmin=0,
                          vmax=len(CITYSCAPES_PALETTE) - 1, interpolation="nearest")  # fmt: skip
        axes[r, 2].set_xticks([])
        axes[r, 2].set_yticks([])
        if r == 0:
            axes[r, 2].set_title("semantic tags", fontsize=10)
        axes[r, 0].set_ylabel(name, fontsize=10)
        tags.append(np.unique(sem))
    bar = fig.colorbar(depth_im, ax=axes[:, 1].tolist(), fraction=0.05, pad=0.01, location="bottom")
    bar.set_label(f"planar depth [m], log scale ({DEPTH_RANGE_M[0]:g}–{DEPTH_RANGE_M[1]:g} m; sky is 1000 m)", fontsize=8)
    bar.set_ticks([0.5, 1, 2, 5, 10, 20, 50, 100], labels=["0.5", "1", "2", "5", "10", "20", "50", "100"])
    bar.ax.tick_params(labelsize=7)
    _semantic_legend(fig, np.concatenate(tags), loc="outside lower center", ncol=6)
    fig.suptitle(title, fontsize=12)
    return fig


def lidar_figure(lidar: np.ndarray | None, semantic: np.ndarray | None, title: str, metres: float = 120.0) -> plt.Figure:
    """One LiDAR sweep from above: the LiDAR coloured by intensity (with its bar) beside the semantic LiDAR coloured by
    class (with a legend), range rings with distances."""
    fig, axes = plt.subplots(1, 2, figsize=(11.5, 6.6), layout="constrained")
    colors = None if lidar is None else intensity_colors(lidar[:, 3])
    _bev(axes[0], lidar, colors, metres, f"LIDAR_TOP: {0 if lidar is None else len(lidar):,} points by intensity")
    _intensity_bar(fig, axes[0])
    tags = np.zeros(0, np.int64) if semantic is None else semantic[:, 5].astype(np.int64)
    sem_colors = CITYSCAPES_PALETTE[tags % len(CITYSCAPES_PALETTE)]
    _bev(axes[1], semantic, sem_colors, metres, f"SEM_LIDAR_TOP: {len(tags):,} points by class")
    if len(tags):
        _semantic_legend(fig, tags, loc="outside lower center", ncol=7)
    fig.suptitle(title, fontsize=12)
    return fig


def render_figure(frame: np.ndarray, title: str, metres: float = 100.0) -> plt.Figure:
    """``env.render()``'s frame: the front camera (left) beside the bird's-eye view (right, ``metres`` across, the ego
    red, other vehicles blue), each panel labelled, the bird's-eye view with metre axes."""
    h, total = frame.shape[:2]
    front_w = total - h
    fig, axes = plt.subplots(1, 2, figsize=(4.2 * front_w / h + 4.6, 5.4), layout="constrained",
                             gridspec_kw={"width_ratios": [front_w / h, 1.0]})  # fmt: skip
    _image(axes[0], frame[:, :front_w], "CAM_FRONT")
    half = metres / 2
    axes[1].imshow(frame[:, front_w:], extent=(-half, half, -half, half))
    axes[1].set_title(f"bird's-eye view, {metres:g} m across (ego red, vehicles blue)", fontsize=10)
    axes[1].set_xlabel("right of the ego [m]", fontsize=8)
    axes[1].set_ylabel("ahead of the ego [m]", fontsize=8)
    axes[1].tick_params(labelsize=7)
    fig.suptitle(title, fontsize=12)
    return fig


def night_levels_figure(day: dict[str, np.ndarray] | None, night: dict[str, np.ndarray], title: str,
                        zoom: float = 3.0) -> plt.Figure:  # fmt: skip
    """The front camera per fog level (columns, clear first): by day (when given), by night as the renderer exposed it,
    and by night magnified ``zoom``× around the clear night frame's brightest light, where the glow of lit fog shows."""
    names = list(night)
    first = night[names[0]]
    h, w = first.shape[:2]
    lum = first.astype(np.float32) @ np.array([0.2126, 0.7152, 0.0722], np.float32)
    cy, cx = np.unravel_index(int(np.argmax(lum)), lum.shape)
    ch, cw = max(2, int(h / zoom)), max(2, int(w / zoom))
    y0, x0 = int(np.clip(cy - ch // 2, 0, h - ch)), int(np.clip(cx - cw // 2, 0, w - cw))
    rows: dict[str, list[np.ndarray]] = {}
    if day is not None:
        rows["day"] = [day[n] for n in names]
    rows["night (auto-exposed)"] = [night[n] for n in names]
    rows[f"night, {zoom:g}× around\nthe brightest light"] = [night[n][y0 : y0 + ch, x0 : x0 + cw] for n in names]
    panel_w = 3.2
    fig, axes = plt.subplots(len(rows), len(names), figsize=(panel_w * len(names) + 0.8, len(rows) * panel_w * h / w + 0.9),
                             squeeze=False, layout="constrained")  # fmt: skip
    for r, (label, imgs) in enumerate(rows.items()):
        for c, img in enumerate(imgs):
            _image(axes[r, c], img, names[c] if r == 0 else None)
        axes[r, 0].set_ylabel(label, fontsize=9)
    fig.suptitle(title, fontsize=12)
    return fig

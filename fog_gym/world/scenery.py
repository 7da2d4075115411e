"""Road surface map and roadside scenery from sampled lane geometry (pure numpy + OpenCV).

Input is a list of :class:`LaneGeometry` (lane centre and both boundaries sampled along the lane, with
highway-env's line types); nothing here imports highway-env.

Surface classes (values of the map): 0 terrain, 1 road, 2 sidewalk/shoulder, 3 lane marking.

Example:
    >>> import numpy as np
    >>> x = np.arange(0.0, 50.0)
    >>> lane = LaneGeometry.straight((0, 0), (50, 0), width=4.0, line_types=(2, 2))
    >>> surf = build_surface([lane], resolution=0.5)
    >>> int(surf.class_at(25.0, 0.0)), int(surf.class_at(25.0, 30.0))
    (1, 0)
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

TERRAIN, ROAD, SIDEWALK, MARKING = 0, 1, 2, 3
#: Semantic tag (CARLA ≥ 0.9.14) of each surface class.
SURFACE_TAGS = np.array([10, 1, 2, 24], dtype=np.uint8)
#: LiDAR reflectivity of each surface class (near infrared): grass, asphalt, pavement, retroreflective lane paint.
SURFACE_REFLECTIVITY = np.array([0.30, 0.12, 0.25, 0.75])
#: Day albedo (0–255) of each surface class.
SURFACE_RGB = np.array([[96, 118, 68], [82, 82, 86], [150, 146, 140], [225, 225, 220]], dtype=np.float64)

STRIPED, CONTINUOUS, CONTINUOUS_LINE = 1, 2, 3  # highway-env LineType values
STRIPE_PERIOD, STRIPE_LENGTH = 4.33, 3.0  # highway-env LaneGraphics stripe layout [m]
MARKING_WIDTH = 0.15
SIDEWALK_WIDTH = 2.5


@dataclass(frozen=True)
class LaneGeometry:
    """One lane sampled along its length: ``s`` (S,), centre/left/right boundary points (S, 2).

    ``line_types`` = (left, right) as highway-env's ``LineType`` values.
    """

    s: np.ndarray
    center: np.ndarray
    left: np.ndarray
    right: np.ndarray
    line_types: tuple[int, int]

    @classmethod
    def straight(cls, start, end, width: float = 4.0, line_types=(1, 0), step: float = 1.0) -> LaneGeometry:
        start, end = np.asarray(start, float), np.asarray(end, float)
        length = float(np.linalg.norm(end - start))
        s = np.linspace(0.0, length, max(2, int(np.ceil(length / step)) + 1))
        d = (end - start) / length
        n = np.array([-d[1], d[0]])  # +r is to the driver's right (+y for an eastbound lane)
        c = start + s[:, None] * d
        return cls(s, c, c - n * width / 2, c + n * width / 2, tuple(line_types))

    @property
    def heading(self) -> np.ndarray:
        d = np.gradient(self.center, axis=0)
        return np.arctan2(d[:, 1], d[:, 0])


@dataclass(frozen=True)
class SurfaceMap:
    """Row-major class grid: row = world y, column = world x, cell (0, 0) corner at ``origin``."""

    grid: np.ndarray
    origin: tuple[float, float]
    resolution: float

    def class_at(self, x: float | np.ndarray, y: float | np.ndarray) -> np.ndarray:
        col = np.floor((np.asarray(x) - self.origin[0]) / self.resolution).astype(np.int64)
        row = np.floor((np.asarray(y) - self.origin[1]) / self.resolution).astype(np.int64)
        inside = (row >= 0) & (col >= 0) & (row < self.grid.shape[0]) & (col < self.grid.shape[1])
        out = np.zeros(np.shape(col), np.uint8)
        out[inside] = self.grid[row[inside], col[inside]]
        return out

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """(x_min, x_max, y_min, y_max) in metres."""
        h, w = self.grid.shape
        x0, y0 = self.origin
        return (x0, x0 + w * self.resolution, y0, y0 + h * self.resolution)


def _to_px(points: np.ndarray, origin, resolution: float, shift: int) -> np.ndarray:
    return np.round((points - np.asarray(origin)) / resolution * (1 << shift)).astype(np.int32)


def build_surface(lanes: list[LaneGeometry], resolution: float = 0.1, margin: float = 60.0) -> SurfaceMap:
    """Rasterise lanes (road), a sidewalk/shoulder band around them, and lane markings into a class grid."""
    if not lanes:
        raise ValueError("build_surface needs at least one lane")
    pts = np.concatenate([np.concatenate([ln.left, ln.right]) for ln in lanes])
    lo = pts.min(axis=0) - margin
    hi = pts.max(axis=0) + margin
    shape = (int(np.ceil((hi[1] - lo[1]) / resolution)), int(np.ceil((hi[0] - lo[0]) / resolution)))
    grid = np.zeros(shape, np.uint8)
    shift = 4
    origin = (float(lo[0]), float(lo[1]))

    def ribbon(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return _to_px(np.concatenate([a, b[::-1]]), origin, resolution, shift)

    # sidewalk band first, then road on top, then markings
    for ln in lanes:
        n = ln.right - ln.center
        width = np.linalg.norm(n, axis=1, keepdims=True)
        unit = n / np.maximum(width, 1e-9)
        outer_l = ln.left - unit * SIDEWALK_WIDTH
        outer_r = ln.right + unit * SIDEWALK_WIDTH
        cv2.fillPoly(grid, [ribbon(outer_l, outer_r)], SIDEWALK, lineType=cv2.LINE_8, shift=shift)
    for ln in lanes:
        cv2.fillPoly(grid, [ribbon(ln.left, ln.right)], ROAD, lineType=cv2.LINE_8, shift=shift)
    thickness = max(1, int(round(MARKING_WIDTH / resolution)))
    for ln in lanes:
        for side, kind in zip((ln.left, ln.right), ln.line_types):
            if kind in (CONTINUOUS, CONTINUOUS_LINE):
                cv2.polylines(grid, [_to_px(side, origin, resolution, shift)], False, MARKING, thickness, cv2.LINE_8, shift)
            elif kind == STRIPED:
                phase = np.mod(ln.s, STRIPE_PERIOD) < STRIPE_LENGTH
                edges = np.flatnonzero(np.diff(np.r_[0, phase.astype(np.int8), 0]))
                for a, b in zip(edges[::2], edges[1::2]):
                    if b - a >= 2:
                        seg = _to_px(side[a:b], origin, resolution, shift)
                        cv2.polylines(grid, [seg], False, MARKING, thickness, cv2.LINE_8, shift)
    return SurfaceMap(grid, origin, float(resolution))


@dataclass(frozen=True)
class Props:
    """Static roadside boxes: centres (P, 3), sizes (P, 3) = (l, w, h), yaws (P,), albedo (P, 3) in [0, 1], tags (P,)."""

    centers: np.ndarray
    sizes: np.ndarray
    yaws: np.ndarray
    colors: np.ndarray
    tags: np.ndarray

    @classmethod
    def empty(cls) -> Props:
        z = np.zeros((0, 3))
        return cls(z, z.copy(), np.zeros(0), z.copy(), np.zeros(0, np.uint8))

    def __len__(self) -> int:
        return len(self.yaws)


@dataclass(frozen=True)
class SceneryStyle:
    """How a town dresses its roadside. Offsets are metres beyond the outer road edge.

    Street-light poles stand every ``pole_spacing`` metres along each outer road edge and are ``pole_height``
    tall; the lamp hangs at the pole's top (:func:`lamp_heads`). Real roads light with 8–10 m mounting heights
    and 25–40 m spacing (e.g. EN 13201 / IES RP-8 layouts), and so do the styles.
    """

    guard_rails: bool = True
    building_offset: tuple[float, float] = (16.0, 30.0)
    building_spacing: tuple[float, float] = (14.0, 30.0)
    building_height: tuple[float, float] = (6.0, 24.0)
    tree_offset: tuple[float, float] = (5.0, 12.0)
    tree_spacing: tuple[float, float] = (7.0, 16.0)
    pole_spacing: float = 36.0
    pole_height: float = 10.0

    def __post_init__(self) -> None:
        if not (self.pole_spacing > 0 and self.pole_height > 0):
            raise ValueError(f"pole_spacing and pole_height must be > 0, got {self.pole_spacing}, {self.pole_height}")


STYLES: dict[str, SceneryStyle] = {
    "freeway": SceneryStyle(),
    "urban": SceneryStyle(guard_rails=False, building_offset=(5.0, 12.0), building_spacing=(10.0, 20.0),
                          building_height=(8.0, 30.0), tree_offset=(3.2, 4.5), tree_spacing=(10.0, 18.0),
                          pole_spacing=28.0, pole_height=8.0),
    "circuit": SceneryStyle(building_offset=(25.0, 40.0), building_spacing=(40.0, 80.0),
                            building_height=(5.0, 12.0), tree_offset=(6.0, 15.0), tree_spacing=(6.0, 12.0),
                            pole_spacing=32.0, pole_height=9.0),
}  # fmt: skip

_BUILDING_COLORS = np.array([[0.55, 0.50, 0.45], [0.62, 0.60, 0.58], [0.45, 0.40, 0.38], [0.70, 0.66, 0.55],
                             [0.40, 0.42, 0.46], [0.58, 0.45, 0.36]])  # fmt: skip


class _Placer:
    """Coarse occupancy + distance-to-road grid used to keep props off the road and apart."""

    def __init__(self, surface: SurfaceMap, cell: float = 0.5) -> None:
        factor = max(1, int(round(cell / surface.resolution)))
        coarse = surface.grid[factor // 2 :: factor, factor // 2 :: factor]  # nearest sample is enough here
        paved = coarse != TERRAIN
        road = (coarse == ROAD) | (coarse == MARKING)
        h, w = coarse.shape
        self.cell = surface.resolution * factor
        self.origin = surface.origin
        self.dist_paved = cv2.distanceTransform((~paved).astype(np.uint8), cv2.DIST_L2, 5) * self.cell
        self.dist_road = cv2.distanceTransform((~road).astype(np.uint8), cv2.DIST_L2, 5) * self.cell
        self.occupied = np.zeros((h, w), np.uint8)

    def _footprint(self, x, y, length, width, yaw, pad):
        c, s = np.cos(yaw), np.sin(yaw)
        hl, hw = length / 2 + pad, width / 2 + pad
        corners = np.array([[hl, hw], [hl, -hw], [-hl, -hw], [-hl, hw]])
        world = np.c_[x + corners[:, 0] * c - corners[:, 1] * s, y + corners[:, 0] * s + corners[:, 1] * c]
        return np.round((world - np.asarray(self.origin)) / self.cell).astype(np.int32)

    def try_place(self, x, y, length, width, yaw, min_paved_dist, min_road_dist=0.0, pad=0.5) -> bool:
        poly = self._footprint(x, y, length, width, yaw, pad)
        h, w = self.occupied.shape
        if poly.min() < 0 or poly[:, 0].max() >= w or poly[:, 1].max() >= h:
            return False
        (c0, r0), (c1, r1) = poly.min(axis=0), poly.max(axis=0) + 1
        mask = np.zeros((r1 - r0, c1 - c0), np.uint8)
        cv2.fillConvexPoly(mask, poly - [c0, r0], 1)
        sel = mask.astype(bool)
        window = (slice(r0, r1), slice(c0, c1))
        if not sel.any() or self.occupied[window][sel].any():
            return False
        if self.dist_paved[window][sel].min() < min_paved_dist or self.dist_road[window][sel].min() < min_road_dist:
            return False
        cv2.fillConvexPoly(self.occupied, self._footprint(x, y, length, width, yaw, 0.0), 1)
        return True


def _outer_edges(lanes: list[LaneGeometry], surface: SurfaceMap):
    """Yield (points, outward unit normals, headings, s) for each lane side that borders no other road."""
    for ln in lanes:
        n = ln.right - ln.center
        unit = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-9)
        heading = ln.heading
        for side, sign in ((ln.left, -1.0), (ln.right, 1.0)):
            probe = side + sign * unit * 1.0
            outside = surface.class_at(probe[:, 0], probe[:, 1]) != ROAD
            outside &= surface.class_at(probe[:, 0], probe[:, 1]) != MARKING
            if outside.mean() > 0.2:
                yield side, sign * unit, heading, ln.s, outside


def lit_edge_length(lanes: list[LaneGeometry], surface: SurfaceMap) -> float:
    """Length [m] of the outer road edges that the street-light poles line (lane sides bordering no other road).

    >>> lane = LaneGeometry.straight((0, 0), (100, 0), width=4.0, line_types=(2, 2))
    >>> round(lit_edge_length([lane], build_surface([lane], resolution=0.5)))
    200
    """
    total = 0.0
    for side, _, _, _, outside in _outer_edges(lanes, surface):
        seg = np.linalg.norm(np.diff(side, axis=0), axis=1)
        total += float(seg[outside[:-1] & outside[1:]].sum())
    return total


#: Street-lamp heads: on top of each pole (tag 6, the style's ``pole_height``), on an arm reaching this far over
#: the road [m].
LAMP_ARM = 3.5
POLE_TAG = 6


def lamp_heads(props: Props, surface: SurfaceMap) -> np.ndarray:
    """Head positions (N, 3) of the street lamps on the roadside poles: at the pole's top, the arm towards the road.

    Poles stand :data:`SIDEWALK_WIDTH` + 0.6 m beyond the road edge, across the road's heading (their yaw); the
    arm points to whichever side has pavement within 3 m.

    >>> lane = LaneGeometry.straight((0, 0), (80, 0), width=4.0, line_types=(2, 2))
    >>> surf = build_surface([lane], resolution=0.5)
    >>> pole = Props(np.array([[40.0, 2 + SIDEWALK_WIDTH + 0.6, 3.5]]), np.array([[0.25, 0.25, 7.0]]),
    ...              np.zeros(1), np.full((1, 3), 0.45), np.array([POLE_TAG], np.uint8))
    >>> lamp_heads(pole, surf).round(2).tolist()
    [[40.0, 1.6, 7.0]]
    """
    poles = np.flatnonzero(props.tags == POLE_TAG)
    if poles.size == 0:
        return np.zeros((0, 3))
    c = props.centers[poles]
    side = np.c_[-np.sin(props.yaws[poles]), np.cos(props.yaws[poles])]  # left of the heading
    probe_l = surface.class_at(c[:, 0] + 3.0 * side[:, 0], c[:, 1] + 3.0 * side[:, 1]) != TERRAIN
    sign = np.where(probe_l, 1.0, -1.0)[:, None]
    top = c[:, 2] + props.sizes[poles, 2] / 2
    return np.c_[c[:, :2] + sign * LAMP_ARM * side, top]


def place_props(lanes: list[LaneGeometry], surface: SurfaceMap, rng: np.random.Generator, style: SceneryStyle) -> Props:
    """Line the outer road edges with guard rails, poles, trees and buildings, never on pavement or each other."""
    placer = _Placer(surface)
    out: list[tuple] = []  # (cx, cy, cz, l, w, h, yaw, r, g, b, tag)

    def add(x, y, z0, length, width, height, yaw, color, tag):
        out.append((x, y, z0 + height / 2, length, width, height, yaw, *color, tag))

    edges = list(_outer_edges(lanes, surface))
    # guard rails: continuous 6 m segments on the shoulder, 1.2 m beyond the edge
    if style.guard_rails:
        for side, normal, heading, s, outside in edges:
            step = max(1, int(round(6.0 / max(np.median(np.diff(s)), 1e-6))))
            for k in range(0, len(s) - step, step):
                if not (outside[k] and outside[k + step]):
                    continue
                a = side[k] + normal[k] * 1.2
                b = side[k + step] + normal[k + step] * 1.2
                mid = (a + b) / 2
                length = float(np.linalg.norm(b - a))
                yaw = float(np.arctan2(b[1] - a[1], b[0] - a[0]))
                if length > 0.5 and placer.dist_road[
                    int((mid[1] - placer.origin[1]) / placer.cell), int((mid[0] - placer.origin[0]) / placer.cell)
                ] >= 0.8:
                    add(mid[0], mid[1], 0.0, length, 0.3, 0.8, yaw, (0.62, 0.63, 0.65), 28)
    # poles at the sidewalk's outer edge
    for side, normal, heading, s, outside in edges:
        for s0 in np.arange(rng.uniform(0, style.pole_spacing), s[-1], style.pole_spacing):
            k = int(np.searchsorted(s, s0))
            if k >= len(s) or not outside[k]:
                continue
            p = side[k] + normal[k] * (SIDEWALK_WIDTH + 0.6)
            if placer.try_place(p[0], p[1], 0.25, 0.25, heading[k], min_paved_dist=0.0, min_road_dist=2.0, pad=0.2):
                add(p[0], p[1], 0.0, 0.25, 0.25, style.pole_height, heading[k], (0.45, 0.45, 0.47), POLE_TAG)
    # trees: trunk + canopy
    for side, normal, heading, s, outside in edges:
        s0 = rng.uniform(0, style.tree_spacing[1])
        while s0 < s[-1]:
            k = int(np.searchsorted(s, s0))
            s0 += rng.uniform(*style.tree_spacing)
            if k >= len(s) or not outside[k]:
                continue
            off = rng.uniform(*style.tree_offset)
            p = side[k] + normal[k] * off
            crown = rng.uniform(2.5, 4.5)
            trunk_h = rng.uniform(1.8, 3.0)
            if placer.try_place(p[0], p[1], crown, crown, heading[k], min_paved_dist=crown / 2 + 0.3, pad=0.3):
                yaw = rng.uniform(0, np.pi / 2)
                add(p[0], p[1], 0.0, 0.35, 0.35, trunk_h, yaw, (0.36, 0.26, 0.18), 9)
                green = np.array([0.20, 0.38, 0.14]) * rng.uniform(0.8, 1.2)
                add(p[0], p[1], trunk_h, crown, crown, crown * rng.uniform(0.9, 1.4), yaw, tuple(green), 9)
    # buildings
    for side, normal, heading, s, outside in edges:
        s0 = rng.uniform(0, style.building_spacing[1])
        while s0 < s[-1]:
            k = int(np.searchsorted(s, s0))
            length = rng.uniform(10.0, 24.0)
            s0 += length + rng.uniform(*style.building_spacing)
            if k >= len(s) or not outside[k]:
                continue
            depth = rng.uniform(8.0, 18.0)
            off = rng.uniform(*style.building_offset) + depth / 2
            p = side[k] + normal[k] * off
            if placer.try_place(p[0], p[1], length, depth, heading[k], min_paved_dist=2.0, pad=1.0):
                color = _BUILDING_COLORS[rng.integers(len(_BUILDING_COLORS))] * rng.uniform(0.85, 1.1)
                add(p[0], p[1], 0.0, length, depth, rng.uniform(*style.building_height), heading[k],
                    tuple(np.clip(color, 0, 1)), 3)  # fmt: skip
    if not out:
        return Props.empty()
    a = np.array(out, dtype=np.float64)
    return Props(a[:, 0:3].copy(), a[:, 3:6].copy(), a[:, 6].copy(), a[:, 7:10].copy(), a[:, 10].astype(np.uint8))

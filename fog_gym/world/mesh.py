"""Triangle meshes: the scene's primitive (vehicles, scenery, and boxes as one mesh kind), and their materials.

A :class:`Mesh` holds vertices in its own body frame (CARLA's axes: +x forward, +y right, +z up; the origin on the
ground under the centre), triangles as vertex-index triples and one material per triangle. A triangle's outward
normal is ``(v1 − v0) × (v2 − v0)`` as numpy computes the cross product. Meshes are built once per process (the
procedural vehicles of :mod:`fog_gym.world.bodies`, the scenery of :mod:`fog_gym.world.scenery`) and placed per frame
by pose (and a per-axis scale), never re-triangulated.

Materials (:data:`MATERIAL_NAMES` and the tables beside it) give each triangle an albedo (or a share of the instance's own colour: a car's
paint), a CARLA semantic tag (or the instance's: a car's parts are all "Car"), a LiDAR reflectivity in [0, 1], and
whether it emits light at night (head and tail lamps).

Pure numpy; imports nothing from the project but the checks.

Example:
    >>> m = box_mesh((4.0, 2.0, 1.5), BODY)
    >>> m.vertices.shape, m.triangles.shape, bool(is_closed(m))
    ((8, 3), (12, 3), True)
    >>> m.bounds().tolist()
    [[-2.0, -1.0, 0.0], [2.0, 1.0, 1.5]]
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Material fields: name → (albedo RGB in [0, 1], share of the instance colour mixed in, tag (255: the instance's),
#: LiDAR reflectivity, emits at night).
_MATERIAL_ROWS: dict[str, tuple[tuple[float, float, float], float, int, float, bool]] = {
    "paint": ((0.0, 0.0, 0.0), 1.0, 255, 0.30, False),
    "glass": ((0.10, 0.12, 0.15), 0.3, 255, 0.08, False),
    "tyre": ((0.06, 0.06, 0.06), 0.0, 255, 0.05, False),
    "trim": ((0.12, 0.12, 0.13), 0.0, 255, 0.10, False),
    "headlamp": ((0.85, 0.85, 0.82), 0.0, 255, 0.60, True),
    "taillamp": ((0.55, 0.05, 0.05), 0.0, 255, 0.60, True),
    "plate": ((0.90, 0.90, 0.86), 0.0, 255, 0.95, False),
    "cargo": ((0.85, 0.85, 0.82), 0.25, 255, 0.45, False),
    "bark": ((0.36, 0.26, 0.18), 0.0, 9, 0.20, False),
    "leaves": ((0.0, 0.0, 0.0), 1.0, 9, 0.35, False),
    "facade": ((0.0, 0.0, 0.0), 1.0, 3, 0.40, False),
    "window": ((0.16, 0.19, 0.24), 0.0, 3, 0.10, False),
    "roof": ((0.28, 0.27, 0.27), 0.0, 3, 0.25, False),
    "metal": ((0.45, 0.45, 0.47), 0.0, 6, 0.50, False),
    "rail": ((0.62, 0.63, 0.65), 0.0, 28, 0.60, False),
    "sign": ((0.85, 0.86, 0.88), 0.0, 8, 0.95, False),
    "sign_face": ((0.10, 0.38, 0.18), 0.0, 8, 0.95, False),
    "box": ((0.0, 0.0, 0.0), 1.0, 255, 0.30, False),
}
#: Material names in id order.
MATERIAL_NAMES: tuple[str, ...] = tuple(_MATERIAL_ROWS)
#: Material id of each name (a triangle's ``materials`` entry).
MATERIAL_IDS: dict[str, int] = {n: i for i, n in enumerate(MATERIAL_NAMES)}
#: Per material id: albedo (M, 3), instance-colour share (M,), tag (M,) uint8 (255: the instance's tag), LiDAR
#: reflectivity (M,), emissive at night (M,).
MATERIAL_ALBEDO = np.array([r[0] for r in _MATERIAL_ROWS.values()], np.float64)
MATERIAL_PAINT = np.array([r[1] for r in _MATERIAL_ROWS.values()], np.float64)
MATERIAL_TAG = np.array([r[2] for r in _MATERIAL_ROWS.values()], np.uint8)
MATERIAL_REFLECTIVITY = np.array([r[3] for r in _MATERIAL_ROWS.values()], np.float64)
MATERIAL_EMISSIVE = np.array([r[4] for r in _MATERIAL_ROWS.values()], np.bool_)
INSTANCE_TAG = 255
BODY, GLASS, TYRE, TRIM = (MATERIAL_IDS[n] for n in ("paint", "glass", "tyre", "trim"))
HEADLAMP, TAILLAMP, PLATE, CARGO = (MATERIAL_IDS[n] for n in ("headlamp", "taillamp", "plate", "cargo"))
BARK, LEAVES, FACADE, WINDOW, ROOF = (MATERIAL_IDS[n] for n in ("bark", "leaves", "facade", "window", "roof"))
METAL, RAIL, SIGN, SIGN_FACE, BOX = (MATERIAL_IDS[n] for n in ("metal", "rail", "sign", "sign_face", "box"))


@dataclass(frozen=True, eq=False)
class Mesh:
    """A triangle mesh in its body frame: ``vertices`` (V, 3) float64, ``triangles`` (T, 3) int32 (outward normal
    ``(v1 − v0) × (v2 − v0)``), ``materials`` (T,) uint8 ids into :data:`MATERIAL_NAMES`. Checked at construction:
    finite vertices, indices in range, no degenerate triangle, known materials (:meth:`check`)."""

    vertices: np.ndarray
    triangles: np.ndarray
    materials: np.ndarray

    def __post_init__(self) -> None:
        object.__setattr__(self, "vertices", np.ascontiguousarray(self.vertices, np.float64))
        object.__setattr__(self, "triangles", np.ascontiguousarray(self.triangles, np.int32))
        object.__setattr__(self, "materials", np.ascontiguousarray(self.materials, np.uint8))
        self.check()

    def check(self) -> None:
        """``ValueError`` naming the problem: vertices not (V, 3) or not finite, triangles not (T, 3) or indices out of
        range, a degenerate triangle (area below 1e-10 m²), materials not one per triangle or unknown."""
        v, t, m = self.vertices, self.triangles, self.materials
        if v.ndim != 2 or v.shape[1] != 3:
            raise ValueError(f"mesh vertices must be (V, 3), got shape {v.shape}")
        if not np.isfinite(v).all():
            bad = int(np.flatnonzero(~np.isfinite(v).all(axis=1))[0])
            raise ValueError(f"mesh vertices must be finite, vertex {bad} is {v[bad].tolist()}")
        if t.ndim != 2 or t.shape[1] != 3:
            raise ValueError(f"mesh triangles must be (T, 3) vertex indices, got shape {t.shape}")
        if t.size and (t.min() < 0 or t.max() >= len(v)):
            bad = int(np.flatnonzero((t < 0).any(axis=1) | (t >= len(v)).any(axis=1))[0])
            raise ValueError(f"mesh triangle {bad} has vertex indices {t[bad].tolist()} outside 0..{len(v) - 1}")
        area = triangle_areas(v, t)
        if (area < 1e-10).any():
            bad = int(np.flatnonzero(area < 1e-10)[0])
            raise ValueError(f"mesh triangle {bad} is degenerate (area {area[bad]:.3g} m²): {v[t[bad]].tolist()}")
        if m.shape != (len(t),):
            raise ValueError(f"mesh materials must be one per triangle ({len(t)}), got shape {m.shape}")
        if m.size and int(m.max()) >= len(MATERIAL_NAMES):
            raise ValueError(f"mesh material ids must be below {len(MATERIAL_NAMES)}, got {int(m.max())}")

    def __len__(self) -> int:
        return len(self.triangles)

    def bounds(self) -> np.ndarray:
        """``[[xmin, ymin, zmin], [xmax, ymax, zmax]]`` of the vertices."""
        return np.stack([self.vertices.min(axis=0), self.vertices.max(axis=0)])

    def normals(self) -> np.ndarray:
        """Unit outward normal of every triangle (T, 3)."""
        v, t = self.vertices, self.triangles
        n = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
        return n / np.linalg.norm(n, axis=1, keepdims=True)

    def transformed(self, scale=(1.0, 1.0, 1.0), offset=(0.0, 0.0, 0.0)) -> Mesh:
        """The mesh scaled per axis, then moved (same triangles and materials)."""
        return Mesh(self.vertices * np.asarray(scale, np.float64) + np.asarray(offset, np.float64), self.triangles,
                    self.materials)  # fmt: skip

    @staticmethod
    def join(*meshes: Mesh) -> Mesh:
        """One mesh of several (their triangles in order)."""
        offsets = np.cumsum([0] + [len(m.vertices) for m in meshes[:-1]])
        return Mesh(np.concatenate([m.vertices for m in meshes]),
                    np.concatenate([m.triangles + o for m, o in zip(meshes, offsets)]),
                    np.concatenate([m.materials for m in meshes]))  # fmt: skip


def triangle_areas(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Area of every triangle [m²]."""
    v = np.asarray(vertices, np.float64)
    t = np.asarray(triangles)
    if not len(t):
        return np.zeros(0)
    return 0.5 * np.linalg.norm(np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]]), axis=1)


def is_closed(mesh: Mesh) -> bool:
    """Whether every edge is shared by exactly two triangles that run along it in opposite directions (a closed,
    consistently oriented surface: a solid's boundary).

    >>> is_closed(box_mesh((1.0, 1.0, 1.0))), is_closed(Mesh(box_mesh((1, 1, 1)).vertices, box_mesh((1, 1, 1)).triangles[1:], box_mesh((1, 1, 1)).materials[1:]))
    (True, False)
    """
    t = mesh.triangles
    directed = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    keys = directed[:, 0].astype(np.int64) * (len(mesh.vertices) + 1) + directed[:, 1]
    rev = directed[:, 1].astype(np.int64) * (len(mesh.vertices) + 1) + directed[:, 0]
    if len(np.unique(keys)) != len(keys):  # an edge walked twice the same way: not oriented (or not manifold)
        return False
    return bool(np.isin(rev, keys).all())


def signed_volume(mesh: Mesh) -> float:
    """The enclosed volume [m³] (positive when the normals point outwards; meaningful for closed meshes)."""
    v, t = mesh.vertices, mesh.triangles
    return float(np.einsum("ij,ij->i", v[t[:, 0]], np.cross(v[t[:, 1]], v[t[:, 2]])).sum() / 6.0)


# -- building blocks (all closed, outward normals) ---------------------------------------------------------------
def box_mesh(size, material: int = BOX, center=(0.0, 0.0, None)) -> Mesh:
    """An upright box of ``size`` (length, width, height) standing on z = 0 (or centred at ``center``), 12 triangles.

    >>> bool(np.allclose(box_mesh((2, 2, 2)).normals()[:2], [[1, 0, 0], [1, 0, 0]]))
    True
    """
    L, W, H = (float(s) for s in size)
    cx, cy, cz = center
    cz = H / 2 if cz is None else cz
    sx = np.array([1, 1, -1, -1, 1, 1, -1, -1], np.float64)
    sy = np.array([1, -1, -1, 1, 1, -1, -1, 1], np.float64)
    sz = np.array([-1, -1, -1, -1, 1, 1, 1, 1], np.float64)
    v = np.c_[cx + sx * L / 2, cy + sy * W / 2, cz + sz * H / 2]
    quads = [(0, 4, 5, 1), (2, 6, 7, 3), (3, 7, 4, 0), (1, 5, 6, 2), (4, 7, 6, 5), (0, 1, 2, 3)]  # +x −x +y −y +z −z
    tris = _quads_to_tris(quads)
    return _outward(Mesh(v, tris, np.full(len(tris), material, np.uint8)))


def _quads_to_tris(quads) -> np.ndarray:
    return np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))], np.int32)


def _outward(mesh: Mesh) -> Mesh:
    """The mesh with every triangle turned to face away from the centroid of its vertices (for convex parts)."""
    v, t = mesh.vertices, mesh.triangles.copy()
    center = v.mean(axis=0)
    n = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
    inward = np.einsum("ij,ij->i", n, v[t].mean(axis=1) - center) < 0
    t[inward] = t[inward][:, [0, 2, 1]]
    return Mesh(v, t, mesh.materials)


def loft(stations: np.ndarray, profiles: list[np.ndarray], materials: np.ndarray, cap: int | None = None) -> Mesh:
    """A closed solid through cross-sections: ``profiles[k]`` (P, 2) is the (y, z) outline at x = ``stations[k]``,
    all with P points in the same angular order; neighbouring rings are joined by quads (``materials`` (K−1, P):
    the material of the quad from point j to j+1 between ring k and k+1) and both ends capped (material ``cap``,
    default the end quads' second material). Stations strictly increasing. Every side quad is wound alike and each
    cap faces out along ∓x, so the surface is consistently oriented; if that makes its volume negative the sides
    are turned, so the normals point outwards."""
    k, p = len(stations), len(profiles[0])
    v = np.concatenate([np.c_[np.full(p, x), prof] for x, prof in zip(stations, profiles)])
    tris, mats = [], []
    for i in range(k - 1):
        for j in range(p):
            a, b = i * p + j, i * p + (j + 1) % p
            c, d = (i + 1) * p + (j + 1) % p, (i + 1) * p + j
            tris += [(a, b, c), (a, c, d)]
            mats += [materials[i, j]] * 2
    n_sides = len(tris)
    for i, outward in ((0, -1.0), (k - 1, 1.0)):  # end caps: a fan from the ring's centroid, facing ∓x
        centre = len(v)
        v = np.concatenate([v, [[stations[i], *np.asarray(profiles[i]).mean(axis=0)]]])
        m = materials[min(i, k - 2), 1] if cap is None else cap
        for j in range(p):
            tri = (centre, i * p + j, i * p + (j + 1) % p)
            n_x = np.cross(v[tri[1]] - v[tri[0]], v[tri[2]] - v[tri[0]])[0]
            tris.append(tri if n_x * outward > 0 else (tri[0], tri[2], tri[1]))
            mats.append(m)
    t = np.array(tris, np.int32)
    if signed_volume(Mesh(v, t, np.array(mats, np.uint8))) < 0:  # the rings run the other way: turn the sides
        t[:n_sides] = t[:n_sides][:, [0, 2, 1]]
    return Mesh(v, t, np.array(mats, np.uint8))


def cylinder(radius: float, length: float, segments: int, axis: str, center, material: int) -> Mesh:
    """A closed prism of ``segments`` sides around ``axis`` ("x", "y" or "z"), ``length`` long, centred at ``center``;
    with ``segments`` a multiple of 4 it reaches ``radius`` along both other axes (a wheel touches the road)."""
    a = 2 * math.pi * np.arange(segments) / segments
    ring = np.c_[radius * np.cos(a), radius * np.sin(a)]
    h = length / 2
    v = np.concatenate([np.c_[np.full(segments, -h), ring], np.c_[np.full(segments, h), ring], [[-h, 0, 0], [h, 0, 0]]])
    tris = []
    for j in range(segments):
        k = (j + 1) % segments
        tris += [(j, k, segments + k), (j, segments + k, segments + j)]
        tris += [(2 * segments, k, j), (2 * segments + 1, segments + j, segments + k)]
    order = {"x": [0, 1, 2], "y": [1, 0, 2], "z": [1, 2, 0]}[axis]
    v = v[:, order] + np.asarray(center, np.float64)
    return _outward(Mesh(v, np.array(tris, np.int32), np.full(len(tris), material, np.uint8)))


def icosphere(subdivisions: int = 1) -> Mesh:
    """A unit sphere of 20·4ⁿ triangles (``subdivisions`` n), centred at the origin, material ``leaves``."""
    t = (1.0 + 5**0.5) / 2
    v = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
         (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]  # fmt: skip
    f = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2), (10, 7, 6),
         (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10),
         (8, 6, 7), (9, 8, 1)]  # fmt: skip
    verts = [np.array(p, np.float64) / np.linalg.norm(p) for p in v]
    for _ in range(subdivisions):
        cache: dict[tuple[int, int], int] = {}

        def mid(a: int, b: int) -> int:
            key = (min(a, b), max(a, b))
            if key not in cache:
                m = verts[a] + verts[b]
                verts.append(m / np.linalg.norm(m))
                cache[key] = len(verts) - 1
            return cache[key]

        f = [tri for a, b, c in f for tri in ((a, mid(a, b), mid(a, c)), (b, mid(b, c), mid(a, b)),
                                              (c, mid(a, c), mid(b, c)), (mid(a, b), mid(b, c), mid(a, c)))]  # fmt: skip
    return _outward(Mesh(np.array(verts), np.array(f, np.int32), np.full(len(f), LEAVES, np.uint8)))

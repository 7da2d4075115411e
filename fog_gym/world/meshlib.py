"""The process's mesh library: every mesh a primitive can draw, as flat arrays the kernels read.

Each mesh is stored normalised to the unit box ``[−0.5, 0.5]³`` (its bounds' centre at the origin, divided by their
extent), so a primitive row (centre, half sizes, yaw; :class:`~fog_gym.world.primitives.Primitives`) places it by
``world = centre + R(yaw) · (v · 2·halves)`` and the primitive's box is the mesh's tight bound. Id 0 is the box
itself (12 triangles). Meshes are added once per process (by name; adding a name twice returns its id) and never
change; the arrays grow when one is added.

For the ray caster, each mesh's triangles are sorted along the mesh's longest axis into chunks of at most
:data:`CHUNK` with their own bounds, so a ray tests a chunk's triangles only when it meets the chunk's bounds.

Example:
    >>> LIBRARY.id("box"), LIBRARY.arrays().triangles[:12].shape
    (0, (12, 3))
    >>> LIBRARY.arrays().vertices[:8].min(), LIBRARY.arrays().vertices[:8].max()
    (np.float64(-0.5), np.float64(0.5))
"""

from __future__ import annotations

import threading
from typing import NamedTuple

import numpy as np

from fog_gym.world.mesh import Mesh, box_mesh

#: Triangles per ray-casting chunk at most.
CHUNK = 24


class LibraryArrays(NamedTuple):
    """The library as flat arrays: normalised ``vertices`` (V, 3), ``triangles`` (T, 3) into them, ``materials``
    (T,), ``tri_start`` (M + 1,) each mesh's first triangle, ``chunk_start`` (M + 1,) each mesh's first chunk,
    ``chunk_lo`` / ``chunk_hi`` (K, 3) the chunks' bounds, ``chunk_tri`` (K + 1,) each chunk's first triangle
    (triangles are stored chunk by chunk)."""

    vertices: np.ndarray
    triangles: np.ndarray
    materials: np.ndarray
    tri_start: np.ndarray
    chunk_start: np.ndarray
    chunk_lo: np.ndarray
    chunk_hi: np.ndarray
    chunk_tri: np.ndarray


def normalised(mesh: Mesh) -> Mesh:
    """``mesh`` moved and scaled so its bounds are the unit box ``[−0.5, 0.5]³``."""
    lo, hi = mesh.bounds()
    extent = np.where(hi - lo > 0, hi - lo, 1.0)
    return Mesh((mesh.vertices - (lo + hi) / 2) / extent, mesh.triangles, mesh.materials)


def _chunks(mesh: Mesh) -> tuple[Mesh, list[np.ndarray]]:
    """The mesh with its triangles reordered chunk by chunk, and each chunk's triangle indices."""
    v, t = mesh.vertices, mesh.triangles
    centroid = v[t].mean(axis=1)
    axis = int(np.argmax(v.max(axis=0) - v.min(axis=0)))
    order = np.lexsort((centroid[:, 2], centroid[:, 1 - (axis == 1)], centroid[:, axis]))
    mesh = Mesh(v, t[order], mesh.materials[order])
    return mesh, [np.arange(k, min(k + CHUNK, len(t))) for k in range(0, len(t), CHUNK)]


class MeshLibrary:
    """Meshes by name and id (see the module docstring); thread-safe additions."""

    def __init__(self) -> None:
        self._names: dict[str, int] = {}
        self._meshes: list[Mesh] = []
        self._chunks: list[list[np.ndarray]] = []
        self._arrays: LibraryArrays | None = None
        self._lock = threading.Lock()

    def add(self, name: str, mesh: Mesh) -> int:
        """The id of ``name``, adding ``mesh`` (normalised) the first time."""
        with self._lock:
            if name in self._names:
                return self._names[name]
            m, chunks = _chunks(normalised(mesh))
            self._names[name] = len(self._meshes)
            self._meshes.append(m)
            self._chunks.append(chunks)
            self._arrays = None
            return self._names[name]

    def id(self, name: str) -> int:
        """The id of a mesh added before (``KeyError`` naming the known ones otherwise)."""
        try:
            return self._names[name]
        except KeyError:
            raise KeyError(f"no mesh {name!r} in the library (known: {sorted(self._names)})") from None

    def mesh(self, mesh_id: int) -> Mesh:
        """The normalised mesh of an id."""
        return self._meshes[mesh_id]

    def __len__(self) -> int:
        return len(self._meshes)

    def arrays(self) -> LibraryArrays:
        """The flat arrays of every mesh added so far (rebuilt only after an addition)."""
        with self._lock:
            if self._arrays is None:
                self._arrays = self._build()
            return self._arrays

    def _build(self) -> LibraryArrays:
        verts, tris, mats, lo, hi = [], [], [], [], []
        tri_start, chunk_start, chunk_tri = [0], [0], [0]
        v0 = 0
        for m, chunks in zip(self._meshes, self._chunks):
            verts.append(m.vertices)
            tris.append(m.triangles + v0)
            mats.append(m.materials)
            v0 += len(m.vertices)
            for c in chunks:
                pts = m.vertices[m.triangles[c].ravel()]
                lo.append(pts.min(axis=0))
                hi.append(pts.max(axis=0))
                chunk_tri.append(chunk_tri[-1] + len(c))
            tri_start.append(tri_start[-1] + len(m.triangles))
            chunk_start.append(chunk_start[-1] + len(chunks))
        return LibraryArrays(np.ascontiguousarray(np.concatenate(verts)), np.ascontiguousarray(np.concatenate(tris)),
                             np.ascontiguousarray(np.concatenate(mats)), np.array(tri_start, np.int64),
                             np.array(chunk_start, np.int64), np.ascontiguousarray(np.array(lo)),
                             np.ascontiguousarray(np.array(hi)), np.array(chunk_tri, np.int64))  # fmt: skip


#: The process's library; id 0 is the box.
LIBRARY = MeshLibrary()
BOX_MESH = LIBRARY.add("box", box_mesh((1.0, 1.0, 1.0)))


def body_mesh_id(name: str) -> int:
    """The library id of the vehicle body type ``name`` (:mod:`fog_gym.world.bodies`), added on first use."""
    from fog_gym.world.bodies import body_mesh

    return LIBRARY.add(f"body:{name}", body_mesh(name))

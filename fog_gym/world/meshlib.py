"""The process's mesh library: every mesh a primitive can draw, as flat arrays the kernels read.

Each mesh is stored normalised to the unit box ``[−0.5, 0.5]³`` (its bounds' centre at the origin, divided by their
extent), so a primitive row (centre, half sizes, yaw; :class:`~fog_gym.world.primitives.Primitives`) places it by
``world = centre + R(yaw) · (v · 2·halves)`` and the primitive's box is the mesh's tight bound. Id 0 is the box
itself (12 triangles). Meshes are added once per process (by name; adding a name twice returns its id) and never
change; the arrays grow when one is added.

For the ray caster, each mesh carries a bounding-volume hierarchy: its triangles split at the median centroid along
the longest axis, recursively, down to leaves of at most :data:`LEAF` triangles, each node with its bounds. The
nodes are stored depth first with a *skip* index (the node after the subtree), so a ray walks it without a stack:
into a node whose bounds it meets before its nearest hit so far, past the subtree otherwise. The nodes are stored in
:data:`OCTANTS` orders, one per octant of ray directions with each node's nearer child first, so a ray finds near
triangles first and skips the far subtrees.

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

from fog_gym._rounds import held
from fog_gym.world.mesh import Mesh, box_mesh, icosphere

#: Triangles per leaf of a mesh's bounding-volume hierarchy at most.
LEAF = 4
#: Node orders per mesh: one per octant of ray directions (near child first).
OCTANTS = 8


class LibraryArrays(NamedTuple):
    """The library as flat arrays: normalised ``vertices`` (V, 3), ``triangles`` (T, 3) into them, ``materials``
    (T,), ``tri_start`` (M + 1,) each mesh's first triangle, ``vert_start`` (M + 1,) its first vertex,
    ``node_start`` (8 M + 1,) the first node of mesh ``m``'s order for ray octant ``o`` at ``8 m + o`` (its
    root; its nodes run depth first to the next entry's); per node ``node_lo`` / ``node_hi`` (N, 3) its bounds,
    ``node_skip`` (N,) the node after its subtree and ``node_first`` / ``node_count`` (N,) a leaf's triangles
    (count 0: an inner node, whose first child is the next node; the triangles are stored leaf by leaf);
    ``tri_geom`` (T, 12) per triangle its first vertex, two edges and (unnormalised) normal, for the ray caster;
    ``outline`` (O, 3) each mesh's vertices on its convex hull (those farthest along one of 642 directions spread over
    the sphere), from ``outline_start`` (M + 1,), whose hull is the mesh's up to slivers far below a shadow cell;
    ``radius`` (M,) each mesh's bounding sphere about the unit box's centre (its farthest vertex: 0.5 for a round
    crown, ≈ 0.87 for a box), which lets the ray caster pass a mesh whose sphere a ray misses."""

    vertices: np.ndarray
    triangles: np.ndarray
    materials: np.ndarray
    tri_start: np.ndarray
    vert_start: np.ndarray
    node_start: np.ndarray
    node_lo: np.ndarray
    node_hi: np.ndarray
    node_skip: np.ndarray
    node_first: np.ndarray
    node_count: np.ndarray
    tri_geom: np.ndarray
    outline: np.ndarray
    outline_start: np.ndarray
    radius: np.ndarray


def normalised(mesh: Mesh) -> Mesh:
    """``mesh`` moved and scaled so its bounds are the unit box ``[−0.5, 0.5]³``."""
    lo, hi = mesh.bounds()
    extent = np.where(hi - lo > 0, hi - lo, 1.0)
    return Mesh((mesh.vertices - (lo + hi) / 2) / extent, mesh.triangles, mesh.materials)


def _bvh(mesh: Mesh) -> tuple[Mesh, list[list[tuple]]]:
    """The mesh with its triangles reordered leaf by leaf, and its hierarchy's nodes depth first (root first) as
    (lo, hi, skip, first, count) with the skip index relative to the root, in eight orders: for the ray direction
    octant ``o`` (bit 0: x < 0, bit 1: y < 0, bit 2: z < 0), each inner node's child nearer along its split axis
    comes first, so a ray meets near triangles first and prunes the far subtrees with its nearest hit."""
    v, t = mesh.vertices, mesh.triangles
    tri_v = v[t]
    centroid = tri_v.mean(axis=1)
    order: list[int] = []
    tree: list[list] = []  # lo, hi, split axis, lower child, upper child, first, count

    def build(idx: np.ndarray) -> int:
        k = len(tree)
        tree.append([tri_v[idx].reshape(-1, 3).min(axis=0), tri_v[idx].reshape(-1, 3).max(axis=0), -1, -1, -1, 0, 0])
        if len(idx) <= LEAF:
            tree[k][5], tree[k][6] = len(order), len(idx)
            order.extend(idx.tolist())
        else:
            c = centroid[idx]
            axis = int(np.argmax(c.max(axis=0) - c.min(axis=0)))
            idx = idx[np.argsort(c[:, axis], kind="stable")]
            half = len(idx) // 2
            tree[k][2] = axis
            tree[k][3] = build(idx[:half])
            tree[k][4] = build(idx[half:])
        return k

    build(np.arange(len(t)))

    def layout(octant: int) -> list[tuple]:
        nodes: list[list] = []

        def emit(k: int) -> None:
            lo, hi, axis, lower, upper, first, count = tree[k]
            j = len(nodes)
            nodes.append([lo, hi, 0, first, count])
            if axis >= 0:
                near, far = (upper, lower) if octant >> axis & 1 else (lower, upper)
                emit(near)
                emit(far)
            nodes[j][2] = len(nodes)  # skip: the node after this subtree

        emit(0)
        return [tuple(n) for n in nodes]

    order_a = np.array(order)
    return Mesh(v, t[order_a], mesh.materials[order_a]), [layout(o) for o in range(OCTANTS)]


class MeshLibrary:
    """Meshes by name and id (see the module docstring); thread-safe additions."""

    def __init__(self) -> None:
        self._names: dict[str, int] = {}
        self._meshes: list[Mesh] = []
        self._nodes: list[list[list[tuple]]] = []  # per mesh, per octant
        self._arrays: LibraryArrays | None = None
        self._lock = threading.Lock()

    def add(self, name: str, mesh: Mesh) -> int:
        """The id of ``name``, adding ``mesh`` (normalised) the first time."""
        with held(self._lock):
            if name in self._names:
                return self._names[name]
            m, nodes = _bvh(normalised(mesh))
            self._names[name] = len(self._meshes)
            self._meshes.append(m)
            self._nodes.append(nodes)
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
        with held(self._lock):
            if self._arrays is None:
                self._arrays = self._build()
            return self._arrays

    def _build(self) -> LibraryArrays:
        verts, tris, mats, nodes = [], [], [], []
        tri_start, node_start, vert_start = [0], [0], [0]
        v0 = 0
        for m, mesh_nodes in zip(self._meshes, self._nodes):
            verts.append(m.vertices)
            tris.append(m.triangles + v0)
            mats.append(m.materials)
            v0 += len(m.vertices)
            vert_start.append(v0)
            for octant_nodes in mesh_nodes:
                base = len(nodes)
                for lo, hi, skip, first, count in octant_nodes:
                    nodes.append((lo, hi, skip + base, first + tri_start[-1], count))
                node_start.append(len(nodes))
            tri_start.append(tri_start[-1] + len(m.triangles))
        directions = icosphere(3).vertices.T
        outlines = [m.vertices[np.unique(np.argmax(m.vertices @ directions, axis=0))] for m in self._meshes]
        v, t = np.concatenate(verts), np.concatenate(tris)
        e1, e2 = v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]]
        tri_geom = np.ascontiguousarray(np.concatenate([v[t[:, 0]], e1, e2, np.cross(e1, e2)], axis=1))
        return LibraryArrays(
            np.ascontiguousarray(v), np.ascontiguousarray(t),
            np.ascontiguousarray(np.concatenate(mats)), np.array(tri_start, np.int64), np.array(vert_start, np.int64),
            np.array(node_start, np.int64),
            np.ascontiguousarray(np.array([n[0] for n in nodes])), np.ascontiguousarray(np.array([n[1] for n in nodes])),
            np.array([n[2] for n in nodes], np.int64), np.array([n[3] for n in nodes], np.int64),
            np.array([n[4] for n in nodes], np.int64), tri_geom, np.ascontiguousarray(np.concatenate(outlines)),
            np.cumsum([0] + [len(o) for o in outlines]).astype(np.int64),
            np.array([np.sqrt((m.vertices**2).sum(axis=1).max()) for m in self._meshes], np.float64),
        )  # fmt: skip


#: The process's library; id 0 is the box.
LIBRARY = MeshLibrary()
BOX_MESH = LIBRARY.add("box", box_mesh((1.0, 1.0, 1.0)))


def body_mesh_id(name: str) -> int:
    """The library id of the vehicle body type ``name`` (:mod:`fog_gym.world.bodies`), added on first use."""
    from fog_gym.world.bodies import body_mesh

    return LIBRARY.add(f"body:{name}", body_mesh(name))

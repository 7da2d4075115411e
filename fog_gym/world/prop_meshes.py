"""Meshes of the roadside props the towns place (:func:`fog_gym.world.scenery.place_props`), drawn in each prop's box.

- **Trees**: a crown that is not a box — a subdivided icosahedron (80 triangles) or, for one tree in three, a
  conifer's two stacked cones — filling the prop's canopy box, on a slim box trunk.
- **Buildings**: a façade, window panes on every floor of every side (3 m floors, 1.2 × 1.4 m panes every 2.6 m,
  3 cm in front of the wall) and a parapet round the roof's edge (:func:`building_mesh`). The sensors see it as its
  parts (:func:`building_parts`): the wall and the parapet as boxes, and each side's panes as a flat mesh in a thin
  box in front of the wall — a ray then meets the big wall in one box test and the panes in a small hierarchy.
  Pane meshes are made per (side length on a 2 m grid, floors), so a town needs a few dozen.
- **Street-light poles** stay slim boxes; **guard rails** are a beam on three posts, as four boxes
  (:func:`rail_parts`: long thin boxes cost the ray caster least as boxes).

Every mesh fills its prop's box exactly (the box is the mesh's tight bound), as the vehicles' do.

Example:
    >>> m = building_mesh(12.0, 10.0, 9.0)
    >>> m.bounds().round(6).tolist()
    [[-6.0, -5.0, 0.0], [6.0, 5.0, 9.0]]
"""

from __future__ import annotations

import functools

import numpy as np

from fog_gym.world.mesh import FACADE, LEAVES, ROOF, WINDOW, Mesh, box_mesh, cylinder, icosphere
from fog_gym.world.meshlib import LIBRARY

#: Prop tags (CARLA): guard rail, pole, vegetation, building.
RAIL_TAG, POLE_TAG, VEGETATION_TAG, BUILDING_TAG = 28, 6, 9, 3
#: A vegetation prop this thin (m) is a trunk; a wider one a crown.
TRUNK_MAX = 0.5
FLOOR, PANE_W, PANE_H, PANE_STEP, PANE_OUT, PARAPET = 3.0, 1.2, 1.4, 2.6, 0.03, 0.4


def _quad(corners: np.ndarray, material: int) -> Mesh:
    """A flat quad (two triangles) whose normal follows the corners' counter-clockwise order (numpy's cross)."""
    return Mesh(corners, np.array([[0, 1, 2], [0, 2, 3]], np.int32), np.full(2, material, np.uint8))


@functools.lru_cache(maxsize=None)
def building_mesh(length: float, depth: float, height: float) -> Mesh:
    """A building of (length along x, depth along y, height) standing on z = 0: façade, panes, parapet."""
    L, D, H = float(length), float(depth), float(height)
    wall = box_mesh((L - 2 * PANE_OUT, D - 2 * PANE_OUT, H - PARAPET), FACADE)
    parts = [wall]
    t = 0.3
    for s in (-1, 1):  # the parapet: four thin boxes round the roof's edge, up to the full height
        parts.append(box_mesh((L - 2 * PANE_OUT, t, PARAPET), ROOF, center=(0.0, s * (D / 2 - PANE_OUT - t / 2), H - PARAPET / 2)))
        parts.append(box_mesh((t, D - 2 * PANE_OUT - 2 * t, PARAPET), ROOF,
                              center=(s * (L / 2 - PANE_OUT - t / 2), 0.0, H - PARAPET / 2)))  # fmt: skip
    floors = max(1, int((H - PARAPET - 0.6) // FLOOR))
    for side, (span, along, normal, offset) in enumerate(((L, 0, 1, D / 2), (L, 0, 1, -D / 2), (D, 1, 0, L / 2),
                                                           (D, 1, 0, -L / 2))):  # fmt: skip
        n = int((span - 1.0) // PANE_STEP)
        if n < 1:
            continue
        starts = (np.arange(n) - (n - 1) / 2) * PANE_STEP
        for f in range(floors):
            z0 = 1.0 + f * FLOOR
            for a in starts:
                c = np.zeros((4, 3))
                c[:, along] = [a - PANE_W / 2, a + PANE_W / 2, a + PANE_W / 2, a - PANE_W / 2]
                c[:, normal] = offset
                c[:, 2] = [z0, z0, z0 + PANE_H, z0 + PANE_H]
                q = _quad(c, WINDOW)
                if np.sign(q.normals()[0, normal]) != np.sign(offset):
                    q = _quad(c[::-1].copy(), WINDOW)
                parts.append(q)
    return Mesh.join(*parts)


@functools.lru_cache(maxsize=None)
def _fixed_meshes() -> dict[str, int]:
    """The library ids of the props that are one shape scaled to their box."""
    crown = icosphere(1)
    crown = Mesh(crown.vertices * [0.5, 0.5, 0.5] + [0, 0, 0.5], crown.triangles, crown.materials)
    cone_low = cylinder(0.5, 0.5, 8, "z", (0, 0, 0.25), LEAVES)
    v = cone_low.vertices.copy()  # a cone: squeeze the top ring of an eight-sided prism to a small one
    top = v[:, 2] > 0.4
    v[top, :2] *= 0.08
    conifer = Mesh.join(Mesh(v, cone_low.triangles, cone_low.materials),
                        Mesh(v * [0.7, 0.7, 1.0] + [0, 0, 0.45], cone_low.triangles, cone_low.materials))  # fmt: skip
    return {
        "crown": LIBRARY.add("prop:crown", crown),
        "conifer": LIBRARY.add("prop:conifer", conifer),
    }  # fmt: skip


#: A guard rail's beam starts this share of the rail's height above the road; its posts are this wide [m].
BEAM_FROM, POST = 0.55, 0.12


def rail_parts(rails):
    """Each guard rail of ``rails`` (:class:`~fog_gym.world.primitives.Primitives` rows in their boxes) as its beam
    (the top of the box, full length and width) and three posts (ends and middle) down to the road: four box rows
    each, within the rail's box, which stays their tight bound; returns the parts and each part's rail (row index)."""
    from fog_gym.world.primitives import Primitives

    n = len(rails)
    hx, hy, hz = rails.halves[:, 0], rails.halves[:, 1], rails.halves[:, 2]
    c, s = np.cos(rails.yaws), np.sin(rails.yaws)
    ground = rails.centers[:, 2] - hz
    beam_c = rails.centers.copy()
    beam_c[:, 2] = ground + hz * (1.0 + BEAM_FROM)
    beam_h = np.c_[hx, hy, hz * (1.0 - BEAM_FROM)]
    parts_c, parts_h = [beam_c], [beam_h]
    for frac in (-1.0, 0.0, 1.0):
        off = frac * (hx - POST / 2)
        pc = np.c_[rails.centers[:, 0] + off * c, rails.centers[:, 1] + off * s, ground + hz * BEAM_FROM]
        parts_c.append(pc)
        parts_h.append(np.c_[np.full(n, POST / 2), np.full(n, POST / 2), hz * BEAM_FROM])
    rep = lambda a: np.concatenate([a] * 4)  # noqa: E731
    parts = Primitives(np.ascontiguousarray(np.concatenate(parts_c)), np.ascontiguousarray(np.concatenate(parts_h)),
                       rep(rails.yaws), rep(rails.colors), rep(rails.tags), rep(rails.insts), rep(rails.emissive),
                       np.zeros(4 * n, np.int32))  # fmt: skip
    return parts, rep(np.arange(n))


@functools.lru_cache(maxsize=None)
def _panes_id(span: float, floors: int) -> int:
    """The library id of one side's panes: a flat row of panes per floor across ``span`` metres (facing +y); made
    once per (span on the 2 m grid, floors) and process."""
    span = max(2.0, 2.0 * round(span / 2.0))
    name = f"prop:panes:{span:g}x{floors}"
    try:
        return LIBRARY.id(name)
    except KeyError:
        pass
    n = int((span - 1.0) // PANE_STEP)
    a = np.tile((np.arange(n) - (n - 1) / 2) * PANE_STEP, floors)
    z0 = np.repeat(np.arange(floors) * FLOOR, n)
    # each pane: corners (a − w/2, z0), (a − w/2, z0 + h), (a + w/2, z0 + h), (a + w/2, z0) at y = 0, whose two
    # triangles (0, 1, 2), (0, 2, 3) face +y
    x = np.stack([a - PANE_W / 2, a - PANE_W / 2, a + PANE_W / 2, a + PANE_W / 2], axis=1)
    z = np.stack([z0, z0 + PANE_H, z0 + PANE_H, z0], axis=1)
    vertices = np.stack([x, np.zeros_like(x), z], axis=2).reshape(-1, 3)
    base = 4 * np.arange(n * floors, dtype=np.int32)[:, None, None]
    triangles = (base + np.array([[0, 1, 2], [0, 2, 3]], np.int32)).reshape(-1, 3)
    mesh = Mesh(vertices, triangles, np.full(len(triangles), WINDOW, np.uint8))
    assert (mesh.normals()[:, 1] > 0).all()
    return LIBRARY.add(name, mesh)


def building_parts(buildings):
    """Each building of ``buildings`` (:class:`~fog_gym.world.primitives.Primitives` rows in their boxes, mesh 0) as
    the parts the sensors see: the wall (a box 3 cm inside the building's box), the parapet (four boxes round the
    roof's edge, up to the full height) and, for each side wide enough, its panes (a flat mesh in the outer 3 cm):
    all within the building's box, which stays their tight bound; returns the parts and each part's building."""
    from fog_gym.world.primitives import Primitives

    rows: list[tuple] = []  # centre (3), halves (3), yaw, row of the building, mesh
    for k in range(len(buildings)):
        cx, cy, cz = buildings.centers[k]
        hx, hy, hz = buildings.halves[k]
        yaw = float(buildings.yaws[k])
        c, s = np.cos(yaw), np.sin(yaw)
        ground = cz - hz

        def world(lx: float, ly: float) -> tuple[float, float]:
            return cx + lx * c - ly * s, cy + lx * s + ly * c

        rows.append(((cx, cy, ground + (2 * hz - PARAPET) / 2), (hx - PANE_OUT, hy - PANE_OUT, (2 * hz - PARAPET) / 2),
                     yaw, k, 0))  # fmt: skip
        t = 0.3
        zp = ground + 2 * hz - PARAPET / 2
        for sgn in (-1.0, 1.0):
            rows.append(((*world(0.0, sgn * (hy - PANE_OUT - t / 2)), zp), (hx - PANE_OUT, t / 2, PARAPET / 2), yaw, k, 0))
            rows.append(((*world(sgn * (hx - PANE_OUT - t / 2), 0.0), zp), (t / 2, hy - PANE_OUT - t, PARAPET / 2), yaw, k, 0))
        floors = max(1, int((2 * hz - PARAPET - 0.6) // FLOOR))
        z_mid = ground + 1.0 + ((floors - 1) * FLOOR + PANE_H) / 2
        for span, out, side_yaw in ((2 * hx, (0.0, hy), yaw), (2 * hx, (0.0, -hy), yaw + np.pi),
                                    (2 * hy, (hx, 0.0), yaw - np.pi / 2), (2 * hy, (-hx, 0.0), yaw + np.pi / 2)):  # fmt: skip
            if span - 1.0 < PANE_STEP:
                continue
            mesh = _panes_id(span, floors)
            lo, hi = LIBRARY.mesh(mesh).bounds()
            n = int((max(2.0, 2.0 * round(span / 2.0)) - 1.0) // PANE_STEP)
            width = (n - 1) * PANE_STEP + PANE_W
            depth_dir = np.array(out) / max(np.hypot(*out), 1e-9)
            pos = np.array(world(*(np.array(out) - depth_dir * PANE_OUT / 2)))
            rows.append(((pos[0], pos[1], z_mid), (width / 2, PANE_OUT / 2, ((floors - 1) * FLOOR + PANE_H) / 2),
                         side_yaw, k, mesh))  # fmt: skip
    if not rows:
        return Primitives.empty(), np.zeros(0, np.int64)
    idx = np.array([r[3] for r in rows])
    return Primitives(np.array([r[0] for r in rows], np.float64), np.array([r[1] for r in rows], np.float64),
                      np.array([r[2] for r in rows], np.float64), buildings.colors[idx], buildings.tags[idx],
                      buildings.insts[idx], buildings.emissive[idx], np.array([r[4] for r in rows], np.int32)), idx  # fmt: skip


def prop_mesh_ids(sizes: np.ndarray, tags: np.ndarray, seeds: np.ndarray) -> np.ndarray:
    """The library mesh of every prop (sizes (P, 3) = length, width, height; CARLA tags; an integer per prop that
    picks between alternative shapes); 0 (the box) for a prop of another kind (guard rails and buildings are drawn as
    their parts: :func:`rail_parts`, :func:`building_parts`)."""
    fixed = _fixed_meshes()
    out = np.zeros(len(tags), np.int32)
    for k, (size, tag) in enumerate(zip(sizes, tags)):
        if tag == VEGETATION_TAG and size[0] > TRUNK_MAX:  # a crown; trunks and poles are slim boxes
            out[k] = fixed["conifer" if seeds[k] % 3 == 0 else "crown"]
    return out

"""Triangle meshes and the procedural vehicle bodies: every body is closed and outward, its box is its tight bound
(bumpers, mirrors, roof, tyres on the road), each class spans several shapes with real silhouettes (a sloped
windscreen, glass, lamps, plates, tyres), and bad mesh input is refused with a clear error."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fog_gym.world.bodies import BODY_TYPES, CLASS_BODIES, body_mesh, body_type_of
from fog_gym.world.fleet import CLASS_SPECS
from fog_gym.world.mesh import (GLASS, HEADLAMP, PLATE, TAILLAMP, TYRE, Mesh, box_mesh, cylinder, icosphere,
                                is_closed, signed_volume, triangle_areas)  # fmt: skip


@pytest.mark.parametrize("name", sorted(BODY_TYPES))
def test_every_body_is_closed_outward_and_its_box_is_its_tight_bound(name):
    m = body_mesh(name)
    L, W, H = BODY_TYPES[name].size
    assert is_closed(m) and signed_volume(m) > 0
    np.testing.assert_allclose(m.bounds(), [[-L / 2, -W / 2, 0.0], [L / 2, W / 2, H]], atol=1e-9)


@pytest.mark.parametrize("name", sorted(BODY_TYPES))
def test_every_body_has_glass_lamps_plates_and_tyres_on_the_road(name):
    m = body_mesh(name)
    mats = set(m.materials.tolist())
    assert {GLASS, HEADLAMP, TAILLAMP, PLATE, TYRE} <= mats
    tyres = m.vertices[m.triangles[m.materials == TYRE].ravel()]
    assert tyres[:, 2].min() == pytest.approx(0.0, abs=1e-9)  # the tyres stand on the road
    lamps = m.vertices[m.triangles[m.materials == HEADLAMP].ravel()]
    tails = m.vertices[m.triangles[m.materials == TAILLAMP].ravel()]
    assert lamps[:, 0].mean() > 0 > tails[:, 0].mean()  # head lamps at the front, tail lamps at the rear


def test_the_classes_span_ten_body_types_with_different_silhouettes():
    assert {c: len(v) for c, v in CLASS_BODIES.items()} == {0: 4, 1: 3, 4: 3}
    assert set(CLASS_BODIES) == set(CLASS_SPECS)
    # the windscreen is sloped: its glass normals lean forward and up, not along a box axis
    m = body_mesh("sedan")
    n = m.normals()[m.materials == GLASS]
    screen = n[(n[:, 0] > 0.2) & (n[:, 2] > 0.2)]
    assert len(screen) and np.all(np.degrees(np.arccos(np.clip(np.abs(screen).max(axis=1), 0, 1))) > 20)
    # a share of the surface faces none of the box axes within 10° (a box: 0 %)
    areas = triangle_areas(m.vertices, m.triangles)
    off_axis = np.abs(m.normals()).max(axis=1) < np.cos(np.radians(10))
    assert areas[off_axis].sum() / areas.sum() > 0.15
    outlines = {name: np.round(np.array(BODY_TYPES[name].stations)[:, 3], 2).tobytes() for name in BODY_TYPES}
    assert len(set(outlines.values())) == len(BODY_TYPES)  # no two bodies share a roof line


def test_body_types_follow_the_id_evenly_and_the_ego_is_a_sedan():
    picks = [body_type_of(i, 0) for i in range(2, 4002)]
    counts = {n: picks.count(n) for n in CLASS_BODIES[0]}
    assert min(counts.values()) > 800  # 4000 ids over 4 types: each ≈ 1000
    assert body_type_of(1, 1, ego_id=1) == "sedan"
    with pytest.raises(ValueError, match="fog_class must be one of"):
        body_type_of(3, 2)


def test_building_blocks_are_closed_with_the_volume_of_their_shape():
    assert signed_volume(box_mesh((4.0, 2.0, 1.5))) == pytest.approx(12.0)
    c = cylinder(1.0, 2.0, 64, "z", (0, 0, 0), TYRE)
    assert is_closed(c) and signed_volume(c) == pytest.approx(2 * np.pi, rel=0.01)
    s = icosphere(2)
    assert is_closed(s) and len(s) == 320 and 0.95 * 4 / 3 * np.pi < signed_volume(s) < 4 / 3 * np.pi  # inscribed


def test_bad_mesh_input_is_refused_naming_the_problem():
    v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    t = np.array([[0, 1, 2]])
    m = np.zeros(1, np.uint8)
    with pytest.raises(ValueError, match="vertices must be finite, vertex 1"):
        Mesh(np.array([[0.0, 0, 0], [np.nan, 0, 0], [0, 1, 0]]), t, m)
    with pytest.raises(ValueError, match=r"triangle 0 has vertex indices \[0, 1, 3\] outside 0..2"):
        Mesh(v, np.array([[0, 1, 3]]), m)
    with pytest.raises(ValueError, match="triangle 0 is degenerate"):
        Mesh(np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0]]), t, m)
    with pytest.raises(ValueError, match="materials must be one per triangle"):
        Mesh(v, t, np.zeros(2, np.uint8))
    with pytest.raises(ValueError, match="material ids must be below"):
        Mesh(v, t, np.array([200], np.uint8))
    with pytest.raises(ValueError, match=r"vertices must be \(V, 3\)"):
        Mesh(v[:, :2], t, m)
    with pytest.raises(ValueError, match="body type must be one of"):
        body_mesh("limousine")


@settings(max_examples=30, deadline=None)
@given(st.floats(0.5, 20), st.floats(0.5, 20), st.floats(0.5, 20), st.floats(-5, 5), st.floats(-5, 5))
def test_a_box_mesh_is_closed_outward_and_bounded_by_its_size(length, width, height, x, y):
    m = box_mesh((length, width, height), center=(x, y, None))
    assert is_closed(m) and signed_volume(m) == pytest.approx(length * width * height, rel=1e-9)
    np.testing.assert_allclose(m.bounds(), [[x - length / 2, y - width / 2, 0], [x + length / 2, y + width / 2, height]])

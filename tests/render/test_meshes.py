"""Every sensor on the meshes: a triangle covers exactly the pixels its projection says, a ray stops at the
analytically nearest front-facing triangle (with its material and incidence), and on a frame of mesh vehicles no
LiDAR return lies outside its vehicle's box while the camera sees shapes that boxes cannot make."""

from __future__ import annotations

import functools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fog_gym.render.raster import render
from fog_gym.render.surface import tile_surface
from fog_gym.sensors.raycast import GROUND, MISS, cast_rays
from fog_gym.world.mesh import MATERIAL_IDS, Mesh
from fog_gym.world.meshlib import LIBRARY, body_mesh_id
from fog_gym.world.primitives import Primitives

SIGN = MATERIAL_IDS["sign"]


def _prims(center, size, yaw, mesh, inst=7, tag=14):
    return Primitives.coerce({"centers": np.array([center], float), "halves": np.array([size], float) / 2,
                              "yaws": np.array([yaw], float), "insts": np.array([inst]), "tags": np.array([tag]),
                              "meshes": np.array([mesh]), "colors": np.array([[0.5, 0.4, 0.3]])})  # fmt: skip


def _brute_force(origin, dirs, prims):
    """Nearest front-facing triangle per ray by testing every triangle in the world frame (numpy)."""
    lib = LIBRARY.arrays()
    m = int(prims.meshes[0])
    t0, t1 = lib.tri_start[m], lib.tri_start[m + 1]
    v = lib.vertices * (2 * prims.halves[0])
    c, s = np.cos(prims.yaws[0]), np.sin(prims.yaws[0])
    w = np.c_[v[:, 0] * c - v[:, 1] * s, v[:, 0] * s + v[:, 1] * c, v[:, 2]] + prims.centers[0]
    tri = w[lib.triangles[t0:t1]]
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    n = np.cross(e1, e2)
    best = np.full(len(dirs), np.inf)
    mat = np.full(len(dirs), 255)
    for i, d in enumerate(dirs):
        p = np.cross(d, e2)
        det = np.einsum("ij,ij->i", e1, p)
        q0 = origin - tri[:, 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            u = np.einsum("ij,ij->i", q0, p) / det
            q = np.cross(q0, e1)
            vv = q @ d / det
            t = np.einsum("ij,ij->i", e2, q) / det
        ok = (n @ d < 0) & (np.abs(det) > 1e-18) & (u >= 0) & (u <= 1) & (vv >= 0) & (u + vv <= 1) & (t > 1e-6)
        if ok.any():
            k = np.flatnonzero(ok)[np.argmin(t[ok])]
            best[i], mat[i] = t[k], lib.materials[t0 + k]
    return best, mat


@settings(max_examples=25, deadline=None)
@given(st.floats(0, 2 * np.pi), st.floats(-3, 3), st.floats(0.3, 2.5), st.integers(0, 2**31 - 1))
def test_a_ray_stops_at_the_nearest_front_triangle_of_a_mesh(yaw, lateral, height, seed):
    prims = _prims((12.0, lateral, 0.75), (4.6, 1.9, 1.5), yaw, body_mesh_id("sedan"))
    origin = np.array([0.0, 0.0, height])
    rng = np.random.default_rng(seed)
    target = prims.centers[0] + rng.uniform(-1, 1, (300, 3)) * [2.6, 1.2, 0.9]
    dirs = target - origin
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    hits = cast_rays(origin, dirs, 100.0, prims)
    want, mat = _brute_force(origin, dirs, prims)
    on_mesh = hits.index == 0
    assert on_mesh.sum() > 30  # most of these rays meet the car
    np.testing.assert_allclose(hits.distance[on_mesh], want[on_mesh], rtol=1e-6)
    np.testing.assert_array_equal(hits.material[on_mesh], mat[on_mesh])
    # a ray the mesh lets through (between the wheels, past the glasshouse) goes on to the ground or beyond
    assert np.all(np.isinf(want[~on_mesh]) | (want[~on_mesh] > hits.distance[~on_mesh]))
    assert set(np.unique(hits.index[~on_mesh])) <= {GROUND, MISS}
    # incidence: |cos| between the ray and the triangle's normal
    assert ((hits.cos_incidence[on_mesh] > 0) & (hits.cos_incidence[on_mesh] <= 1 + 1e-6)).all()


@settings(max_examples=25, deadline=None)
@given(st.floats(0, 2 * np.pi), st.floats(0.3, 12.0), st.integers(0, 2**31 - 1))
def test_a_ray_past_a_round_crown_s_bounding_sphere_misses_it_and_one_through_it_hits_the_nearest_triangle(yaw, height,
                                                                                                        seed):
    """Crowns are tested against their bounding sphere first: rays aimed at the sphere's rim (grazing in and out of
    it), at the crown's box corners (outside the sphere) and through it give the brute force's hits and misses."""
    from fog_gym.world.prop_meshes import _fixed_meshes

    crown = _fixed_meshes()["crown"]
    assert LIBRARY.arrays().radius[crown] < 0.8  # the caster tests its sphere
    prims = _prims((15.0, 2.0, 6.0), (5.0, 4.0, 6.0), yaw, crown)
    origin = np.array([0.0, 0.0, height])
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(300, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    scale = rng.choice([0.98, 1.0, 1.02, 1.2, 0.5], (300, 1))  # in, on and just past the sphere, and at the corners
    c, s = np.cos(yaw), np.sin(yaw)
    local = u * scale * 0.5 * np.array([5.0, 4.0, 6.0])
    local[:100] = rng.choice([-0.5, 0.5], (100, 3)) * [5.0, 4.0, 6.0] * 0.999
    target = prims.centers[0] + np.c_[local[:, 0] * c - local[:, 1] * s, local[:, 0] * s + local[:, 1] * c, local[:, 2]]
    dirs = target - origin
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    hits = cast_rays(origin, dirs, 100.0, prims)
    want, mat = _brute_force(origin, dirs, prims)
    on_mesh = hits.index == 0
    assert 30 < on_mesh.sum() < 290  # hits and misses both
    ground = np.where(dirs[:, 2] < 0, -height / np.minimum(dirs[:, 2], -1e-12), np.inf)
    np.testing.assert_array_equal(on_mesh, want < ground)
    np.testing.assert_allclose(hits.distance[on_mesh], want[on_mesh], rtol=1e-6)  # float32 distances


def _triangle_mesh() -> int:
    """A single triangle facing −x (towards a camera at the origin looking along +x), in the library."""
    v = np.array([[0.0, -1.0, 0.2], [0.0, 1.2, 0.6], [0.0, 0.1, 2.0]])
    tri = Mesh(v, np.array([[0, 2, 1]]), np.array([SIGN], np.uint8))
    if tri.normals()[0, 0] > 0:
        tri = Mesh(v, np.array([[0, 1, 2]]), np.array([SIGN], np.uint8))
    return LIBRARY.add("test:triangle", tri)


def test_a_triangle_covers_exactly_the_pixels_its_projection_says():
    mesh = _triangle_mesh()
    m = LIBRARY.mesh(mesh)
    lo, hi = m.bounds()
    size = np.array([0.01, 2.2, 1.8])  # the triangle's extent (x flat: any small depth)
    prims = _prims((3.5, 0.1, 1.1), size, 0.0, mesh, tag=8)
    # camera at (0, 0, 1.1) looking along +x: camera frame x right (= world y), y down (= −z), z forward (= x)
    R = np.array([[[0.0, 1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]]])
    t = -R[0] @ np.array([0.0, 0.0, 1.1])
    w, h, f = 96, 72, 60.0
    k = np.array([[f, f, w / 2, h / 2]])
    surface = tile_surface(np.zeros((4, 4), np.uint8), (-1000.0, -1000.0), 500.0)
    out = render(R, t[None], k, w, h, 1000.0, prims, surface, np.zeros((1, 3), np.uint8), np.zeros(1, np.uint8),
                 np.zeros(3), np.zeros(3), np.array([0.0, 0.0, 1.0]), 0.5, 0.5)  # fmt: skip
    # the analytic projection of the world triangle, and pixel centres inside it
    verts = LIBRARY.arrays().vertices[LIBRARY.arrays().triangles[LIBRARY.arrays().tri_start[mesh]]] * size
    world = verts + prims.centers[0]
    cam = (R[0] @ world.T).T + t
    uv = np.c_[f * cam[:, 0] / cam[:, 2] + w / 2, f * cam[:, 1] / cam[:, 2] + h / 2]
    jj, ii = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    p = np.stack([jj, ii], -1)

    def edge(a, b):
        return (b[0] - a[0]) * (p[..., 1] - a[1]) - (b[1] - a[1]) * (p[..., 0] - a[0])

    e = np.stack([edge(uv[0], uv[1]), edge(uv[1], uv[2]), edge(uv[2], uv[0])])
    inside = (e >= 0).all(axis=0) | (e <= 0).all(axis=0)
    margin = np.abs(e).min(axis=0) < 1e-6 * np.abs(e).max()  # pixel centres on an edge may go either way
    drawn = out["inst"][0] == 7
    assert inside.sum() > 300
    assert np.array_equal(drawn[~margin], inside[~margin])
    assert (out["sem"][0][drawn] == 8).all()  # the material's tag (traffic sign), not the instance's
    np.testing.assert_allclose(out["depth"][0][drawn], 3.5, atol=1e-5)  # a plane at x = 3.5: planar depth 3.5 m


def test_lidar_returns_of_mesh_vehicles_lie_inside_their_boxes_and_the_camera_sees_more_than_boxes():
    import gymnasium as gym

    import fog_gym  # noqa: F401
    from fog_gym.geometry import box_corners

    env = gym.make("FogDrive-v0", resolution=(320, 240), geometry="meshes", labels=None)
    env.reset(seed=4)
    for _ in range(3):
        env.step(1)
    base = env.unwrapped
    sem = base.points["SEM_LIDAR_TOP"]
    scene = base.scene
    v = scene.vehicles
    lidar_to_world = base._label_lidar_to_vehicle
    from fog_gym import geometry as geo

    world = (geo.yaw_transform(*scene.ego_pose) @ lidar_to_world @ np.c_[sem[:, :3], np.ones(len(sem))].T).T[:, :3]
    checked = 0
    for vid in np.unique(sem[:, 4]).astype(int):
        if vid == 0:
            continue
        k = int(np.flatnonzero(v.ids == vid)[0])
        pts = world[sem[:, 4] == vid]
        c, s = np.cos(v.yaws[k]), np.sin(v.yaws[k])
        d = pts - v.centers[k]
        local = np.c_[d[:, 0] * c + d[:, 1] * s, -d[:, 0] * s + d[:, 1] * c, d[:, 2]]
        assert (np.abs(local) <= v.sizes[k] / 2 + 1e-3).all(), vid  # the box is the mesh's bound
        checked += len(pts)
    assert checked > 50
    assert box_corners is not None
    env.close()


@settings(max_examples=20, deadline=None)
@given(st.floats(0, 2 * np.pi), st.floats(20, 70), st.floats(2, 12))
def test_a_shadow_falls_away_from_the_sun_as_long_as_the_caster_over_the_tangent_of_its_elevation(azimuth, elevation,
                                                                                                 height):  # fmt: skip
    from fog_gym.render.shadows import shadow_map

    e = np.radians(elevation)
    sun = np.array([np.cos(e) * np.cos(azimuth), np.cos(e) * np.sin(azimuth), np.sin(e)])
    pole = {"centers": [[0.0, 0.0, height / 2]], "halves": [[0.1, 0.1, height / 2]], "yaws": [0.0]}
    sm = shadow_map(pole, sun, (0.0, 0.0), half=60.0, resolution=0.1)
    rows, cols = np.nonzero(sm.grid)
    xy = np.c_[sm.origin[0] + (cols + 0.5) * 0.1, sm.origin[1] + (rows + 0.5) * 0.1]
    away = -sun[:2] / np.linalg.norm(sun[:2])
    along = xy @ away
    assert along.max() == pytest.approx(height / np.tan(e), abs=0.25)  # the caster's projected length
    assert along.min() > -0.3  # nothing on the sun's side beyond the pole's own footprint
    side = xy @ np.array([-away[1], away[0]])
    assert np.abs(side).max() < 0.3  # as wide as the pole


def test_shadows_darken_the_ground_only_and_leave_depth_and_tags_alone():
    import dataclasses

    import gymnasium as gym

    import fog_gym  # noqa: F401

    env = gym.make("FogDrive-v0", resolution=(320, 240), geometry="meshes", labels=None, cameras=["CAM_FRONT"])
    env.reset(seed=4)
    base = env.unwrapped
    scene = base.scene
    prims = base.cameras.primitives(scene)
    lit = base.cameras.render(scene, prims)["CAM_FRONT"]
    flat = base.cameras.render(dataclasses.replace(scene, geometry="boxes"), prims)["CAM_FRONT"]  # no shadow map
    np.testing.assert_array_equal(lit.depth, flat.depth)
    np.testing.assert_array_equal(lit.semantic, flat.semantic)
    np.testing.assert_array_equal(lit.instance, flat.instance)
    differ = np.any(lit.rgb != flat.rgb, axis=-1)
    assert differ.any() and (lit.instance[differ] == 0).all()  # only the ground changes
    assert (lit.rgb[differ].astype(int).sum(-1) < flat.rgb[differ].astype(int).sum(-1)).all()  # and only darker
    env.close()


def test_a_cached_shadow_window_equals_the_shadows_of_every_caster_filled_afresh():
    from fog_gym.render.shadows import ShadowCache, _fill

    rng = np.random.default_rng(3)
    n = 60
    static = Primitives.coerce({"centers": np.c_[rng.uniform(-150, 150, (n, 2)), rng.uniform(1, 6, n)],
                                "halves": rng.uniform(0.3, 4.0, (n, 3)), "yaws": rng.uniform(0, np.pi, n),
                                "meshes": rng.choice([0, body_mesh_id("sedan")], n)})  # fmt: skip
    moving = Primitives.coerce({"centers": [[5.0, 2.0, 0.8]], "halves": [[2.3, 0.9, 0.8]], "yaws": [0.4],
                                "meshes": [body_mesh_id("suv")]})  # fmt: skip
    sun = np.array([0.5, -0.3, 0.6])
    cache = ShadowCache(margin=20.0)
    for center in [(0.0, 0.0), (3.3, -7.9), (19.0, 4.0), (45.0, -30.0), (44.1, -29.05)]:  # within, then past the margin
        sm = cache.window(static, "town", moving, sun, center, half=40.0, resolution=0.25)
        assert abs(sm.origin[0] - (center[0] - 40.0)) <= 0.125 + 1e-9 and abs(sm.origin[1] - (center[1] - 40.0)) <= 0.125 + 1e-9
        fresh = _fill(np.zeros_like(sm.grid), Primitives.concat(static, moving), sun, *sm.origin, 0.25)
        assert sm.grid.any()
        np.testing.assert_array_equal(sm.grid, fresh)


@functools.cache
def _row_kernels():
    """A ground row drawn with a shadow lookup per pixel and per run (compiled once for the test below)."""
    from numba import njit

    from fog_gym.render.raster import _ground_colour, _ground_row

    @njit
    def per_pixel(rgb, sem, depth, width, fxw, fyw, kx, ky, flat, rows, cols, tx, lut, tags, shadow, x0, y0, k, dark):
        for j in range(width):
            gx = fxw + kx * j
            gy = fyw + ky * j
            r, g, b, tag = _ground_colour(gx, gy, flat, rows, cols, tx, lut, tags, shadow, x0 + k * gx, y0 + k * gy,
                                          dark)  # fmt: skip
            rgb[0, 0, j, 0], rgb[0, 0, j, 1], rgb[0, 0, j, 2], sem[0, 0, j] = r, g, b, tag
            depth[0, 0, j] = np.float32(7.0)

    @njit
    def per_run(rgb, sem, depth, width, fxw, fyw, kx, ky, flat, rows, cols, tx, lut, tags, shadow, x0, y0, k, dark):
        _ground_row(rgb, sem, depth, 0, 0, width, np.float32(7.0), fxw, fyw, kx, ky, flat, rows, cols, tx, lut, tags,
                    shadow, x0, y0, k, dark)

    return per_pixel, per_run


@given(kx=st.floats(-3.0, 3.0), ky=st.floats(-3.0, 3.0), fxw=st.floats(-50.0, 250.0), fyw=st.floats(-50.0, 250.0),
       sh_k=st.sampled_from([0.25, 0.5, 1.0, 2.5]), seed=st.integers(0, 2**16))  # fmt: skip
@settings(max_examples=60, deadline=None)
def test_a_ground_row_reads_the_shadow_map_per_run_and_colours_every_pixel_as_one_lookup_each(kx, ky, fxw, fyw, sh_k,
                                                                                            seed):  # fmt: skip
    """The day's ground rows read the shadow map once per run of pixels in one cell: the same colours, tags and
    depths as a lookup per pixel, for rows in every direction, steep and flat, entering and leaving the map."""
    rng = np.random.default_rng(seed)
    surface = tile_surface(rng.integers(0, 4, (200, 200)).astype(np.uint8), (0.0, 0.0), 0.5)
    shadow = (rng.random((60, 70)) < 0.3).astype(np.uint8)
    shadow[rng.integers(0, 60, 5)] = 1  # runs of shadow, not noise alone
    lut = rng.integers(0, 256, (4 * 16, 3)).astype(np.uint8)
    dark = (lut // 2).astype(np.uint8)
    tags = np.arange(4, dtype=np.uint8) + 10
    outs = []
    for f in _row_kernels():
        rgb, sem = np.zeros((1, 1, 300, 3), np.uint8), np.zeros((1, 1, 300), np.uint8)
        depth = np.zeros((1, 1, 300), np.float32)
        f(rgb, sem, depth, 300, fxw, fyw, kx, ky, surface.flat, surface.rows, surface.cols, surface.tiles_x, lut, tags,
          shadow, -3.0, -2.0, sh_k, dark)
        outs.append((rgb, sem, depth))
    for a, b in zip(*outs):
        np.testing.assert_array_equal(a, b)

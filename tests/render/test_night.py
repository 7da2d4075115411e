"""Night lighting: street lamps, low beams, auto-exposure, and the camera fog at night."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fog_gym.fog import add_glow, glow_sigma_px, night_airlight
from fog_gym.render import lights as L
from fog_gym.render.raster import render
from fog_gym.render.lights import headlights
from fog_gym.render.surface import albedo_lut, ground_lut, tiled_surface
from tests.render.reference_night import shade_night
from fog_gym.world.scenery import POLE_TAG, SIDEWALK_WIDTH, STYLES, LaneGeometry, Props, build_surface, lamp_heads, lit_edge_length, place_props  # fmt: skip
from tests.render.test_raster import front_rig, make_scene

UP = np.array([0.0, 0.0, 1.0])


def pole_props(xs, y=6.0):
    n = len(xs)
    return Props(np.c_[xs, np.full(n, y), np.full(n, 3.5)], np.tile([0.25, 0.25, 7.0], (n, 1)), np.zeros(n),
                 np.full((n, 3), 0.45), np.full(n, POLE_TAG, np.uint8))  # fmt: skip


# -- light model ----------------------------------------------------------------------------------------------
def test_lamp_irradiance_is_inverse_square_and_cosine_weighted():
    lamp = L.street_lamp_lights(np.array([[0.0, 0.0, 8.0]]))
    below = L.irradiance(np.zeros(3), UP, lamp)[0] / L.LAMP_COLOR[0]
    window = lambda d: (1 - (d / L.LAMP_RADIUS) ** 4) ** 2  # noqa: E731
    assert below == pytest.approx(L.LAMP_INTENSITY / 64 * window(8.0))
    # 6 m aside: d = 10 m, cos = 0.8
    aside = L.irradiance(np.array([6.0, 0.0, 0.0]), UP, lamp)[0] / L.LAMP_COLOR[0]
    assert aside == pytest.approx(L.LAMP_INTENSITY * 0.8 / 100 * window(10.0))
    # nothing beyond the radius, nothing on a face turned away, nothing above the head
    assert L.irradiance(np.array([L.LAMP_RADIUS, 0.0, 0.0]), UP, lamp).sum() == 0.0
    assert L.irradiance(np.zeros(3), -UP, lamp).sum() == 0.0
    assert L.irradiance(np.array([3.0, 0.0, 9.0]), np.array([-1.0, 0, 0]), lamp).sum() == 0.0


def test_low_beam_lights_a_cone_ahead_only():
    beam = L.headlight_lights(np.array([[0.0, 0.0, 0.75]]), np.array([[4.0, 2.0, 1.5]]), np.zeros(1), np.array([0.7]))
    facing = np.array([-1.0, 0.0, 0.0])  # a wall facing the car
    ahead = L.irradiance(np.array([20.0, 0.0, 0.7]), facing, beam)[0]
    assert ahead > 1.0
    assert L.irradiance(np.array([20.0, 20.0 * math.tan(math.radians(25)), 0.7]), facing, beam).sum() == 0.0
    assert L.irradiance(np.array([-20.0, 0.0, 0.7]), -facing, beam).sum() == 0.0  # behind
    assert L.irradiance(np.array([70.0, 0.0, 0.7]), facing, beam).sum() == 0.0  # beyond its range
    # the road ahead is lit from 5 m to ≈ 55 m, and more brightly at 15 m than 3 m aside of the cone's edge
    road = [L.irradiance(np.array([x, 0.0, 0.0]), UP, beam)[0] for x in (5.0, 15.0, 30.0, 45.0, 55.0)]
    assert min(road) > 0.0
    assert L.irradiance(np.array([15.0, 15.0 * math.tan(math.radians(21)), 0.0]), UP, beam)[0] < 0.2 * road[1]
    # a ray above the cut-off is dim: a sign 3 m up at 20 m gets far less than the wall at lamp height
    assert L.irradiance(np.array([20.0, 0.0, 3.7]), facing, beam)[0] < 0.01 * ahead


def test_headlights_sit_ahead_of_each_vehicle_along_its_heading():
    scene = make_scene([(5, 0, (10.0, 3.0), (4.5, 1.9, 1.5), math.pi / 2)], night=True)
    beams = headlights(scene.vehicles)
    assert len(beams) == 2  # the ego too
    np.testing.assert_allclose(beams.pos[1, :2], [10.0, 3.0 + 4.5 / 2 + 0.3], atol=1e-9)
    np.testing.assert_allclose(beams.axis[1], [0.0, 1.0, 0.0], atol=1e-9)


def test_lamp_heads_hang_over_the_road_at_pole_top():
    lane = LaneGeometry.straight((0, 0), (100, 0), width=4.0, line_types=(2, 2))
    surf = build_surface([lane], resolution=0.5)
    y = 2.0 + SIDEWALK_WIDTH + 0.6
    heads = lamp_heads(pole_props([20.0, 60.0], y=y), surf)
    np.testing.assert_allclose(heads[:, 2], 7.0)
    assert np.all(np.abs(heads[:, 1]) < 2.0)  # over the road
    heads_other_side = lamp_heads(pole_props([20.0], y=-y), surf)
    assert abs(heads_other_side[0, 1]) < 2.0
    assert lamp_heads(Props.empty(), surf).shape == (0, 3)


@pytest.mark.parametrize("style", sorted(STYLES))
def test_every_style_hangs_lamps_8_to_10_m_high_and_25_to_40_m_apart_as_real_roads(style):
    lane = LaneGeometry.straight((0, 0), (400, 0), width=4.0, line_types=(2, 2))
    surf = build_surface([lane], resolution=0.5)
    props = place_props([lane], surf, np.random.default_rng(1), STYLES[style])
    heads = lamp_heads(props, surf)
    assert len(heads) >= 2 * (400 // 40)
    np.testing.assert_allclose(heads[:, 2], STYLES[style].pole_height)  # at the pole's top
    assert 8.0 <= STYLES[style].pole_height <= 10.0 and 25.0 <= STYLES[style].pole_spacing <= 40.0
    for side in (heads[:, 1] > 0, heads[:, 1] < 0):  # consecutive lamps along each road edge
        gaps = np.diff(np.sort(heads[side, 0]))
        np.testing.assert_allclose(gaps, STYLES[style].pole_spacing, atol=1.0)
    assert 25.0 <= lit_edge_length([lane], surf) / len(heads) <= 40.0
    poles = props.tags == POLE_TAG  # the poles are geometry of that height
    np.testing.assert_allclose(props.centers[poles, 2] + props.sizes[poles, 2] / 2, STYLES[style].pole_height)


def test_a_style_refuses_a_pole_of_no_height():
    from fog_gym.world.scenery import SceneryStyle

    with pytest.raises(ValueError, match="pole_height"):
        SceneryStyle(pole_height=0.0)


# -- exposure -------------------------------------------------------------------------------------------------
@settings(max_examples=25, deadline=None)
@given(st.floats(1e-3, 0.1), st.floats(1.5, 4.0))
def test_exposure_is_scale_invariant_within_its_limits(level, factor):
    rng = np.random.default_rng(0)
    lin = (rng.uniform(0.5, 1.5, (1, 16, 16, 3)) * level).astype(np.float32)
    g1, g2 = L.exposure_gains(lin)[0], L.exposure_gains(lin * factor)[0]
    assert L.GAIN_MIN <= g2 <= g1 <= L.GAIN_MAX
    if L.GAIN_MIN < g2 and g1 < L.GAIN_MAX:  # both unclamped: the exposed image is the same (up to histogram bins)
        assert g1 / g2 == pytest.approx(factor, rel=0.15)


def test_exposure_ignores_the_darkest_half_and_a_few_bright_sources():
    lin = np.full((1, 20, 20, 3), 0.05, np.float32)
    lin[0, :10] = 0.0  # black sky: half the frame
    base = L.exposure_gains(lin)[0]
    lin[0, 19, :4] = 50.0  # four lamp pixels (1 %)
    assert L.exposure_gains(lin)[0] == pytest.approx(base, rel=0.05)
    assert base * 0.05 == pytest.approx(L.KEY, rel=0.1)


# -- rendering ------------------------------------------------------------------------------------------------
def road_pixel(rig, scene, x, y):
    """Image (row, col) of the ground point (x, y) seen by the rig's front camera."""
    T = rig.world_to_camera(scene, "CAM_FRONT")
    p = T @ np.array([x, y, 0.0, 1.0])
    K = rig.intrinsics["CAM_FRONT"]
    return int(K[1, 1] * p[1] / p[2] + K[1, 2]), int(K[0, 0] * p[0] / p[2] + K[0, 2])


def test_road_is_brighter_under_a_lamp_than_between_lamps():
    rig = front_rig(320, 240)
    scene = make_scene(night=True, props=pole_props([30.0, 100.0], y=6.0))
    frame = rig.render(scene)["CAM_FRONT"]
    lum = frame.rgb.astype(float).sum(axis=2)
    heads = lamp_heads(scene.static.props, scene.static.surface)
    under = lum[road_pixel(rig, scene, heads[0, 0], heads[0, 1])]
    between = lum[road_pixel(rig, scene, 65.0, heads[0, 1])]
    assert under > 3 * between


def test_ego_beam_lights_the_road_ahead_not_beside():
    rig = front_rig(320, 240)
    scene = make_scene(night=True)
    frame = rig.render(scene)["CAM_FRONT"]
    lum = frame.rgb.astype(float).sum(axis=2)
    ahead = lum[road_pixel(rig, scene, 15.0, 0.0)]
    beside = lum[road_pixel(rig, scene, 15.0, 12.0)]  # 39° off the axis: outside the ±22° cone
    assert ahead > 2.5 * beside


def test_day_render_does_not_depend_on_the_lighting_pass():
    """The face-id buffers of the lighting pass leave every day channel as the plain render makes it."""
    rig = front_rig(160, 120)
    scene = make_scene([(5, 0, (12.0, 1.0), (4.5, 1.9, 1.5), 0.3)], props=pole_props([20.0]))
    prims = rig.primitives(scene)
    T = rig.world_to_camera(scene, "CAM_FRONT")[None]
    K = rig.intrinsics["CAM_FRONT"]
    ks = np.array([[K[0, 0], K[1, 1], K[0, 2], K[1, 2]]])
    light = scene.lighting
    args = (T[:, :3, :3], T[:, :3, 3], ks, 160, 120, rig.far, prims, tiled_surface(scene.static), ground_lut(light),
            np.array([10, 1, 2, 24], np.uint8), light.sky_horizon, light.sky_zenith, light.sun_dir, light.ambient,
            light.sun_intensity)  # fmt: skip
    plain, with_ids = render(*args), render(*args, face_ids=True)
    for k in ("rgb", "depth", "sem", "inst"):
        assert np.array_equal(plain[k], with_ids[k])
    frame = rig.render(scene)["CAM_FRONT"]
    assert np.array_equal(frame.rgb, plain["rgb"][0]) and rig.exposure["CAM_FRONT"] == 1.0
    # faces the buffer names are the ones the instance buffer shows
    seen = with_ids["face"][0] >= 0
    assert np.array_equal(seen, with_ids["inst"][0] > 0) or seen.sum() >= (with_ids["inst"][0] > 0).sum()


def test_same_seed_same_night_image_and_geometry_unchanged_by_lights():
    from fog_gym.envs.fogdrive import FogDriveEnv

    def run(tod):
        env = FogDriveEnv(town="highway", time_of_day=tod, resolution=(96, 72), cameras=["CAM_FRONT"], labels=None)
        env.reset(seed=11)
        env.step(1)
        f = env.frames["CAM_FRONT"]
        env.close()
        return f, env.points

    (a, pa), (b, _), (day, pday) = run("night"), run("night"), run("day")
    assert np.array_equal(a.rgb, b.rgb)
    for k in ("depth", "semantic", "instance"):
        assert np.array_equal(getattr(a, k), getattr(day, k))
    assert pa.keys() == pday.keys() and all(np.array_equal(pa[k], pday[k]) for k in pa)
    assert a.rgb.mean() > 0.15 * day.rgb.mean()  # a night a camera can see in


def test_ground_light_map_matches_the_point_evaluation():
    lamps = L.street_lamp_lights(np.array([[10.0, 5.0, 7.0]]))
    m = L.lamp_light_map(lamps, (0.0, 40.0, -10.0, 20.0), resolution=0.5)
    i, j = 30, 21  # cell centre (10.75, 5.25)
    expected = L.irradiance(np.array([10.75, 5.25, 0.01]), UP, lamps)
    np.testing.assert_allclose(m.irradiance[i, j], expected, rtol=1e-5)
    beams = L.headlight_lights(np.array([[0.0, 5.0, 0.75]]), np.array([[4.0, 2.0, 1.5]]), np.zeros(1), np.array([0.7]))
    w = L.beam_window(m, beams, np.array([10.0, 5.0]), half=8.0)
    k = np.argwhere(w.irradiance.sum(axis=2) > m.irradiance.max() * 2)  # the beam adds to the lamp's pool
    assert len(k) and np.all(w.origin[0] + (k[:, 1] + 0.5) * 0.5 > 2.0)  # only ahead of the car


def test_shade_night_names_missing_buffers():
    with pytest.raises(ValueError, match="face_ids=True"):
        shade_night(np.eye(3)[None], np.zeros((1, 3)), np.ones((1, 4)), 100.0,
                      {"rgb": np.zeros((1, 2, 2, 3), np.uint8), "depth": np.zeros((1, 2, 2), np.float32)}, {},
                      L.street_lamp_lights(np.zeros((0, 3))), (L.GroundLightMap.empty(),) * 2, np.zeros((0, 3)))


# -- fog at night ---------------------------------------------------------------------------------------------
def test_night_airlight_comes_from_the_lit_surroundings():
    rgb = np.zeros((10, 10, 3), np.uint8)
    depth = np.full((10, 10), 1000.0, np.float32)
    rgb[5:], depth[5:] = 60, 12.0  # lit road near the camera
    rgb[0, 0] = 255  # a lamp head against the sky does not set the airlight
    assert night_airlight(rgb, depth).tolist() == [60.0, 60.0, 60.0]
    with pytest.raises(ValueError, match="depth"):
        night_airlight(rgb, depth[:5])


def test_glow_grows_in_width_and_strength_with_alpha():
    K = np.array([[200.0, 0, 40.0], [0, 200.0, 40.0], [0, 0, 1]])
    clean = np.zeros((80, 80, 3), np.uint8)
    clean[39:41, 39:41] = 255
    depth = np.full((80, 80), 40.0, np.float32)
    base = np.zeros_like(clean)
    light, dense = (add_glow(base, clean, depth, K, a).astype(int)[..., 0] for a in (math.log(20) / 160, math.log(20) / 50))
    assert glow_sigma_px(K, math.log(20) / 50) > glow_sigma_px(K, math.log(20) / 160)
    assert dense.sum() > light.sum() > 0
    assert dense[40, 52] > light[40, 52]  # wider
    assert np.array_equal(add_glow(base, clean, depth, K, 0.0), base)  # clear air: no glow
    # symmetric about the source
    assert dense[40, 30] == dense[40, 49] or abs(int(dense[40, 30]) - int(dense[40, 49])) <= 1


def test_fog_wrapper_at_night_keeps_koschmieder_and_adds_glow():
    from fog_gym.envs.fogdrive import FogDriveEnv
    from wrappers.fog import FogWrapper

    base = FogDriveEnv(town="highway", time_of_day="night", resolution=(96, 72), cameras=["CAM_FRONT"], labels=None)
    env = FogWrapper(base, fog=["dense"])  # paired: clean and fogged channels
    obs, _ = env.reset(seed=3)
    clean = obs["CAM_FRONT"]
    fogged = obs["CAM_FRONT_FOG_DENSE"]
    depth = obs["CAM_FRONT_DEPTH"]
    A = env.airlight["CAM_FRONT"]
    assert np.all(A < 255) and np.array_equal(A, night_airlight(clean, depth))
    far = depth >= 500
    # far away the fog shows its (lit) airlight, not the black sky
    assert np.abs(fogged[far].astype(float).mean(axis=0) - A).max() < 25
    env.close()


def _night_call(width, height):
    """A lit night scene (a car, two lamp poles) on the front camera: (render arguments up to the lights, lights,
    ground maps, lamp heads, camera rotation, translation, intrinsics, rig, primitives)."""
    rig = front_rig(width, height)
    scene = make_scene([(5, 0, (14.0, 3.5), (4.5, 1.9, 1.5), 0.2)], night=True, props=pole_props([12.0, 50.0]))
    prims = rig.primitives(scene)
    heads, lights, ground = rig.night_lights(scene)
    T = rig.world_to_camera(scene, "CAM_FRONT")[None]
    K = rig.intrinsics["CAM_FRONT"]
    ks = np.array([[K[0, 0], K[1, 1], K[0, 2], K[1, 2]]])
    light = scene.lighting
    common = (T[:, :3, :3], T[:, :3, 3], ks, width, height, rig.far, prims, tiled_surface(scene.static), albedo_lut(),
              np.array([10, 1, 2, 24], np.uint8), light.sky_horizon, light.sky_zenith)  # fmt: skip
    return common, lights, ground, heads, T, ks, rig, prims


def test_fused_night_render_matches_the_two_pass_reference():
    """render_night lights pixels as they are drawn; shade_night lights an albedo render afterwards: same image."""
    common, lights, ground, heads, T, ks, rig, prims = _night_call(160, 120)
    fused, gains = L.render_night(*common, lights, ground, heads)
    ref = render(*common, np.array([0.0, 0, -1]), 1.0, 0.0, face_ids=True)
    shade_night(T[:, :3, :3], T[:, :3, 3], ks, rig.far, ref, prims, lights, ground, heads, gains=gains)
    for k in ("depth", "sem", "inst"):
        assert np.array_equal(fused[k], ref[k])
    diff = np.abs(fused["rgb"].astype(int) - ref["rgb"].astype(int)).max(axis=-1)
    assert (diff <= 2).mean() > 0.99 and fused["rgb"].mean() > 20
    # the exposure measured on the small render is close to the one of the full-size image
    assert L.GAIN_MIN <= gains[0] <= L.GAIN_MAX


def test_timing_a_night_render_leaves_its_image_unchanged_and_names_every_phase():
    args, lights, ground, heads, *_ = _night_call(96, 72)
    common = (*args, lights, ground, heads)
    plain, g0 = L.render_night(*common)
    phases: dict[str, float] = {}
    timed, g1 = L.render_night(*common, timings=phases)
    assert np.array_equal(g0, g1) and all(np.array_equal(plain[k], timed[k]) for k in plain)
    assert list(phases) == ["light set-up", "exposure", "lit render", "lamp heads"]
    assert all(v >= 0.0 for v in phases.values())

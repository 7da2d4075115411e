"""Property tests (hypothesis) over the pure functions users call with their own data: fog, projection and box
labelling, point unpacking, and the command line's argument parsing. Any input either works — finite results
of the right shape — or fails early with a clear ``ValueError`` (argparse: exit status 2)."""

import argparse
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from fog_gym import geometry
from fog_gym.cli import _resolution, build_parser
from fog_gym.fog import alpha_from_visibility, fog_image, fog_lidar, parse_fog
from fog_gym.labels.boxes import boxes_2d
from fog_gym.dataset.packing import COLUMNS, pack_points, unpack_points

FAST = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
visibilities = st.floats(min_value=1e-3, max_value=1e7, allow_nan=False, allow_infinity=False)
depth_values = st.one_of(st.just(0.0), st.just(1000.0), st.floats(0.0, 2000.0, width=32))


@FAST
@given(visibility=visibilities, h=st.integers(1, 6), w=st.integers(1, 6), data=st.data())
def test_camera_fog_keeps_each_pixel_between_its_colour_and_the_airlight(visibility, h, w, data):
    rgb = data.draw(arrays(np.uint8, (h, w, 3)))
    depth = data.draw(arrays(np.float32, (h, w), elements=depth_values))
    airlight = np.array(data.draw(st.lists(st.floats(0, 255), min_size=3, max_size=3)))
    K = geometry.intrinsic_matrix(w, h, 90.0)
    out = fog_image(rgb, depth, K, alpha_from_visibility(visibility), airlight)
    assert out.shape == rgb.shape and out.dtype == np.uint8
    lo = np.minimum(rgb, np.floor(airlight)).astype(int) - 1
    hi = np.maximum(rgb, np.ceil(airlight)).astype(int) + 1
    assert ((out >= lo) & (out <= hi)).all()
    assert np.array_equal(out[depth == 0], rgb[depth == 0])  # no air between camera and pixel: unchanged


@FAST
@given(bad=st.sampled_from([np.nan, np.inf, -1.0]))
def test_camera_fog_refuses_bad_depth(bad):
    depth = np.full((2, 2), 10.0, np.float32)
    depth[0, 1] = bad
    with pytest.raises(ValueError, match="depth must be finite"):
        fog_image(np.zeros((2, 2, 3), np.uint8), depth, geometry.intrinsic_matrix(2, 2, 90.0), 0.03, np.full(3, 200.0))


@FAST
@given(v=st.one_of(st.floats(max_value=0.0), st.just(math.nan), st.text(max_size=8), st.booleans(), st.none()))
def test_bad_visibilities_are_a_clear_value_error(v):
    assume(not (isinstance(v, str) and v.strip().lower() in ("clear", "light", "moderate", "dense")))
    with pytest.raises(ValueError, match="fog"):
        parse_fog(v)


@FAST
@given(visibility=visibilities, seed=st.integers(0, 2**32 - 1), data=st.data())
def test_lidar_fog_keeps_the_point_count_and_finite_intensities_in_0_1(visibility, seed, data):
    n = data.draw(st.integers(0, 40))
    xyz = data.draw(arrays(np.float32, (n, 3), elements=st.floats(-150, 150, width=32)))
    inten = data.draw(arrays(np.float32, (n, 1), elements=st.floats(0, 1, width=32)))
    pts = np.concatenate([xyz, inten], axis=1)
    out = fog_lidar(pts, parse_fog(visibility), np.random.default_rng(seed))
    assert out.shape == pts.shape and out.dtype == np.float32 and np.isfinite(out).all()
    assert ((out[:, 3] >= 0) & (out[:, 3] <= 1)).all()
    r_in, r_out = np.linalg.norm(pts[:, :3], axis=1), np.linalg.norm(out[:, :3], axis=1)
    ok = (r_in > 1e-3) & (r_out > 1e-3)  # every point stays on its own ray (a fog return moves along it)
    cos = (pts[ok, :3] * out[ok, :3]).sum(axis=1) / (r_in[ok] * r_out[ok])
    assert (cos > 0.999).all()
    with pytest.raises(ValueError, match="finite"):
        fog_lidar(np.array([[np.nan, 0, 0, 1]], np.float32), parse_fog("dense"), np.random.default_rng(0))


boxes = st.tuples(
    st.floats(-300, 300), st.floats(-300, 300), st.floats(-5, 5),  # centre: ahead, behind, beside, far outside
    st.floats(0.1, 20), st.floats(0.1, 5), st.floats(0.1, 5), st.floats(-4, 4),  # l, w, h, yaw
)


@FAST
@given(st.lists(boxes, min_size=0, max_size=8), st.sampled_from(["CAM_FRONT", "CAM_LEFT", "CAM_BACK"]))
def test_box_projection_never_leaves_the_image_or_makes_nan(box_list, camera):
    from fog_gym.sensors.rig import RigConfig

    cam = {c.name: c for c in RigConfig.fogdrive(resolution=(64, 48)).cameras}[camera]
    arr = np.array(box_list, np.float64).reshape(-1, 7)
    corners = geometry.box_corners(arr[:, :3], arr[:, 3:6], arr[:, 6])
    p = cam.pose
    E = geometry.lidar_to_camera(geometry.transform_matrix((0, 0, 2.0), (0, 0, 0)),
                                 geometry.transform_matrix((p.x, p.y, p.z), (p.pitch, p.roll, p.yaw)))
    out = boxes_2d(corners, E, geometry.intrinsic_matrix(64, 48, 100.0), 64, 48)
    b = out["bboxes"][out["in_view"]]
    assert ((b[..., 0] >= 0) & (b[..., 0] <= 63) & (b[..., 1] >= 0) & (b[..., 1] <= 47)).all()
    assert (b[:, 0] <= b[:, 1]).all()  # min corner before max corner
    assert np.isfinite(out["truncation"]).all() and ((out["truncation"] >= 0) & (out["truncation"] <= 1)).all()
    behind = (geometry.transform_points(E, corners.reshape(-1, 3)).reshape(-1, 8, 3)[..., 2] <= 0.05).all(axis=1)
    assert not out["in_view"][behind].any()  # wholly behind the near plane: never annotated
    with pytest.raises(ValueError, match="finite"):
        boxes_2d(np.full((1, 8, 3), np.nan), E, geometry.intrinsic_matrix(64, 48, 100.0), 64, 48)


@FAST
@given(channel=st.sampled_from(["LIDAR_TOP", "LIDAR_TOP_FOG_DENSE", "SEM_LIDAR_TOP", "RADAR_FRONT"]), data=st.data())
def test_unpack_points_inverts_pack_points(channel, data):
    cols = COLUMNS["LIDAR_TOP" if channel.startswith("LIDAR") else channel]
    n = data.draw(st.integers(0, 20))
    pts = data.draw(arrays(np.float32, (n, cols), elements=st.floats(-200, 200, width=32)))
    real = pts[:, 3] != 0 if channel == "RADAR_FRONT" else np.any(pts[:, :3] != 0, axis=1)
    pts = pts[real]  # a real return is never all-zero (range > 0; radar depth > 0)
    extra = data.draw(st.integers(0, 5))
    packed = pack_points(pts, len(pts) + extra)
    assert np.array_equal(unpack_points({channel: packed}, channel), pts)
    with pytest.raises(ValueError):
        pack_points(pts, len(pts) - 1) if len(pts) else unpack_points(np.zeros(3), channel)


@FAST
@given(channel=st.sampled_from(["LIDAR_TOP", "RADAR_FRONT", None]), data=st.data())
def test_unpack_points_keeps_every_point_in_order_however_the_rows_lie(channel, data):
    """The one-pass reader (which stops at the first empty row when all after it is zero) against a brute-force mask,
    on channels with empty rows anywhere, tails that are empty for the rule but not zero, and column views."""
    rows = data.draw(st.integers(0, 30))
    cols = data.draw(st.integers(4, 6))
    values = st.sampled_from([0.0, -0.0, 1.5, -3.0, float("nan")])
    array = data.draw(arrays(np.float32, (rows, cols), elements=values))
    valid = (array[:, 3] != 0 if channel == "RADAR_FRONT" else np.any(array[:, :3] != 0, axis=1)) if channel else \
        np.any(array != 0, axis=1)  # fmt: skip
    columns = data.draw(st.one_of(st.none(), st.integers(1, cols)))
    got = unpack_points(array, channel, columns=columns)
    assert np.array_equal(got, array[valid][:, :columns], equal_nan=True)
    assert got.flags.c_contiguous and got.dtype == np.float32 and not np.shares_memory(got, array)
    seen = unpack_points(array, channel, columns=columns, copy=False)  # the same points; in place when packed
    assert np.array_equal(seen, got, equal_nan=True)
    packed = len(got) == 0 or np.array_equal(array[: len(got)][:, :columns], got, equal_nan=True) and not valid[len(got):].any()
    if len(got) and packed and not np.any(array[len(got):] != 0):  # a packed channel (zeros after its points)
        assert np.shares_memory(seen, array)
    if cols > 4:  # the same through a view of the leading columns (not contiguous)
        view = array[:, :4]
        keep = np.any(view != 0, axis=1) if channel is None else valid
        assert np.array_equal(unpack_points(view, channel), view[keep], equal_nan=True)


@FAST
@given(st.one_of(st.integers(-3, 0), st.floats(), st.booleans(), st.text(max_size=3)))
def test_unpack_points_refuses_a_bad_column_count(columns):
    with pytest.raises(ValueError, match=r"^columns must be a positive number of leading columns or None"):
        unpack_points(np.zeros((3, 4), np.float32), "LIDAR_TOP", columns=columns)
    if not isinstance(columns, bool):
        with pytest.raises(ValueError, match=r"^copy must be True or False"):
            unpack_points(np.zeros((3, 4), np.float32), "LIDAR_TOP", copy=columns)


@FAST
@given(st.text(max_size=12))
def test_resolution_argument_is_two_positive_ints_or_a_clear_error(text):
    try:
        w, h = _resolution(text)
    except argparse.ArgumentTypeError as e:
        assert "resolution must" in str(e)
    else:
        assert w > 0 and h > 0 and isinstance(w, int) and isinstance(h, int)


@settings(max_examples=80, deadline=None)
@given(st.lists(st.sampled_from(["demo", "generate", "validate", "stats", "audit", "--root", "x", "--scenes", "-3",
                                 "2", "--resolution", "0x0", "64x48", "--fog", "dense", "0", "-1", "nan", "--steps",
                                 "--workers", "--towns", "Town01", "highway", "--seconds", "--plot", "--help"]),
                max_size=7))  # fmt: skip
def test_cli_parsing_accepts_or_exits_with_usage_never_crashes(argv):
    try:
        ns = build_parser().parse_args(argv)
    except SystemExit as e:
        assert e.code in (0, 2)  # --help, or argparse's usage error
    else:
        assert ns.command in ("demo", "generate", "validate", "stats", "audit", "bench")
        if getattr(ns, "resolution", None) is not None:
            assert min(ns.resolution) > 0

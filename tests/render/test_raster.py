"""Camera geometry and content, on hand-built scenes with known answers."""

import numpy as np
import pytest

from fog_gym import geometry as g
from fog_gym.sensors.camera import CameraConfig
from fog_gym.geometry import Pose
from fog_gym.sensors.rig import RigConfig
from fog_gym.world.scene import Lighting, Scene, StaticWorld, vehicle_primitives
from fog_gym.world.scenery import Props, SurfaceMap
from fog_gym.render.surface import ground_lut, tiled_surface
from fog_gym.sensors import CameraRig
from fog_gym.world.fleet import VehicleState

W, H = 320, 240


def make_scene(vehicles=(), night=False, props=None, ego_pose=(0.0, 0.0, 0.0)):
    """Road everywhere within ±200 m; vehicles = [(id, class, (x, y), (l, w, h), yaw)]; ego (id 1) at the origin."""
    grid = np.ones((400, 400), np.uint8)
    surface = SurfaceMap(grid, (-200.0, -200.0), 1.0)
    rows = [(1, 0, ego_pose[:2], (4.79, 2.16, 1.49), ego_pose[2])] + list(vehicles)
    state = VehicleState(
        np.array([r[0] for r in rows], np.int32),
        np.array([r[1] for r in rows], np.int8),
        np.array([(r[2][0], r[2][1], r[3][2] / 2) for r in rows], float),
        np.array([r[3] for r in rows], float),
        np.array([r[4] for r in rows], float),
        np.zeros((len(rows), 3)),
        np.full((len(rows), 3), 0.6),
    )
    light = Lighting.for_time_of_day("night" if night else "day", np.random.default_rng(0))
    return Scene(0.0, 1, ego_pose, state, StaticWorld.build(surface, props or Props.empty()), light,
                 vehicle_primitives(state, night, exclude_id=1))  # fmt: skip


def front_rig(w=W, h=H, pose=Pose(1.8, 0, 1.2)):
    return CameraRig(RigConfig((CameraConfig("CAM_FRONT", pose, w, h, 100.0),)))


def render_boxes(rig, scene, prims):
    """Render raw primitives (no vehicle parts) with the rig's front camera."""
    from fog_gym.render.raster import render

    M = rig.world_to_camera(scene, "CAM_FRONT")
    K = rig.intrinsics["CAM_FRONT"]
    light = scene.lighting
    return render(M[None, :3, :3], M[None, :3, 3], np.array([[K[0, 0], K[1, 1], K[0, 2], K[1, 2]]]), W, H, 1000.0,
                  prims, tiled_surface(scene.static), ground_lut(light), np.array([10, 1, 2, 24], np.uint8),
                  light.sky_horizon, light.sky_zenith, light.sun_dir, light.ambient, light.sun_intensity)  # fmt: skip


def test_flat_road_depth_is_analytic():
    rig = front_rig()
    f = rig.render(make_scene())["CAM_FRONT"]
    K = rig.intrinsics["CAM_FRONT"]
    rows = np.arange(H // 2 + 1, H)
    expected = K[1, 1] * 1.2 / (rows + 0.5 - K[1, 2])
    np.testing.assert_allclose(f.depth[rows, :], np.repeat(expected[:, None], W, 1), rtol=1e-6)
    assert np.all(f.depth[: H // 2] == 1000.0)  # sky above the horizon
    assert set(np.unique(f.semantic[: H // 2])) == {11}
    near = f.depth < 150  # the road map covers ±200 m; terrain beyond
    assert set(np.unique(f.semantic[near & (np.arange(H)[:, None] >= H // 2)])) == {1}


def test_tilted_camera_ground_depth():
    """Pitched and rolled camera: every ground pixel's depth puts its 3D point on z = 0."""
    pose = Pose(0.0, 0.0, 2.0, pitch=-15.0, roll=7.0, yaw=20.0)
    rig = front_rig(pose=pose)
    f = rig.render(make_scene())["CAM_FRONT"]
    K = rig.intrinsics["CAM_FRONT"]
    v, u = np.nonzero(f.semantic == 1)
    z = f.depth[v, u].astype(np.float64)
    pc = np.c_[(u + 0.5 - K[0, 2]) / K[0, 0] * z, (v + 0.5 - K[1, 2]) / K[1, 1] * z, z]
    cam_to_world = np.linalg.inv(rig.world_to_camera(make_scene(), "CAM_FRONT"))
    np.testing.assert_allclose(g.transform_points(cam_to_world, pc)[:, 2], 0.0, atol=2e-4 * z.max())


def test_box_projects_where_K_predicts():
    """A lone box's visible face: the pixel K predicts holds its id, at the exact planar depth."""
    rig = front_rig()
    scene = make_scene()
    M = rig.world_to_camera(scene, "CAM_FRONT")
    K = rig.intrinsics["CAM_FRONT"]
    prims = {
        "centers": np.array([[22.0, 3.0, 1.0]]), "halves": np.array([[2.0, 1.0, 1.0]]), "yaws": np.array([0.0]),
        "colors": np.array([[1.0, 0.0, 0.0]]), "tags": np.array([14], np.uint8), "insts": np.array([7], np.uint16),
        "emissive": np.array([False]),
    }  # fmt: skip
    out = render_boxes(rig, scene, prims)
    inst, depth = out["inst"][0], out["depth"][0]
    # rear face (x = 20) is planar depth 20 − 1.8 = 18.2 from the camera
    corners_world = g.box_corners(prims["centers"], 2 * prims["halves"], prims["yaws"])[0]
    uv = g.project_points(K, g.transform_points(M, corners_world))
    rear = corners_world[:, 0] < 21
    centre_uv = g.project_points(K, g.transform_points(M, np.array([[20.0, 3.0, 1.0]])))[0]
    j, i = int(np.floor(centre_uv[0])), int(np.floor(centre_uv[1]))
    assert inst[i, j] == 7 and depth[i, j] == pytest.approx(18.2, abs=1e-4)
    assert out["sem"][0][i, j] == 14
    # the id mask's extent matches the projected corners to within one pixel
    vv, uu = np.nonzero(inst == 7)
    assert abs(uu.min() + 0.5 - uv[:, 0].min()) <= 1 and abs(uu.max() + 0.5 - uv[:, 0].max()) <= 1
    assert abs(vv.min() + 0.5 - uv[:, 1].min()) <= 1 and abs(vv.max() + 0.5 - uv[:, 1].max()) <= 1
    assert rear.sum() == 4


def test_box_crossing_near_plane_is_clipped_not_exploded():
    """A long box that starts behind the camera and ends in front covers only what it should."""
    rig = front_rig()
    scene = make_scene()
    prims = {
        "centers": np.array([[2.0, 2.5, 0.75]]), "halves": np.array([[5.0, 1.0, 0.75]]), "yaws": np.array([0.0]),
        "colors": np.array([[0.5, 0.5, 0.5]]), "tags": np.array([14], np.uint8), "insts": np.array([9], np.uint16),
        "emissive": np.array([False]),
    }  # fmt: skip
    out = render_boxes(rig, scene, prims)
    mask = out["inst"][0] == 9
    assert mask.any()
    cols = np.nonzero(mask.any(axis=0))[0]
    assert cols.min() > W // 2  # entirely on the right half: it is to the camera's right
    assert np.all(out["depth"][0][mask] > 0.05)


def test_ego_body_is_never_drawn_and_ids_are_vehicles():
    rig = CameraRig(RigConfig.fogdrive(resolution=(W, H)))
    scene = make_scene([(5, 0, (15.0, 0.0), (4.5, 1.9, 1.5), 0.0), (6, 1, (-14.0, 0.0), (9.0, 2.5, 3.4), 0.0)])
    frames = rig.render(scene)
    assert not any((f.instance == 1).any() for f in frames.values())
    assert set(np.unique(frames["CAM_FRONT"].instance)) == {0, 5}
    assert set(np.unique(frames["CAM_BACK"].instance)) == {0, 6}
    assert set(np.unique(frames["CAM_BACK"].semantic[frames["CAM_BACK"].instance == 6])) == {15}  # truck


def test_night_keeps_geometry_channels_and_tail_lamps_glow():
    vehicles = [(5, 0, (10.0, 0.0), (4.5, 1.9, 1.5), 0.0)]
    rig = front_rig(640, 480)
    day = rig.render(make_scene(vehicles))["CAM_FRONT"]
    night = rig.render(make_scene(vehicles, night=True))["CAM_FRONT"]
    assert np.array_equal(day.depth, night.depth) and np.array_equal(day.semantic, night.semantic)
    assert np.array_equal(day.instance, night.instance)
    lamps = night.rgb[night.instance == 5]
    assert (lamps[:, 0] >= 250).sum() >= 4  # red tail lamps of the car ahead glow
    sky = night.depth >= rig.far
    assert night.rgb[sky].mean() < 0.1 * day.rgb[sky].mean()  # the night sky stays dark

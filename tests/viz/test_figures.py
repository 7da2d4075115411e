"""Pictures for people: the bird's-eye view keeps every lane marking; every demo figure has a title, labelled panels,
a colour bar with units for each continuous quantity, a legend naming exactly the classes shown, labelled range
rings; the demo writes its four figures and the night one shows the zoom on the lights."""

import numpy as np

from fog_gym.world.scenery import MARKING
from fog_gym.render.birds_eye import _BEV_COLORS, birds_eye_view
from fog_gym.viz import figures


def test_bev_shows_every_marking_a_fine_scan_crosses(small_env):
    scene = small_env.scene
    size, metres = 480, 100.0
    img = birds_eye_view(scene, size, metres)
    is_marking = np.all(img == _BEV_COLORS[MARKING], axis=-1)
    x, y, yaw = scene.ego_pose
    c, s = np.cos(yaw), np.sin(yaw)
    px = metres / size
    checked = 0
    for row in range(40, size - 40, 37):  # scan rows across the road at 1 cm steps: every marking crossing
        fwd = -(row + 0.5 - size / 2) * px
        right = np.arange(-metres / 2, metres / 2, 0.01)
        cls = scene.static.surface.class_at(x + fwd * c - right * s, y + fwd * s + right * c)
        for k in np.flatnonzero(cls == MARKING):
            col = int((right[k] + metres / 2) / px)
            assert is_marking[row, max(col - 1, 0) : col + 2].any(), (row, col)
            checked += 1
    assert checked > 50  # the highway's lines were crossed many times


def _texts(fig) -> list[str]:
    return [t.get_text() for ax in fig.axes for t in ax.texts]


def _colorbar_labels(fig) -> list[str]:
    return [ax.get_ylabel() or ax.get_xlabel() for ax in fig.axes if ax.get_label() == "<colorbar>"]


def test_fog_levels_figure_labels_columns_rows_rings_and_its_intensity_bar():
    rng = np.random.default_rng(0)
    rgb = rng.integers(0, 255, (30, 40, 3), dtype=np.uint8)
    pts = np.column_stack([rng.uniform(-40, 40, (500, 3)), rng.uniform(0, 1, 500)]).astype(np.float32)
    fogged = pts.copy()
    fogged[:7, :3] *= 0.5  # seven points moved into the fog
    fig = figures.fog_levels_figure({"clear": {"rgb": rgb, "lidar": pts}, "dense (50 m)": {"rgb": rgb, "lidar": fogged}},
                                    "the title", metres=100.0)  # fmt: skip
    assert fig._suptitle.get_text() == "the title"
    titles = [ax.get_title() for ax in fig.axes]
    assert titles[:2] == ["clear", "dense (50 m)"]  # column headings
    assert "500 points" in titles and "500 points, 7 fog returns" in titles
    assert fig.axes[0].get_ylabel() == "CAM_FRONT (RGB)"
    assert sorted(set(_texts(fig))) == ["20 m", "40 m"]  # rings every 20 m inside the 100 m view
    assert _colorbar_labels(fig) == ["LiDAR intensity (CARLA: exp(−0.004 · d))"]
    night = figures.fog_levels_figure({"clear": {"rgb": rgb, "lidar": pts}}, "t", zoom_row=True)
    assert "3× around" in night.axes[1].get_ylabel()


def test_cameras_figure_names_exactly_the_classes_it_shows_and_has_a_depth_bar_in_metres():
    sem = np.array([[1, 1, 14], [11, 24, 14]], np.uint8)
    depth = np.array([[1.0, 5.0, 1000.0], [2.0, 50.0, 7.0]], np.float32)
    rgb = np.zeros((2, 3, 3), np.uint8)
    fig = figures.cameras_figure({"CAM_FRONT": (rgb, depth, sem), "CAM_BACK": (rgb, depth, np.full_like(sem, 3))}, "t")
    legend = fig.legends[0]
    assert [t.get_text() for t in legend.get_texts()] == ["1 Road", "3 Building", "11 Sky", "14 Car", "24 RoadLine"]
    assert [ax.get_ylabel() for ax in fig.axes[:6:3]] == ["CAM_FRONT", "CAM_BACK"]
    (bar,) = _colorbar_labels(fig)
    assert bar.startswith("planar depth [m], log scale") and "sky is 1000 m" in bar


def test_lidar_figure_has_an_intensity_bar_and_a_class_legend():
    pts = np.array([[10.0, 0, 0, 0.9], [0, 30, 0, 0.5]], np.float32)
    sem = np.array([[10.0, 0, 0, 1, 7, 14], [0, 30, 0, 1, 0, 1]], np.float32)
    fig = figures.lidar_figure(pts, sem, "sweep")
    assert [t.get_text() for t in fig.legends[0].get_texts()] == ["1 Road", "14 Car"]
    assert len(_colorbar_labels(fig)) == 1 and "60 m" in _texts(fig)


def test_the_demo_writes_four_titled_figures(tmp_path):
    from fog_gym.cli import main

    assert main(["demo", "--resolution", "64x48", "--steps", "1", "--out", str(tmp_path), "--fog", "dense"]) == 0
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == [f"{k}_highway_day_seed0.png" for k in ("contact_sheet", "fog_levels", "lidar", "render")]
    import cv2

    for p in tmp_path.iterdir():
        assert cv2.imread(str(p)).shape[0] > 300  # a figure, not a bare 48-pixel frame

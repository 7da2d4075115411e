"""nuScenes, KITTI and COCO exports, checked with the formats' own tools: the nuScenes devkit (``NuScenes``,
``get_sample_data``, ``LidarPointCloud``, ``render_sample_data``, ``box_velocity``, its map masks and its KITTI reader
``KittiDB``) and pycocotools."""

from __future__ import annotations

import json
from pathlib import Path
import shutil
import subprocess
import sys

import numpy as np
import pytest

from fog_gym.dataset import FogDrive
from fog_gym.dataset.decode import load_channel
from fog_gym.dataset.export import MANIFEST, ExportError, export
from fog_gym.dataset.export.frames import COCO_CATEGORY_ID, KITTI_TYPES, NUSCENES_CATEGORIES, class_from_height
from fog_gym.generate import generate, plan_scenes

nuscenes = pytest.importorskip("nuscenes", reason="the export extra (nuscenes-devkit) checks the exports")
from nuscenes.nuscenes import NuScenes  # noqa: E402
from nuscenes.utils.data_classes import LidarPointCloud  # noqa: E402
from nuscenes.utils.kitti import KittiDB  # noqa: E402
from pyquaternion import Quaternion  # noqa: E402

RES = (160, 120)


@pytest.fixture(scope="module")
def fogdrive(tmp_path_factory):
    root = tmp_path_factory.mktemp("src") / "set"
    generate(root, plan_scenes(2, towns=("merge",), seed=4, resolution=RES, seconds=0.5), progress=False)
    return root


def _boxes(ds: FogDrive, token: str) -> np.ndarray:
    """FogDrive's 3D box corners of a sample in the right-handed LiDAR frame (y negated)."""
    path = ds.get_sample_paths(token, ["BBOX_3D"])["BBOX_3D"]
    return load_channel("BBOX_3D", path)["bboxes_3d"].astype(np.float64) * [1.0, -1.0, 1.0]


def _corner_error(corners_a: np.ndarray, corners_b: np.ndarray) -> float:
    """Largest distance from a corner of ``a`` to the nearest corner of ``b`` (both (8, 3))."""
    return float(np.linalg.norm(corners_a[:, None] - corners_b[None], axis=2).min(axis=1).max())


def test_the_nuscenes_devkit_loads_the_export_and_its_boxes_are_fogdrives(fogdrive, tmp_path):
    out = tmp_path / "nus"
    report = export(fogdrive, out, "nuscenes", fog="dense", progress=False)
    ds = FogDrive(fogdrive)
    nusc = NuScenes(version="v1.0-trainval", dataroot=str(out), verbose=False)
    assert report["samples"] == len(ds.sample) == len(nusc.sample) and report["notes"] == []
    assert {s["name"] for s in nusc.scene} == set(ds.list_scene_names())
    worst, compared = 0.0, 0
    for sample in nusc.sample:
        token = next(s["token"] for s in ds.sample if s["token"].replace("-", "") == sample["token"])
        lidar = sample["data"]["LIDAR_TOP"]
        path, boxes, _ = nusc.get_sample_data(lidar)
        fog = _boxes(ds, token)
        assert len(boxes) == len(fog)
        for box in boxes:  # every exported box has a FogDrive box within 1 cm at each corner
            worst = max(worst, min(_corner_error(box.corners().T, c) for c in fog))
            compared += 1
        points = LidarPointCloud.from_file(path).points.T
        src = load_channel("LIDAR_TOP_FOG_DENSE", ds.get_sample_paths(token, ["LIDAR_TOP_FOG_DENSE"])["LIDAR_TOP_FOG_DENSE"])
        np.testing.assert_allclose(points[:, :3], src[:, :3] * [1, -1, 1], atol=1e-5)
        np.testing.assert_allclose(points[:, 3], src[:, 3] * 255, rtol=1e-6)
        for cam in ("CAM_FRONT", "CAM_BACK", "CAM_LEFT", "CAM_RIGHT"):  # the fog level's images, byte for byte
            exported = nusc.get_sample_data_path(sample["data"][cam])
            assert open(exported, "rb").read() == ds.get_sample_paths(token, [f"{cam}_FOG_DENSE"])[f"{cam}_FOG_DENSE"].read_bytes()
    assert compared > 10 and worst <= 0.01
    names = {nusc.get("category", nusc.get("instance", a["instance_token"])["category_token"])["name"]
             for a in nusc.sample_annotation}  # fmt: skip
    assert names <= set(NUSCENES_CATEGORIES.values())
    assert all(a["num_lidar_pts"] >= 0 and a["visibility_token"] in "1234" for a in nusc.sample_annotation)


def test_the_devkit_draws_the_export_and_the_ego_drives_on_its_maps(fogdrive, tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    out = tmp_path / "nus"
    export(fogdrive, out, "nuscenes", fog="light", cameras=["CAM_FRONT"], progress=False)
    nusc = NuScenes(version="v1.0-trainval", dataroot=str(out), verbose=False)
    sample = nusc.sample[3]
    for channel, kwargs in (("CAM_FRONT", {}), ("LIDAR_TOP", {"underlay_map": False})):
        # underlay_map fails in devkit 1.2.0 under numpy >= 2 for any data (int() of a 1-element array)
        png = tmp_path / f"{channel}.png"
        nusc.render_sample_data(sample["data"][channel], out_path=str(png), verbose=False, **kwargs)
        assert png.stat().st_size > 10_000
    # the devkit calls that fail in the devkit itself, as docs/exports.md lists them with their workaround: the map
    # underlay (render_sample draws every channel with it)
    for call in (lambda: nusc.render_sample_data(sample["data"]["LIDAR_TOP"], out_path=str(tmp_path / "u.png"),
                                                 verbose=False, underlay_map=True),
                 lambda: nusc.render_sample(sample["token"], out_path=str(tmp_path / "s.png"), verbose=False)):  # fmt: skip
        with pytest.raises(TypeError):
            call()
    import nuscenes.map_expansion.map_api  # noqa: F401  (needs descartes: the export extra brings it)

    for scene in nusc.scene:
        log = nusc.get("log", scene["log_token"])
        mask = nusc.get("map", log["map_token"])["mask"]
        poses = [nusc.get("ego_pose", nusc.get("sample_data", s["data"]["LIDAR_TOP"])["ego_pose_token"])["translation"]
                 for s in nusc.sample if s["scene_token"] == scene["token"]]  # fmt: skip
        xy = np.array(poses)[:, :2]
        assert mask.is_on_mask(xy[:, 0], xy[:, 1]).all()  # the road mask (from semantic LiDAR) is under the ego
        assert not mask.is_on_mask(xy[:, 0], xy[:, 1] + 60.0).any()  # and not 60 m to the side


def test_nuscenes_ego_poses_and_box_velocities_are_the_true_ones(tmp_path):
    """A recorded day/night pair: the exported ego poses are the env's, and the devkit's box velocities
    (differences of global positions) are the vehicles' true velocities."""
    from fog_gym.dataset.export.nuscenes import tok
    from fog_gym.envs.fogdrive import FogDriveEnv
    from fog_gym.wrappers import RecordFogDrive

    root = tmp_path / "rec"
    truth = {}
    for time_of_day in ("night", "day"):  # the day episode's truth is kept
        env = RecordFogDrive(FogDriveEnv(town="highway", time_of_day=time_of_day, resolution=(64, 48),
                                         episode_seconds=1.0), root)  # fmt: skip
        obs, info = env.reset(seed=5)
        folder = info["scene_folder"]
        for k in range(11):
            v = env.unwrapped.scene.vehicles  # every vehicle's true world position (CARLA frame) and speed
            truth[k] = (env.unwrapped.scene.ego_pose, dict(zip(v.ids.tolist(), v.centers[:, :2])),
                        dict(zip(v.ids.tolist(), np.linalg.norm(v.velocities, axis=1))))  # fmt: skip
            if k < 10:
                obs, _, _, _, info = env.step(1)
        env.close()
    out = tmp_path / "nus"
    export(root, out, "nuscenes", cameras=["CAM_FRONT"], progress=False)
    nusc = NuScenes(version="v1.0-trainval", dataroot=str(out), verbose=False)
    scene = next(sc for sc in nusc.scene if sc["name"] == "T1_day_scene001")
    log = nusc.get("log", scene["log_token"])
    origin = np.array(log["world_origin"])
    instance_vid = {tok("instance", log["logfile"], v): v for _, pos, _ in truth.values() for v in pos}
    samples = sorted((s for s in nusc.sample if s["scene_token"] == scene["token"]), key=lambda s: s["timestamp"])
    checked = 0
    for k, sample in enumerate(samples):
        (x, y, yaw), _, speeds = truth[k]
        pose = nusc.get("ego_pose", nusc.get("sample_data", sample["data"]["LIDAR_TOP"])["ego_pose_token"])
        np.testing.assert_allclose(pose["translation"], [x - origin[0], -y - origin[1], 0.0], atol=1e-9)
        assert abs(Quaternion(pose["rotation"]).yaw_pitch_roll[0] + yaw) < 1e-9  # yaw negated: right-handed
        for token in sample["anns"] if 0 < k < len(samples) - 1 else []:
            ann = nusc.get("sample_annotation", token)
            vid = instance_vid[ann["instance_token"]]
            if ann["prev"] == "" or ann["next"] == "":
                continue
            # the centred difference of the vehicle's true world positions, in the right-handed frame
            true = (truth[k + 1][1][vid] - truth[k - 1][1][vid]) / 0.2 * [1, -1]
            np.testing.assert_allclose(nusc.box_velocity(token)[:2], true, atol=1e-4)  # boxes are float32 on disk
            assert abs(np.linalg.norm(true) - speeds[vid]) < 0.5  # and that is the vehicle's speed
            checked += 1
    assert checked >= 5 and folder == log["logfile"]


def test_a_set_without_ego_poses_exports_with_identity_poses_and_says_so(fogdrive, tmp_path):
    root = tmp_path / "old"
    shutil.copytree(fogdrive, root)
    for folder in root.glob("data_root/*/ego_pose"):
        shutil.rmtree(folder)
    report = export(root, tmp_path / "nus", "nuscenes", cameras=["CAM_FRONT"], progress=False)
    assert len(report["notes"]) == 2 and all("identity poses" in n for n in report["notes"])
    assert json.loads((tmp_path / "nus" / MANIFEST).read_text())["notes"] == report["notes"]
    nusc = NuScenes(version="v1.0-trainval", dataroot=str(tmp_path / "nus"), verbose=False)
    ds = FogDrive(root)
    for scene in nusc.scene:
        poses = [nusc.get("ego_pose", nusc.get("sample_data", s["data"]["LIDAR_TOP"])["ego_pose_token"])
                 for s in nusc.sample if s["scene_token"] == scene["token"]]  # fmt: skip
        assert all(p["rotation"] == [1.0, 0.0, 0.0, 0.0] and p["translation"] == poses[0]["translation"] for p in poses)
    sample = nusc.sample[2]
    token = next(s["token"] for s in ds.sample if s["token"].replace("-", "") == sample["token"])
    _, boxes, _ = nusc.get_sample_data(sample["data"]["LIDAR_TOP"])
    fog = _boxes(ds, token)
    assert max(min(_corner_error(b.corners().T, c) for c in fog) for b in boxes) <= 0.01


def test_kitti_labels_give_back_fogdrives_boxes_in_3d_and_by_projection(fogdrive, tmp_path):
    out = tmp_path / "kitti"
    export(fogdrive, out, "kitti", fog="moderate", cameras=["CAM_FRONT", "CAM_BACK"], progress=False)
    ds = FogDrive(fogdrive)
    mapping = [line.split() for line in (out / "ImageSets" / "fogdrive_samples.txt").read_text().splitlines()]
    assert len(mapping) == len(ds.sample)
    ids = sorted(sum(((out / "ImageSets" / f"{s}.txt").read_text().split() for s in ("train", "val", "test")), []))
    assert ids == [m[0] for m in mapping]
    worst_3d, worst_2d, inside = 0.0, 0.0, 0
    for cam, tree in (("CAM_FRONT", out), ("CAM_BACK", out / "CAM_BACK")):
        kitti = KittiDB(root=str(tree), splits=("training",))  # the nuScenes devkit's KITTI reader
        assert len(kitti.tokens) == len(ds.sample)
        for fid, token, _, _ in mapping:
            kt = f"training_{fid}"
            fog = _boxes(ds, token)
            b2 = load_channel(f"{cam}_BBOX", ds.get_sample_paths(token, [f"{cam}_BBOX"])[f"{cam}_BBOX"])
            boxes = kitti.get_boxes(kt)
            assert len(boxes) == len(b2["vehicle_ids"])
            transforms = KittiDB.get_transforms(kt, root=str(tree))
            labels = (tree / "training" / "label_2" / f"{fid}.txt").read_text().splitlines()
            for box, line in zip(boxes, labels):
                box.rotate(kitti.kitti_to_nu_lidar_inv)  # the devkit returns nuScenes' LiDAR axes; back to KITTI's
                worst_3d = max(worst_3d, min(_corner_error(box.corners().T, c) for c in fog))
                parsed = KittiDB.parse_label_line(line)
                assert parsed["name"] in KITTI_TYPES.values() and 0 <= parsed["truncation"] <= 1
                assert parsed["occlusion"] in (0, 1, 2)
                from nuscenes.utils.data_classes import Box

                quat = Quaternion(axis=(0, 1, 0), angle=parsed["yaw_camera"]) * Quaternion(axis=(1, 0, 0), angle=np.pi / 2)
                cam_box = Box(parsed["xyz_camera"], parsed["wlh"], quat)
                projected = KittiDB.project_kitti_box_to_image(cam_box, transforms["p_left"], RES)
                corners = cam_box.copy()
                corners.translate(np.array([0, -parsed["wlh"][2] / 2, 0]))
                uv = transforms["p_left"] @ np.vstack([corners.corners(), np.ones(8)])
                uv = uv[:2] / uv[2]
                fully_inside = (uv >= 0).all() and (uv[0] <= RES[0] - 1).all() and (uv[1] <= RES[1] - 1).all()
                if fully_inside and parsed["truncation"] == 0:
                    worst_2d = max(worst_2d, float(np.abs(np.subtract(projected, parsed["bbox_camera"])).max()))
                    inside += 1
            points = KittiDB.get_pointcloud(kt, root=str(tree)).points.T
            src = load_channel("LIDAR_TOP_FOG_MODERATE", ds.get_sample_paths(token, ["LIDAR_TOP_FOG_MODERATE"])["LIDAR_TOP_FOG_MODERATE"])
            np.testing.assert_array_equal(points, src * [1, -1, 1, 1])
    assert worst_3d <= 0.01 and inside >= 5 and worst_2d <= 2.0


def test_coco_loads_in_pycocotools_and_ground_truth_scores_ap_1(fogdrive, tmp_path):
    import contextlib
    import io

    from pycocotools.coco import COCO
    from pycocotools.cocoeval import COCOeval

    out = tmp_path / "coco"
    export(fogdrive, out, "coco", fog="dense", progress=False)
    ds = FogDrive(fogdrive)
    total = 0
    caches = {}
    for split in ("train", "val", "test"):
        path = out / "annotations" / f"instances_{split}.json"
        with contextlib.redirect_stdout(io.StringIO()):
            gt = COCO(str(path))
        total += len(gt.imgs)
        if not gt.anns:
            continue
        for img in gt.imgs.values():  # each image is the fog level's camera image, byte for byte
            src = ds.get_sample_paths(img["sample_token"], [f"{img['camera']}_FOG_DENSE"])[f"{img['camera']}_FOG_DENSE"]
            assert (out / "images" / img["file_name"]).read_bytes() == src.read_bytes()
            assert (img["width"], img["height"]) == RES
        dets = [{"image_id": a["image_id"], "category_id": a["category_id"], "bbox": a["bbox"], "score": 1.0}
                for a in gt.anns.values()]  # fmt: skip
        with contextlib.redirect_stdout(io.StringIO()):
            ev = COCOeval(gt, gt.loadRes(dets), "bbox")
            ev.evaluate()
            ev.accumulate()
            ev.summarize()
        assert ev.stats[0] == pytest.approx(1.0) and ev.stats[1] == pytest.approx(1.0)
        assert {c["id"] for c in gt.cats.values()} == set(COCO_CATEGORY_ID.values())
        # the same boxes in YOLO's layout: labels/<split>/<camera>/<name>.txt beside images/, listed in <split>.txt
        listed = (out / f"{split}.txt").read_text().split()
        assert sorted(listed) == sorted(f"./images/{img['file_name']}" for img in gt.imgs.values())
        assert all(p.startswith(f"./images/{split}/") for p in listed)
        # Ultralytics' label cache: the first label file's folder + .cache (img2label_paths, then .parent.with_suffix)
        first_label = Path(listed[0].replace("/images/", "/labels/")).with_suffix(".txt")
        caches[split] = first_label.parent.with_suffix(".cache")
        for img in gt.imgs.values():
            text = (out / "labels" / img["file_name"].replace(".png", ".txt")).read_text()
            rows = np.array([line.split() for line in text.splitlines()], float).reshape(-1, 5)
            anns = gt.loadAnns(gt.getAnnIds(imgIds=img["id"]))
            expected = [[a["category_id"] - 1, (a["bbox"][0] + a["bbox"][2] / 2) / img["width"],
                         (a["bbox"][1] + a["bbox"][3] / 2) / img["height"], a["bbox"][2] / img["width"],
                         a["bbox"][3] / img["height"]] for a in anns]  # fmt: skip
            np.testing.assert_allclose(rows, np.reshape(expected, (-1, 5)), atol=1e-6)
    assert total == 4 * len(ds.sample)
    # one Ultralytics label cache per split, none shared
    assert caches and len(set(caches.values())) == len(caches) and all(s in str(c) for s, c in caches.items())
    config = (out / "dataset.yaml").read_text()  # YAML: train/val/test lists and the class names by YOLO id
    assert "\ntrain: train.txt\nval: val.txt\ntest: test.txt\n" in config
    assert config.endswith("names:\n  0: car\n  1: truck\n  2: large_vehicle\n")


def test_class_from_height_matches_the_class_size_ranges():
    from fog_gym.world.fleet import CLASS_SPECS

    for cls, (_, _, _, (lo, hi)) in CLASS_SPECS.items():
        assert class_from_height(np.array([lo, (lo + hi) / 2, hi])).tolist() == [cls] * 3


def test_export_refuses_bad_input_and_a_folder_it_must_not_touch(fogdrive, tmp_path):
    for kwargs, message in (({"format": "yolo"}, "format must be one of"), ({"format": "coco", "fog": "thick"}, "fog must be"),
                            ({"format": "coco", "split": "dev"}, "split must be"),
                            ({"format": "kitti", "cameras": ["CAM_TOP"]}, "cameras must be cameras of the set"),
                            ({"format": "kitti", "cameras": "CAM_FRONT"}, "cameras must be a non-empty list")):  # fmt: skip
        with pytest.raises(ExportError, match=message):
            export(fogdrive, tmp_path / "x", progress=False, **kwargs)
    with pytest.raises(ExportError, match="must lie outside the dataset root"):
        export(fogdrive, fogdrive / "exported", "coco", progress=False)
    stranger = tmp_path / "home"
    stranger.mkdir()
    (stranger / "notes.txt").write_text("mine")
    with pytest.raises(ExportError, match="not empty; pass overwrite=True .* or resume=True"):  # Python's keywords
        export(fogdrive, stranger, "coco", progress=False)
    # on the command line: the flags, and the refusal comes before the set is validated (no progress bar)
    cli = subprocess.run([sys.executable, "-m", "fog_gym.cli", "export", str(fogdrive), str(stranger), "--format", "coco"],
                         capture_output=True, text=True)  # fmt: skip
    assert cli.returncode == 1 and cli.stderr.strip() == (
        f"fog-gym export: the output folder {stranger} is not empty; pass --overwrite to replace an earlier export or "
        "--resume to complete an interrupted one")  # fmt: skip
    with pytest.raises(ExportError, match="refusing to delete it"):
        export(fogdrive, stranger, "coco", overwrite=True, progress=False)
    assert (stranger / "notes.txt").read_text() == "mine"
    broken = tmp_path / "broken"
    shutil.copytree(fogdrive, broken)
    next(broken.glob("data_root/*/lidar/000001.npy")).write_bytes(b"\x93NUMPY")
    with pytest.raises(ExportError, match="not a valid FogDrive set .*lidar/000001.npy"):
        export(broken, tmp_path / "y", "kitti", progress=False)
    out = subprocess.run([sys.executable, "-m", "fog_gym.cli", "export", str(broken), str(tmp_path / "z"), "--format",
                          "coco"], capture_output=True, text=True)  # fmt: skip
    last = out.stderr.strip().splitlines()[-1]  # after validate's progress bar: one line
    assert out.returncode == 1 and last.startswith("fog-gym export: ") and "lidar/000001.npy" in last
    assert "Traceback" not in out.stderr


def test_overwrite_replaces_an_export_and_resume_refuses_other_settings(fogdrive, tmp_path):
    out = tmp_path / "coco"
    export(fogdrive, out, "coco", fog="light", cameras=["CAM_FRONT"], progress=False)
    with pytest.raises(ExportError, match="other settings .*fog: 'light' there, 'dense' now"):
        export(fogdrive, out, "coco", fog="dense", cameras=["CAM_FRONT"], resume=True, progress=False)
    export(fogdrive, out, "coco", fog="dense", cameras=["CAM_LEFT"], overwrite=True, progress=False)
    assert sorted(p.name for p in (out / "images").glob("*/*")) == ["CAM_LEFT"]
    assert json.loads((out / MANIFEST).read_text())["complete"] is True


def test_cli_export_writes_each_format_with_a_progress_bar(fogdrive, tmp_path):
    for fmt in ("nuscenes", "kitti", "coco"):
        out = subprocess.run([sys.executable, "-m", "fog_gym.cli", "export", str(fogdrive), str(tmp_path / fmt),
                              "--format", fmt, "--fog", "moderate", "--split", "train"], capture_output=True, text=True)  # fmt: skip
        assert out.returncode == 0, out.stderr
        assert "export" in out.stderr and "sample" in out.stderr  # tqdm's bar
        assert f"{fmt} export" in out.stdout
    assert "--format {nuscenes,kitti,coco}" in subprocess.run(
        [sys.executable, "-m", "fog_gym.cli", "export", "--help"], capture_output=True, text=True).stdout


def _devkit_car_ap(fogdrive, tmp_path, fog: str, min_points: int, radar: bool = True) -> tuple[float, int, int]:
    """Export at ``fog``, submit every ground-truth box with at least ``min_points`` LiDAR (and, with ``radar``, radar)
    points as a detection (score 1) to the devkit's DetectionEval; returns (car AP, boxes submitted, boxes without a
    point)."""
    import contextlib
    import io

    from nuscenes.eval.common.config import config_factory
    from nuscenes.eval.detection.evaluate import DetectionEval
    from nuscenes.eval.detection.utils import category_to_detection_name

    out = tmp_path / f"nus_{fog}"
    if not out.exists():
        export(fogdrive, out, "nuscenes", fog=fog, cameras=["CAM_FRONT"], progress=False)
    nusc = NuScenes(version="v1.0-trainval", dataroot=str(out), verbose=False)
    scenes = json.loads((out / "v1.0-trainval" / "splits.json").read_text())["fogdrive_train"]
    assert scenes and set(scenes) <= {s["name"] for s in nusc.scene}  # the fixture: one day/night pair, in train
    train = {s["token"] for s in nusc.scene if s["name"] in scenes}
    results, empty = {}, 0
    for sample in (s for s in nusc.sample if s["scene_token"] in train):
        anns = [nusc.get("sample_annotation", t) for t in sample["anns"]]
        empty += sum(a["num_lidar_pts"] + radar * a["num_radar_pts"] == 0 for a in anns)
        results[sample["token"]] = [{
            "sample_token": sample["token"], "translation": a["translation"], "size": a["size"],
            "rotation": a["rotation"], "velocity": [0.0 if np.isnan(v) else float(v) for v in nusc.box_velocity(a["token"])[:2]],
            "detection_name": category_to_detection_name(a["category_name"]), "detection_score": 1.0,
            "attribute_name": nusc.get("attribute", a["attribute_tokens"][0])["name"] if a["attribute_tokens"] else "",
        } for a in anns if a["num_lidar_pts"] + radar * a["num_radar_pts"] >= min_points]  # fmt: skip
    path = tmp_path / f"results_{fog}_{min_points}_{radar}.json"
    path.write_text(json.dumps({"meta": {"use_lidar": True, "use_camera": False, "use_radar": False, "use_map": False,
                                         "use_external": False}, "results": results}))  # fmt: skip
    with contextlib.redirect_stdout(io.StringIO()):
        ev = DetectionEval(nusc, config_factory("detection_cvpr_2019"), str(path), "fogdrive_train",
                           str(tmp_path / f"eval_{fog}_{min_points}_{radar}"), verbose=False)  # fmt: skip
        metrics, _ = ev.evaluate()
    summary = metrics.serialize()
    if min_points:
        assert summary["label_tp_errors"]["car"]["trans_err"] < 1e-6
    return summary["mean_dist_aps"]["car"], sum(len(r) for r in results.values()), empty


def test_the_devkit_evaluates_the_ground_truth_on_fogdrives_split_at_map_1(fogdrive, tmp_path):
    """The nuScenes detection evaluation runs on the export's custom split; the ground truth scores AP = 1."""
    ap, _, empty = _devkit_car_ap(fogdrive, tmp_path, "clear", 0)
    assert ap == pytest.approx(1.0)


def test_in_dense_fog_the_devkit_keeps_the_boxes_the_radar_sees_and_drops_those_without_any_point(
        fogdrive, tmp_path):  # fmt: skip
    """docs/exports.md: DetectionEval removes ground-truth boxes with no LiDAR and no radar point (num_lidar_pts +
    num_radar_pts 0), as for nuScenes. In dense fog the LiDAR loses far boxes the radar (not fogged) still sees: the
    ground truth with LiDAR points alone misses them (AP < 1); with LiDAR or radar points it scores AP = 1."""
    ap_lidar, n_lidar, no_lidar = _devkit_car_ap(fogdrive, tmp_path, "dense", 1, radar=False)
    ap_pts, n_pts, empty = _devkit_car_ap(fogdrive, tmp_path, "dense", 1)
    assert no_lidar > empty and n_pts > n_lidar  # boxes without a LiDAR return that the radar detects
    assert ap_lidar < 0.999 and ap_pts == pytest.approx(1.0)

"""Datasets of fog fields: each sample's field recorded beside it (fog_field/), generated, validated, read back by the
access class, carried into the exports; homogeneous sets unchanged."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import fog_gym
from fog_gym.dataset import FogDrive
from fog_gym.dataset.export import FOG_FIELDS, export
from fog_gym.dataset.fog_record import decode_fog_record, encode_fog_record, fog_record_problem
from fog_gym.dataset.manifest import read_manifest
from fog_gym.dataset.validate import validate
from fog_gym.fog.fields import (FogBank, FogSum, HeightFog, Homogeneous, field_from_info, field_info,
                                field_json, world_optical_depth)  # fmt: skip
from fog_gym.generate import generate, plan_scenes, scene_fog
from fog_gym.wrappers.fog import FogWrapper
from fog_gym.wrappers.record import RecordFogDrive

RES = (64, 48)
LEVELS = ("light", "moderate", "dense")


# -- the record -------------------------------------------------------------------------------------------------
def test_a_record_round_trips_every_kind_of_field():
    fields = {"light": HeightFog(160.0, 8.0, name="light"), "moderate": FogBank(100.0, 40.0, 60.0, velocity=2.0,
              name="moderate"), "dense": FogSum((HeightFog(200.0, 5.0), FogBank(50.0, 30.0, 20.0, edge=0.0)),
              name="dense"), "haze": Homogeneous(75.0, name="haze")}  # fmt: skip
    record = decode_fog_record(encode_fog_record((3.0, -2.0, 0.25), 1.5, {k: field_info(v) for k, v in fields.items()}))
    assert {k: field_from_info(v) for k, v in record.fields.items()} == fields
    assert record.time == 1.5 and record.frame.tolist() == [3.0, -2.0, 0.25]


def test_the_optical_depth_of_a_field_laid_in_the_world_is_along_the_fields_axis():
    # a 20 m wide dense bank starting 30 m along a frame rotated by 90°: the world's +y is the field's u
    bank = FogBank(50.0, 30.0, 20.0, edge=0.0, name="dense")
    record = decode_fog_record(encode_fog_record((10.0, 5.0, math.pi / 2), 0.0, {"dense": field_info(bank)}))
    ends = [[10.0, 105.0, 1.0], [10.0, 30.0, 1.0], [110.0, 5.0, 1.0]]
    tau = world_optical_depth(field_from_info(record.fields["dense"]), record.frame, record.time, [10.0, 5.0, 1.0], ends)
    np.testing.assert_allclose(tau, [20.0 * math.log(20.0) / 50.0, 0.0, 0.0], atol=1e-12)


@pytest.mark.parametrize(("frame", "time", "fields", "match"), [
    ((0.0, 0.0), 0.0, {"dense": {"type": "Homogeneous", "visibility_m": 50.0}}, "frame"),
    ((0.0, math.nan, 0.0), 0.0, {"dense": {"type": "Homogeneous", "visibility_m": 50.0}}, "frame"),
    ((0.0, 0.0, 0.0), math.inf, {"dense": {"type": "Homogeneous", "visibility_m": 50.0}}, "time"),
    ((0.0, 0.0, 0.0), 0.0, {}, "fields"),
    ((0.0, 0.0, 0.0), 0.0, {"dense": 50.0}, "must be a JSON object"),
    ((0.0, 0.0, 0.0), 0.0, {"dense": {"type": "Fog", "visibility_m": 50.0}}, "type must be one of"),
    ((0.0, 0.0, 0.0), 0.0, {"dense": {"type": "FogBank", "visibility": 50.0}}, r"lacks \['start', 'length'\]"),
    ((0.0, 0.0, 0.0), 0.0, {"dense": {"type": "HeightFog", "visibility": "x", "scale_height": 2}}, "number"),
])  # fmt: skip
def test_a_bad_record_is_refused_before_anything_is_written(frame, time, fields, match):
    with pytest.raises(ValueError, match=match):
        encode_fog_record(frame, time, fields)


@settings(max_examples=60, deadline=None)
@given(st.one_of(st.binary(max_size=64), st.recursive(
    st.none() | st.booleans() | st.floats() | st.text(max_size=5),
    lambda c: st.lists(c, max_size=3) | st.dictionaries(st.sampled_from(["frame", "time", "fields", "light", "type",
                                                                         "visibility", "x"]), c, max_size=4),
    max_leaves=12).map(lambda v: json.dumps(v).encode())))  # fmt: skip
def test_any_bytes_get_a_problem_or_decode_never_a_crash(data):
    problem = fog_record_problem(data)
    if problem is None:
        decode_fog_record(data)
    else:
        with pytest.raises(ValueError):
            decode_fog_record(data)


# -- generate ---------------------------------------------------------------------------------------------------
def test_scene_fog_lays_out_one_geometry_for_the_three_levels_at_fogdrives_visibilities():
    for kind in ("banks", "height", "mixed"):
        for spec in plan_scenes(8, towns=("highway",), seed=3, fog_fields=kind):
            fog = scene_fog(spec)
            assert [f.name for f in fog] == list(LEVELS) and fog == scene_fog(spec)  # seeded by (seed, scene index)
            infos = [f.info() for f in fog]
            geometry = [{k: v for k, v in i.items() if k not in ("name", "visibility", "visibility_m", "alpha")}
                        for i in infos if i.get("type") in ("FogBank", "HeightFog")]  # fmt: skip
            assert all(g == geometry[0] for g in geometry)
    kinds = {type(scene_fog(s)[0]).__name__ for s in plan_scenes(16, towns=("highway",), fog_fields="mixed")}
    assert kinds == {"FogLevel", "FogBank", "HeightFog", "FogSum"}
    assert all(f.is_homogeneous for s in plan_scenes(4, fog_fields="levels") for f in scene_fog(s))
    with pytest.raises(ValueError, match="fog_fields must be one of"):
        plan_scenes(2, fog_fields="fog")


@pytest.fixture(scope="module")
def mixed_set(tmp_path_factory):
    root = tmp_path_factory.mktemp("mixed") / "set"
    plan = plan_scenes(2, towns=("highway",), resolution=RES, seconds=0.2, fog_fields="mixed")
    generate(root, plan, workers=1, progress=False)
    return root, plan


def test_a_generated_set_of_fields_records_each_samples_field_and_validates(mixed_set):
    root, plan = mixed_set
    assert validate(root) == [] and read_manifest(root)["fog_fields"] == "mixed"
    ds = FogDrive(root)
    for scene, spec in zip(sorted(ds.scene, key=lambda s: s["name"]), sorted(plan, key=lambda s: s.folder)):
        samples = ds.get_samples_for_scene(scene["token"])
        records = [ds.get_fog_field(s["token"]) for s in samples]
        assert all(r is not None and r.fields == {f.name: json.loads(field_json(f)) for f in scene_fog(spec)}
                   for r in records)  # fmt: skip
        np.testing.assert_allclose([r.time for r in records], np.arange(len(records)) * 0.1, atol=1e-9)
        assert len({tuple(r.frame) for r in records}) == 1  # laid at reset
        pose = ds.get_ego_pose(samples[0]["token"])
        np.testing.assert_allclose(records[0].frame[:2], pose.lidar_to_world()[:2, 3], atol=1e-9)
        assert records[0].frame[2] == pytest.approx(pose.yaw)


def test_validate_finds_a_missing_or_wrong_fog_field_file(mixed_set, tmp_path):
    import shutil

    root = tmp_path / "copy"
    shutil.copytree(mixed_set[0], root)
    files = sorted((root / "data_root").glob("*/fog_field/*.json"))
    files[1].unlink()
    files[2].write_text(json.dumps({"frame": [0, 0, 0], "time": 0, "fields": {"dense": {"visibility_m": 50.0}}}))
    problems = validate(root)
    assert any(str(files[1].relative_to(root)) + ": missing file" in p for p in problems)
    assert any(str(files[2].relative_to(root)) + ": fields must name the levels" in p for p in problems)
    shutil.rmtree(files[0].parent)
    assert any("fog_field: missing folder (the manifest says the set has fog fields)" in p for p in validate(root))


def test_resume_refuses_other_fog_fields(mixed_set):
    root, plan = mixed_set
    banks = plan_scenes(2, towns=("highway",), resolution=RES, seconds=0.2, fog_fields="banks")
    with pytest.raises(ValueError, match="fog_fields: mixed in the dataset, banks now"):
        generate(root, banks, workers=1, resume=True, progress=False)


def test_a_homogeneous_set_writes_no_fog_field_files_and_its_manifest_as_before(tmp_path):
    plan = plan_scenes(2, towns=("highway",), resolution=RES, seconds=0.1)
    generate(tmp_path / "set", plan, workers=1, progress=False)
    assert "fog_fields" not in read_manifest(tmp_path / "set")
    assert not list((tmp_path / "set" / "data_root").glob("*/fog_field"))
    ds = FogDrive(tmp_path / "set")
    assert ds.get_fog_field(ds.sample[0]["token"]) is None


# -- RecordFogDrive with fields, through the files ----------------------------------------------------------------
@pytest.fixture(scope="module")
def bank_set(tmp_path_factory):
    root = tmp_path_factory.mktemp("bank")
    banks = [FogBank(v, start=25.0, length=30.0, edge=0.0, name=n) for n, v in zip(LEVELS, (160.0, 100.0, 8.0))]
    for tod, seed in (("day", 4), ("night", 5)):  # (FogDrive's splits hold day and night half and half)
        base = fog_gym.FogDriveEnv(time_of_day=tod, resolution=RES, episode_seconds=0.2)
        env = RecordFogDrive(FogWrapper(base, banks), root)
        env.reset(seed=seed)
        env.step(env.unwrapped.idle_action)
        env.close()
    return root, banks


def test_recorded_lidar_before_a_bank_is_the_clean_one_and_a_dense_bank_hides_what_lies_behind(bank_set):
    root, banks = bank_set
    assert validate(root) == []
    ds = FogDrive(root)
    for sample in ds.sample:
        record, pose = ds.get_fog_field(sample["token"]), ds.get_ego_pose(sample["token"])
        assert {k: field_from_info(v) for k, v in record.fields.items()} == {b.name: b for b in banks}
        paths = ds.get_sample_paths(sample["token"], ["LIDAR_TOP", "LIDAR_TOP_FOG_DENSE"])
        clean, dense = (np.load(paths[c]) for c in ("LIDAR_TOP", "LIDAR_TOP_FOG_DENSE"))

        def u(points):  # distance along the field frame's u of LiDAR-frame points
            world = points[:, :3] @ pose.lidar_to_world()[:3, :3].T + pose.lidar_to_world()[:3, 3]
            h = np.array([math.cos(record.frame[2]), math.sin(record.frame[2])])
            return (world[:, :2] - record.frame[:2]) @ h

        front = u(clean) < 25.0 - 1.0
        assert front.sum() > 100
        kept = {tuple(p) for p in dense[:, :3].round(4).tolist()}
        assert all(tuple(p) in kept for p in clean[front, :3].round(4).tolist())  # clear air before the bank
        behind = u(clean) > 55.0 + 1.0
        assert behind.sum() > 50 and (u(dense) > 55.0 + 1.0).sum() < 0.05 * behind.sum()  # 30 m at 8 m visibility


def test_exports_carry_each_samples_field_of_the_exported_level(bank_set, tmp_path):
    root, banks = bank_set
    ds = FogDrive(root)
    export(root, tmp_path / "coco", "coco", fog="dense", progress=False)
    meta = json.loads((tmp_path / "coco" / FOG_FIELDS).read_text())
    assert meta["fog"] == "dense" and sorted(meta["samples"]) == sorted(s["token"] for s in ds.sample)
    assert all(r["field"]["type"] == "FogBank" and r["field"]["visibility"] == 8.0 for r in meta["samples"].values())
    images = json.loads(next((tmp_path / "coco" / "annotations").glob("*.json")).read_text())["images"]
    assert images and all(im["fog_field"] == meta["samples"][im["sample_token"]] for im in images)
    export(root, tmp_path / "kitti", "kitti", fog="light", progress=False)
    meta = json.loads((tmp_path / "kitti" / FOG_FIELDS).read_text())
    assert {r["field"]["visibility"] for r in meta["samples"].values()} == {160.0}
    export(root, tmp_path / "clear", "kitti", fog="clear", progress=False)
    assert not (tmp_path / "clear" / FOG_FIELDS).exists()  # the clean data has no fog


def test_record_fog_drive_refuses_fields_not_named_as_fogdrives_levels(tmp_path):
    env = FogWrapper(fog_gym.FogDriveEnv(resolution=RES, episode_seconds=0.1),
                     [FogBank(50.0, 20.0, 10.0, name="bank"), "moderate", "dense"])  # fmt: skip
    with pytest.raises(ValueError, match="three fog fields named light, moderate and dense"):
        RecordFogDrive(env, tmp_path)

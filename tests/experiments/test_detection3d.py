"""Experiment 1: BEV encoding, targets ↔ decoding, subsets, the LiDAR-only set, and a tiny end-to-end run."""

import json
import math
import shutil

import numpy as np
import pytest

torch = pytest.importorskip("torch")  # the torch extra is part of the dev extra: never skipped in CI

from tests.helpers import Killed, killed_after_first_epoch  # noqa: E402
from fog_gym.dataset import FogDrive  # noqa: E402
from fog_gym.generate import generate, plan_scenes  # noqa: E402
from fog_gym.dataset.layout import MODALITIES  # noqa: E402
from fog_gym.dataset.validate import validate  # noqa: E402
from fog_gym.experiments.detection3d.bev import BEVGrid, class_from_height, decode_cells, make_targets, point_features  # noqa: E402
from fog_gym.experiments.detection3d.data import SweepCache, SweepDataset, collate  # noqa: E402
from fog_gym.experiments.detection3d.study import Exp1Config, run_experiment1  # noqa: E402
from fog_gym.experiments.detection3d.model import BEVCenterNet, decode, detection_loss  # noqa: E402
from fog_gym.experiments.detection3d.protocol import TEST_COLUMNS, evaluation_subsets, training_subsets  # noqa: E402
from fog_gym.metrics.detection3d import evaluate  # noqa: E402

GRID = BEVGrid()


def _boxes(rng, n):
    return np.c_[rng.uniform(-39, 39, (n, 2)), rng.uniform(-1.5, -0.5, n), rng.uniform(4, 9, n),
                 rng.uniform(1.8, 2.6, n), rng.uniform(1.4, 3.8, n), rng.uniform(-np.pi, np.pi, n)]  # fmt: skip


def test_class_from_height_recovers_every_vehicles_class():
    from fog_gym.envs.fogdrive import FogDriveEnv

    env = FogDriveEnv(town="highway", resolution=(32, 24), highway_config={"vehicles_count": 60})
    seen = 0
    for seed in range(3):
        env.reset(seed=seed)
        v = env.scene.vehicles
        others = v.ids != env.scene.ego_id
        assert (class_from_height(v.sizes[others, 2]) == v.classes[others]).all()
        seen += others.sum()
    assert seen > 100


def test_targets_decode_back_to_the_boxes():
    rng = np.random.default_rng(0)
    boxes = _boxes(rng, 12)
    boxes = boxes[np.unique(np.floor((boxes[:, :2] + 40) / 1.0), axis=0, return_index=True)[1]]  # one box per cell
    classes = class_from_height(boxes[:, 5])
    t = make_targets(boxes, classes, GRID)
    back = decode_cells(t["index"], t["regression"], GRID)
    np.testing.assert_allclose(back, boxes, atol=1e-5)
    assert t["heatmap"].max() == 1.0 and (t["heatmap"] == 1.0).sum() == len(boxes)


def test_a_perfect_network_output_decodes_to_map_one():
    rng = np.random.default_rng(1)
    boxes = _boxes(rng, 8)
    boxes = boxes[np.unique(np.floor((boxes[:, :2] + 40) / 2.0), axis=0, return_index=True)[1]]  # apart
    classes = class_from_height(boxes[:, 5])
    t = make_targets(boxes, classes, GRID)
    h, w = GRID.out_shape
    heat = torch.full((1, 3, h, w), -20.0)
    reg = torch.zeros((1, 8, h * w))
    for k, (cell, c) in enumerate(zip(t["index"], t["classes"], strict=True)):
        heat[0, c].view(-1)[cell] = 5.0
        reg[0, :, cell] = torch.from_numpy(t["regression"][k])
    pred = decode({"heatmap": heat, "regression": reg.view(1, 8, h, w)}, GRID)
    r = evaluate([{"boxes": boxes, "classes": classes}], pred)
    assert r["mAP"] == pytest.approx(1.0) and r["ATE_m"] < 1e-5 and r["mean_TP"] > 0.99999


def test_features_of_a_mirrored_sweep_are_the_mirrored_features():
    rng = np.random.default_rng(2)
    pts = np.c_[rng.uniform(-45, 45, (5000, 2)), rng.uniform(-3.5, 2.5, 5000), rng.uniform(0, 1, 5000)].astype(np.float32)
    f = point_features(pts, GRID)
    g = point_features(pts * np.float32([1, -1, 1, 1]), GRID)
    np.testing.assert_allclose(g, f[:, :, ::-1], atol=1e-6)
    inside = (np.abs(pts[:, :2]) < 40).all(1) & (pts[:, 2] >= -3) & (pts[:, 2] < 2)
    assert np.expm1(f[0]).round().sum() == inside.sum()  # every point in range counted once


def test_subsets_follow_the_paper():
    names = [f"T1_day_scene{i:03d}" for i in range(100)]
    s = training_subsets(names, seed=3)
    light, dense, ms, ml = (set(s[k]) for k in ("Light", "Dense", "Mixed-S", "Mixed-L"))
    assert len(light) == len(dense) == 20 and len(ms) == 24 and len(ml) == 60
    assert {n for n, _ in light} == {n for n, _ in dense} == {n for n, _ in ml}
    assert light | dense <= ml  # Mixed-L holds both single-density subsets
    by_level = {lv: {n for n, l in ms if l == lv} for lv in ("light", "moderate", "dense")}
    assert all(len(v) == 8 for v in by_level.values()) and len(set.union(*by_level.values())) == 24  # disjoint
    t = evaluation_subsets([f"x{i}" for i in range(10)])
    assert list(t) == list(TEST_COLUMNS) and all([n for n, _ in v] == [n for n, _ in t["light"]] for v in t.values())
    assert len(t["dense"]) == 2
    with pytest.raises(ValueError, match="no scenes"):
        training_subsets([])


@pytest.fixture(scope="module")
def lidar_set(tmp_path_factory):
    root = tmp_path_factory.mktemp("exp1") / "lidar"
    generate(root, plan_scenes(10, towns=("highway", "merge"), seed=4, resolution=(64, 48), seconds=0.4,
                               modality="lidar"), progress=False)  # fmt: skip
    return root


def test_a_lidar_only_set_validates_and_equals_the_full_sets_lidar_files(lidar_set, tmp_path):
    assert validate(lidar_set) == []
    ds = FogDrive(lidar_set)
    assert ds.list_channels() == sorted(MODALITIES["lidar"])
    full = tmp_path / "full"
    generate(full, plan_scenes(10, towns=("highway", "merge"), seed=4, resolution=(64, 48), seconds=0.4)[:2],
             progress=False)  # fmt: skip
    for rec in FogDrive(full).sample_data:
        if rec["channel"] in MODALITIES["lidar"]:
            assert (lidar_set / rec["filename"]).read_bytes() == (full / rec["filename"]).read_bytes(), rec["filename"]


TOY = {"pillar_widths": (8, 8, 8), "pillar_layers": (1, 1, 1), "pfn": 8, "neck": 8, "head": 8, "width": 8}


def test_training_lowers_the_loss_on_real_sweeps(lidar_set, tmp_path):
    ds = FogDrive(lidar_set)
    cache = SweepCache(tmp_path / "cache", GRID)
    data = SweepDataset(ds, [(ds.splits["train"][0], "light")], cache, "bev", GRID)
    batch = collate([data[i] for i in range(len(data))])
    assert sum(len(g["boxes"]) for g in batch["gt"]) > 0
    torch.manual_seed(0)
    model = BEVCenterNet(width=16)
    opt = torch.optim.Adam(model.parameters(), 3e-3)
    losses = []
    for _ in range(25):
        loss, _ = detection_loss(model(**batch["inputs"]), batch["heatmap"], batch["batch_index"], batch["cell_index"],
                                 batch["regression"])  # fmt: skip
        opt.zero_grad()
        loss.backward()
        opt.step()
        losses.append(float(loss.detach()))
    assert losses[-1] < 0.5 * losses[0]


def test_the_cache_gives_the_files_points_and_boxes(lidar_set, tmp_path):
    from fog_gym.dataset.decode import load_channel
    from fog_gym.experiments.detection3d.data import ground_truth

    ds = FogDrive(lidar_set)
    cache = SweepCache(tmp_path / "cache", Exp1Config().pillar_config.grid)
    data = SweepDataset(ds, [(ds.splits["train"][0], "dense")], cache, "pillars")
    channel, lidar, box, _ = data.items[0]
    p, gt = cache.get(channel, lidar, box)
    again, _ = cache.get(channel, lidar, box)  # read back from the cache file
    assert np.array_equal(p.points, again.points) and np.array_equal(p.cells, again.cells)
    pts = load_channel(channel, lidar)
    inside = (np.abs(pts[:, :2]) < 40).all(1) & (pts[:, 2] >= -3) & (pts[:, 2] < 2)
    assert sorted(map(tuple, p.points)) == sorted(map(tuple, pts[inside, :4]))
    want = ground_truth(load_channel("BBOX_3D", box), cache.grid)
    assert np.array_equal(gt["boxes"], want["boxes"]) and np.array_equal(gt["classes"], want["classes"])
    # the BEV detector's features from the cached points equal those of the file
    bev = SweepDataset(ds, [(ds.splits["train"][0], "dense")], cache, "bev", GRID)
    np.testing.assert_allclose(bev[0][0]["x"], point_features(pts, GRID), atol=1e-6)  # sums in another order


def test_experiment1_end_to_end_writes_every_cell(lidar_set, tmp_path):
    cfg = Exp1Config(epochs=1, batch_size=4, every=1, test_every=1, rows=("Light", "Mixed-L"), test_fraction=1.0, **TOY)
    res = run_experiment1(lidar_set, tmp_path / "out", cfg, progress=False, log=lambda *_: None)
    for det in ("pillars", "bev"):
        table = res["tables"][det]
        for row in ("Light", "Mixed-L"):
            for col in TEST_COLUMNS:
                cell = {k: v["mean"] for k, v in table[row][col].items()}
                assert cell["epoch"] == 1 and cell["n_gt"] > 0 and table[row][col]["mAP"]["ci95"] is None  # one seed
                assert all(0.0 <= cell[k] <= 1.0 for k in ("mAP", "mean_TP", "ATE", "ASE", "AOE", "FDS"))
                assert cell["FDS"] == pytest.approx(0.5 * cell["mAP"] + 0.5 * cell["mean_TP"])
    units = res["units"]
    assert units["pillars_Mixed-L_s0"]["result"]["train_sweeps"] == 3 * units["pillars_Light_s0"]["result"]["train_sweeps"]
    out = tmp_path / "out"
    text = (out / "exp1.md").read_text()
    assert "## Verdicts" in text and "| Mixed-L |" in text and "## Wall time" in text and "| pillars_Light_s0 | rows |" in text
    assert "(test scenes resampled, one seed;" in text and "(best-FDS epoch per cell, one seed;" in text  # no seeds claimed
    for name in ("exp1.png", "exp1_curve.png", "exp1_sweeps.png"):
        assert (out / name).stat().st_size > 0
    assert any((out / "tb" / "pillars_Light_s0").iterdir())
    comp = res["comparisons"]["pillars"]["Mixed-L − Light"]["light"]["mAP"]
    observed = (units["pillars_Mixed-L_s0"]["result"]["best"]["light"]["mAP"]
                - units["pillars_Light_s0"]["result"]["best"]["light"]["mAP"])  # fmt: skip
    assert comp["diff"] == pytest.approx(observed, abs=1e-9)  # the bootstrap's point estimate is the tables' difference
    shutil.rmtree(out / "models")  # a unit restored from a kept folder has its predictions, not its model
    (out / "exp1_sweeps.png").unlink()
    again = run_experiment1(lidar_set, out, cfg, progress=False, log=lambda *_: None)
    assert json.dumps(again["tables"]) == json.dumps(res["tables"])
    assert (out / "exp1_sweeps.png").stat().st_size > 0  # drawn from preds/


def test_a_second_run_keeps_finished_rows_and_refuses_other_settings(lidar_set, tmp_path):
    cfg = Exp1Config(epochs=1, batch_size=4, every=1, test_every=1, rows=("Dense",), detectors=("bev",), **TOY)
    first = run_experiment1(lidar_set, tmp_path / "out", cfg, progress=False, log=lambda *_: None)
    messages = []
    again = run_experiment1(lidar_set, tmp_path / "out", Exp1Config(**{**cfg.__dict__, "rows": ("Dense", "Clear")}),
                            progress=False, log=messages.append)  # fmt: skip
    assert any(m.startswith("bev_Dense_s0: kept from") for m in messages)
    assert again["units"]["bev_Dense_s0"] == json.loads(json.dumps(first["units"]["bev_Dense_s0"]))
    assert set(again["tables"]["bev"]) == {"Dense", "Clear"}
    # a unit's weights do not depend on the units trained before it in the same process
    run_experiment1(lidar_set, tmp_path / "fresh", Exp1Config(**{**cfg.__dict__, "rows": ("Dense", "Clear")}),
                    progress=False, log=lambda *_: None)  # fmt: skip
    kept, fresh = (torch.load(tmp_path / d / "models" / "bev_Clear_s0.pt") for d in ("out", "fresh"))
    assert all(torch.equal(kept[k], fresh[k]) for k in kept)
    with pytest.raises(ValueError, match="other settings \\(lr: 0.002 there, 0.0005 here\\)"):
        run_experiment1(lidar_set, tmp_path / "out", Exp1Config(**{**cfg.__dict__, "lr": 5e-4}), progress=False,
                        log=lambda *_: None)  # fmt: skip


def test_seeds_repeat_each_row_and_the_tables_give_their_ci(lidar_set, tmp_path):
    cfg = Exp1Config(epochs=1, batch_size=4, every=1, test_every=1, rows=("Dense",), detectors=("bev",), seed=5, **TOY)
    res = run_experiment1(lidar_set, tmp_path / "out", cfg, progress=False, log=lambda *_: None, seeds=2)
    per_seed = {s: res["units"][f"bev_Dense_s{s}"]["result"] for s in (5, 6)}
    assert res["runner"]["seeds"] == [5, 6]
    for col in TEST_COLUMNS:
        values = [per_seed[s]["best"][col]["n_pred"] for s in (5, 6)]
        cell = res["tables"]["bev"]["Dense"][col]["n_pred"]
        assert cell["seeds"] == 2 and cell["mean"] == pytest.approx(np.mean(values))
        assert cell["ci95"] == pytest.approx(12.706 * abs(values[0] - values[1]) / 2, rel=1e-3)  # t(0.975, 1) · SD / √2
    a, b = (torch.load(tmp_path / "out" / "models" / f"bev_Dense_s{s}.pt") for s in (5, 6))
    assert not all(torch.equal(a[k], b[k]) for k in a)  # another seed, another network
    text = (tmp_path / "out" / "exp1.md").read_text()
    assert " ± " in text and "mean ± 95 % CI across 2 seeds;" in text


def test_bad_settings_fail_before_training(tmp_path):
    with pytest.raises(ValueError, match="epochs must be a positive integer"):
        Exp1Config(epochs=0)
    with pytest.raises(ValueError, match="rows must be a non-empty subset"):
        Exp1Config(rows=("Heavy",))
    with pytest.raises(ValueError, match="detectors must be a non-empty subset"):
        Exp1Config(detectors=())
    with pytest.raises(FileNotFoundError, match="not a FogDrive dataset root"):
        run_experiment1(tmp_path, tmp_path / "out")
    assert not math.isnan(GRID.out_cell_m)


@pytest.mark.parametrize("argv, message", [
    (["--pillar-widths", "32", "-4", "128"], "pillar_widths must be three positive integers"),
    (["--pillar-size", "0.3"], "must be an integer multiple of stride|multiple of 4"),
    (["--range", "40", "--pillar-size", "0.8"], "multiple of 4"),
    (["--epochs", "0"], "epochs must be a positive integer"),
    (["--rows", "Heavy"], "rows must be a non-empty subset"),
    (["--detectors", "yolo"], "invalid choice: 'yolo'"),
])  # fmt: skip
def test_bad_flags_are_one_line_usage_errors(argv, message, tmp_path, capsys):
    from fog_gym.experiments.detection3d.study import Exp1Study
    from fog_gym.experiments.runner import main

    with pytest.raises(SystemExit) as e:
        main(Exp1Study, ["--root", str(tmp_path), "--out", str(tmp_path / "out"), *argv])
    assert e.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("fog-gym exp1: error:") and __import__("re").search(message, err[-1])
    assert not (tmp_path / "out").exists()


def test_an_empty_subset_or_split_is_refused_before_training(lidar_set, tmp_path, capsys):
    import shutil

    from fog_gym.experiments.detection3d.study import Exp1Study
    from fog_gym.experiments.runner import main

    with pytest.raises(SystemExit) as e:  # no rows at all
        main(Exp1Study, ["--root", str(lidar_set), "--out", str(tmp_path / "out"), "--rows"])
    assert e.value.code == 2 and "--rows: expected at least one argument" in capsys.readouterr().err
    empty = tmp_path / "empty"
    shutil.copytree(lidar_set, empty)
    splits = json.loads((empty / "index" / "splits.json").read_text())
    (empty / "index" / "splits.json").write_text(json.dumps({**splits, "test": []}))
    with pytest.raises(SystemExit, match="^fog-gym exp1: .*needs a dataset with train and test scenes"):
        main(Exp1Study, ["--root", str(empty), "--out", str(tmp_path / "out2")])
    assert not (tmp_path / "out2" / "rows").exists()


def test_gpu_flag_selects_the_gpu_configuration_at_toy_size(lidar_set, tmp_path):
    """The --gpu configuration builds and trains (here on the CPU, at toy size: one epoch, one row)."""
    cfg = Exp1Config.gpu(epochs=1, batch_size=2, every=4, test_every=4, rows=("Light",), detectors=("pillars",),
                         pillar_m=0.8 * 0 + 0.4, pfn=8, pillar_widths=(8, 8, 8), pillar_layers=(1, 1, 1), neck=8, head=8)  # fmt: skip
    assert cfg.profile == "gpu" and Exp1Config.gpu().pillar_m == 0.2 and Exp1Config.gpu().pillar_widths == (64, 128, 256)
    res = run_experiment1(lidar_set, tmp_path / "out", cfg, progress=False, log=lambda *_: None)
    assert res["config"]["profile"] == "gpu" and "pillars_Light_s0" in res["units"]


def test_a_unit_killed_after_an_epoch_resumes_from_its_checkpoint_to_the_uninterrupted_weights(lidar_set, tmp_path,
                                                                                              monkeypatch):  # fmt: skip
    cfg = Exp1Config(epochs=2, batch_size=4, every=1, test_every=1, rows=("Dense",), detectors=("bev",), **TOY)
    whole = run_experiment1(lidar_set, tmp_path / "whole", cfg, progress=False, log=lambda *_: None)
    # killed in its first unit; which rows a run asks for is not a setting
    with killed_after_first_epoch(monkeypatch), pytest.raises(Killed):
        run_experiment1(lidar_set, tmp_path / "out", Exp1Config(**{**cfg.__dict__, "rows": ("Dense", "Clear")}),
                        progress=False, log=lambda *_: None)  # fmt: skip
    assert (tmp_path / "out" / "checkpoints" / "bev_Dense_s0.pt").exists()
    resumed = run_experiment1(lidar_set, tmp_path / "out", cfg, progress=False, log=lambda *_: None)
    record = resumed["units"]["bev_Dense_s0"]["result"]
    assert record["resumed_at_epoch"] == 1 and record["steps"] == whole["units"]["bev_Dense_s0"]["result"]["steps"]
    assert record["curve"] == whole["units"]["bev_Dense_s0"]["result"]["curve"]
    a, b = (torch.load(tmp_path / d / "models" / "bev_Dense_s0.pt") for d in ("whole", "out"))
    assert all(torch.equal(a[k], b[k]) for k in a)
    assert not (tmp_path / "out" / "checkpoints" / "bev_Dense_s0.pt").exists()  # cleared once the unit's files exist


def test_a_claim_without_its_rows_reads_not_run_and_says_which_row_is_missing():
    from fog_gym.experiments.detection3d.report import _verdict_lines, verdicts

    iv = {"diff": -0.05, "lo": -0.1, "hi": -0.03, "verdict": "worse"}
    comp = {"pillars": {"Mixed-S − Light": {lv: {"mAP": iv} for lv in ("light", "moderate", "dense")}}}
    ver = verdicts(comp)
    assert ver["pillars"]["claim1"] == "not run" and ver["pillars"]["claim2"] == "refuted"  # hi −0.03 < −margin
    text = "\n".join(_verdict_lines({}, comp, ver))
    assert "**not run** (the Mixed-L row has not been trained yet)." in text
    assert "**refuted**. Mixed-S − Light: mAP light -0.050 [-0.100, -0.030]" in text
    assert "; Mixed-S − Dense: not run (no Dense row)." in text

"""Experiment 2 (defog-then-detect vs train-on-fog): the oracle is exact on generated frames, the protocol runs end
to end at a tiny budget, keeps its models for a second run and refuses bad settings before any work."""

from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("torch")

from tests.helpers import Killed, killed_after_first_epoch  # noqa: E402
from fog_gym.dataset.access import FogDrive  # noqa: E402
from fog_gym.experiments.defog.data import LEVELS, choose_scenes, frames, intrinsic, load_boxes, load_image  # noqa: E402
from fog_gym.experiments.defog.train import augment_hsv  # noqa: E402
from fog_gym.experiments.defog.dehazers import DEHAZERS, OracleDehazer  # noqa: E402
from fog_gym.experiments.defog.study import Exp2Config, run_experiment2  # noqa: E402
from fog_gym.fog import parse_fog, ray_length_factor  # noqa: E402
from fog_gym.generate import generate, plan_scenes  # noqa: E402

TINY = dict(epochs=1, batch_size=8, every=2, test_every=2, input_size=(64, 64), train_fraction=1.0, val_fraction=1.0,
            test_fraction=1.0, aod_epochs=1, aod_pairs=8, cameras=("CAM_FRONT",), device="cpu", width=8,
            dehazeformer_steps=2, dehazeformer_crop=32)  # fmt: skip


@pytest.fixture(scope="module")
def camera_set(tmp_path_factory):
    root = tmp_path_factory.mktemp("exp2") / "set"
    generate(root, plan_scenes(10, towns=("highway", "merge"), seed=4, resolution=(64, 48), seconds=0.3), progress=False)
    return root


def test_the_oracle_recovers_generated_day_frames_to_within_rounding_where_light_gets_through(camera_set):
    ds = FogDrive(camera_set)
    oracle = OracleDehazer(ds)
    day = [n for n in ds.list_scene_names() if "_day_" in n][0]
    f = frames(ds, [day], 1, ["CAM_FRONT"])[1]  # not the airlight's own frame
    clean = load_image(ds, f, "clean").astype(float)
    depth_ch = "CAM_FRONT_DEPTH"
    from fog_gym.dataset.decode import load_channel

    depth = load_channel(depth_ch, ds.get_sample_paths(f.sample, [depth_ch])[depth_ch])
    for level in LEVELS:
        fogged = load_image(ds, f, level)
        back = oracle(fogged, f, level).astype(float)
        t = np.exp(-parse_fog(level).alpha * depth * ray_length_factor(64, 48, intrinsic(64, 48)))
        seen = t >= 0.05
        assert seen.mean() > 0.3
        # the depth PNG is exact to ~0.1 mm and the airlight is recomputed from sample 0: only I's rounding is left
        assert (np.abs(back - clean)[seen] <= (0.5 / t[seen] + 1.0)[:, None]).all(), level
        assert np.abs(back - clean)[seen].mean() < 0.25 * np.abs(fogged - clean)[seen].mean()


def test_boxes_come_back_as_pixel_edges_inside_the_image(camera_set):
    ds = FogDrive(camera_set)
    f = frames(ds, ds.list_scene_names()[:1], 1, ["CAM_FRONT"])[0]
    boxes, classes = load_boxes(ds, f)
    assert boxes.shape == (len(classes), 4)
    assert (boxes[:, 2] > boxes[:, 0]).all() and (boxes[:, 3] > boxes[:, 1]).all()
    assert (boxes >= 0).all() and (boxes[:, [0, 2]] <= 64).all() and (boxes[:, [1, 3]] <= 48).all()


def test_experiment2_runs_every_pipeline_and_a_second_run_reuses_the_models(camera_set, tmp_path):
    out = tmp_path / "out"
    config = Exp2Config(**TINY)
    r = run_experiment2(camera_set, out, config, progress=False, log=lambda *_: None)
    det = r["detection"]
    assert set(det) == {"A", "B", "D", *(f"C-{d}" for d in DEHAZERS)}
    assert list(det["A"]) == ["clean"] and all(list(det[k]) == list(LEVELS) for k in det if k != "A")
    for cells in det.values():
        for m in cells.values():
            assert 0.0 <= m["mAP50_95"]["mean"] <= m["mAP50"]["mean"] <= 1.0 and m["n_gt"]["mean"] > 0
            assert m["mAP50"]["seeds"] == 1 and m["mAP50"]["ci95"] is None
    iq = r["image_quality"]
    assert set(iq) == set(LEVELS) and all(set(iq[lv]) == {"foggy", *DEHAZERS} for lv in LEVELS)
    assert iq["light"]["foggy"]["PSNR"]["mean"] > iq["dense"]["foggy"]["PSNR"]["mean"]  # denser fog departs further
    assert {p.name for p in out.iterdir()} >= {"exp2.md", "exp2.png", "exp2_quality.png", "exp2_curve.png",
                                               "exp2_examples.png", "results.json", "models", "records", "tb", "study.json"}  # fmt: skip
    md = (out / "exp2.md").read_text()
    assert md.count("| D (fog→fog) |") == 3 and md.count("| C – ") == 3 * len(DEHAZERS) and "## Wall time" in md
    assert "## Verdicts" in md and "(iii) PSNR does not predict detection" in md
    below = det["A"]["clean"]["mAP50"]["mean"] < 0.45  # a toy detector: the verdicts say they describe it alone
    assert ("Below the bar the verdicts describe this detector, not the paper's claims" in md) == below
    assert json.loads((out / "results.json").read_text())["detection"]["B"]["dense"] == det["B"]["dense"]
    # the paired comparisons' point estimates are the tables' differences
    comp = r["comparisons"]
    assert comp["D − B"]["dense"]["diff"] == pytest.approx(det["D"]["dense"]["mAP50"]["mean"] - det["B"]["dense"]["mAP50"]["mean"], abs=1e-9)
    # a second run trains nothing and gives the same numbers; other settings are refused, not mixed in
    said = []
    again = run_experiment2(camera_set, out, config, progress=False, log=said.append)
    assert sum("kept from" in s for s in said) == 7  # clean + three levels + AOD-Net + DehazeFormer, the evaluation
    assert again["detection"] == det
    with pytest.raises(ValueError, match="other settings \\(lr: 0.002 there, 0.01 here\\)"):
        run_experiment2(camera_set, out, Exp2Config(**{**TINY, "lr": 1e-2}), progress=False, log=lambda *_: None)


def test_the_report_gives_the_ci_across_seeds_in_both_tables_and_the_figure(tmp_path):
    from fog_gym.experiments.defog import report
    from fog_gym.experiments.runner import aggregate

    rng = np.random.default_rng(0)
    score = lambda: {"mAP50": rng.uniform(0.2, 0.4), "mAP50_95": 0.1, "precision": 0.5, "recall": 0.5, "AP50/0": 0.3}  # noqa: E731
    det = aggregate({p: {lv: {s: score() for s in (0, 1, 2)} for lv in (["clean"] if p == "A" else LEVELS)}
                     for p in report.PIPELINE_NAMES})  # fmt: skip
    iq = aggregate({lv: {m: {s: {"PSNR": 20.0 + s, "SSIM": 0.5} for s in (0, 1, 2)} for m in ("foggy", *DEHAZERS)}
                    for lv in LEVELS})  # fmt: skip
    assert iq["dense"]["DCP"]["PSNR"]["mean"] == 21.0 and iq["dense"]["DCP"]["PSNR"]["ci95"] == pytest.approx(2.484, abs=1e-3)
    text = "\n".join(report.table_markdown(det, iq, seeds=3))
    assert "mean ± 95 % CI across 3 seeds" in text and "| 21.00 ± 2.48 |" in text and "| 0.500 ± 0.000 |" in text
    row = next(ln for ln in text.splitlines() if ln.startswith("| D (fog→fog) | dense"))
    assert row.count(" ± ") == 5 and row.endswith("| – | – |")  # car AP with its CI; no truck, no bigger car
    report.figure(det, tmp_path / "exp2.png")
    assert (tmp_path / "exp2.png").read_bytes()[:4] == b"\x89PNG"


def test_verdicts_follow_their_rules():
    from fog_gym.experiments.defog.report import MARGIN, verdicts

    def iv(lo, hi):
        return {"diff": (lo + hi) / 2, "lo": lo, "hi": hi}

    lv = ("light", "moderate", "dense")
    comp = {"D − A": {v: iv(-0.01, 0.02) for v in lv}, "best C − B": {v: iv(0.01, 0.05) for v in lv},
            "D − best C": {v: iv(0.02, 0.06) for v in lv}, "gap dense − light": iv(0.01, 0.03),
            "image_quality": {"PSNR": {"reversals": [{}], "within": iv(-0.5, 0.5)},
                              "SSIM": {"reversals": [], "within": iv(0.2, 0.9)}}}  # fmt: skip
    assert verdicts(comp) == {"i": "confirmed", "ii": "confirmed", "iii-PSNR": "confirmed", "iii-SSIM": "refuted"}
    comp["D − A"]["dense"] = iv(-MARGIN - 0.05, -MARGIN - 0.01)  # worse than the margin allows
    comp["D − best C"]["light"] = iv(-0.02, 0.01)  # not resolved
    comp["image_quality"]["SSIM"]["within"] = iv(-0.2, 0.9)
    assert verdicts(comp) == {"i": "refuted", "ii": "not resolved at this power", "iii-PSNR": "confirmed",
                              "iii-SSIM": "not resolved at this power"}  # fmt: skip
    comp["best C − B"]["dense"] = iv(-0.03, -0.01)  # defogging hurts at dense
    assert verdicts(comp)["ii"] == "refuted"


@pytest.mark.parametrize(
    "bad, message",
    [({"input_size": (50, 40)}, "multiples of 32"), ({"dehazeformer": "XL"}, "dehazeformer"), ({"width": 0}, "width"), ({"epochs": 0}, "epochs"), ({"test_fraction": 0.0}, "test_fraction"),
     ({"cameras": ("CAM_TOP",)}, "cameras"), ({"lr": -1.0}, "lr"), ({"min_height": -1.0}, "min_height"),
     ({"min_height": 1e9}, "min_height"), ({"hsv": (0.1, 2.0, 0.1)}, "hsv"), ({"hsv": (0.1, 0.1)}, "hsv")],
)  # fmt: skip
def test_bad_settings_fail_before_any_work(bad, message):
    with pytest.raises(ValueError, match=message):
        Exp2Config(**{**TINY, **bad})


def test_a_lidar_only_set_is_refused_naming_the_missing_camera_channels(tmp_path):
    root = tmp_path / "lidar"
    generate(root, plan_scenes(10, towns=("merge",), seed=1, resolution=(32, 24), seconds=0.1, modality="lidar"),
             progress=False)  # fmt: skip
    with pytest.raises(ValueError, match="CAM_FRONT"):
        run_experiment2(root, tmp_path / "out", Exp2Config(**TINY), progress=False)


def test_scene_choice_is_a_seeded_uniform_subset():
    names = [f"T1_day_scene{i:03d}" for i in range(40)]
    a, b = choose_scenes(names, 0.15, 3), choose_scenes(names, 0.15, 4)
    assert len(a) == 6 and set(a) <= set(names) and a == choose_scenes(list(reversed(names)), 0.15, 3) and a != b


def test_colour_jitter_keeps_geometry_and_grey_and_is_seeded():
    rng = np.random.default_rng(3)
    img = rng.integers(0, 256, (24, 32, 3), dtype=np.uint8)
    a = augment_hsv(img, (0.015, 0.7, 0.4), np.random.default_rng(1))
    b = augment_hsv(img, (0.015, 0.7, 0.4), np.random.default_rng(1))
    assert a.shape == img.shape and a.dtype == np.uint8 and (a == b).all()
    assert not (a == img).all()
    # zero gains change nothing beyond the HSV round trip's rounding
    same = augment_hsv(img, (0.0, 0.0, 0.0), np.random.default_rng(1))
    assert np.abs(same.astype(int) - img).max() <= 8
    grey = np.full((4, 4, 3), 77, np.uint8)  # no hue or saturation: only the value gain acts
    out = augment_hsv(grey, (0.5, 0.5, 0.0), np.random.default_rng(2))
    assert (out == grey).all()


def test_the_gpu_configuration_runs_at_toy_size_on_the_cpu(camera_set, tmp_path):
    """--gpu selects the wider detector, DehazeFormer-S and longer budgets; here shrunk to a toy run on the CPU."""
    full = Exp2Config.gpu()
    assert (full.width, full.depth, full.dehazeformer, full.profile) == (32, 2, "S", "gpu") and full.epochs > Exp2Config().epochs
    config = Exp2Config.gpu(**{**TINY, "dehazeformer_steps": 1})
    r = run_experiment2(camera_set, tmp_path / "gpu", config, progress=False, log=lambda *_: None)
    assert r["config"]["profile"] == "gpu" and r["config"]["dehazeformer"] == "S" and "A" in r["detection"]


def test_a_detector_killed_after_an_epoch_resumes_from_its_checkpoint_to_the_uninterrupted_weights(camera_set, tmp_path,
                                                                                                  monkeypatch):  # fmt: skip
    import torch

    from fog_gym.experiments.defog.data import eval_set
    from fog_gym.experiments.defog.train import DetectionSet, train_detector
    from fog_gym.experiments.runner import EpochCheckpoint

    c = Exp2Config(**{**TINY, "epochs": 2})
    ds = FogDrive(camera_set)
    train_f, val_f = (frames(ds, ds.splits[s], 2, c.cameras) for s in ("train", "val"))
    val = eval_set(ds, val_f, "clean", tuple(c.input_size), min_height=c.min_height)

    def fit(checkpoint):
        data = DetectionSet(ds, train_f, "clean", tuple(c.input_size), augment=True, seed=0, hsv=c.hsv)
        return train_detector(data, *val, c, 0, torch.device("cpu"), "t", None, False, checkpoint=checkpoint)

    whole, whole_summary = fit(None)
    with killed_after_first_epoch(monkeypatch), pytest.raises(Killed):
        fit(tmp_path / "t.pt")
    resumed, summary = fit(tmp_path / "t.pt")
    assert summary["resumed_at_epoch"] == 1 and summary["history"] == whole_summary["history"]
    a, b = whole.state_dict(), resumed.state_dict()
    assert all(torch.equal(a[k], b[k]) for k in a)
    assert EpochCheckpoint(tmp_path / "t.pt", {"other": 1}).load() is None  # another unit's state is never loaded


def test_the_short_dehazer_units_run_before_the_detectors_and_every_model_is_one_unit(tmp_path):
    from fog_gym.experiments.defog.study import Exp2Study

    units = Exp2Study(tmp_path).units([0, 1])
    keys = [u.key for u in units]
    detectors = [f"detector_{lv}_s{s}" for s in (0, 1) for lv in ("clean", *LEVELS)]
    dehazers = [f"{m}_s{s}" for s in (0, 1) for m in ("aodnet", "dehazeformer")]
    assert keys == dehazers + detectors + ["pipelines_s0", "pipelines_s1"]
    assert [u.stage for u in units] == ["train"] * 12 + ["evaluate"] * 2
    assert all(u.seed == int(u.key[-1]) for u in units)

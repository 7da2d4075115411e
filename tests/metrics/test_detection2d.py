"""COCO-style 2D metrics: perfect predictions, known AP values, precision/recall at a confidence, empty inputs."""

import math

import numpy as np
import pytest

pytest.importorskip("pycocotools")  # in the dev extra: never skipped in CI
from fog_gym.metrics.detection2d import evaluate_coco  # noqa: E402

CAR = [100.0, 100.0, 180.0, 150.0]


def _f(boxes, classes, scores=None):
    d = {"boxes": np.asarray(boxes, float).reshape(-1, 4), "classes": np.asarray(classes)}
    if scores is not None:
        d["scores"] = np.asarray(scores, float)
    return d


def test_perfect_predictions_give_one_everywhere():
    rng = np.random.default_rng(0)
    gt, pred = [], []
    for _ in range(10):
        xy = rng.uniform(0, 500, (4, 2))
        b = np.c_[xy, xy + rng.uniform(20, 80, (4, 2))]
        c = rng.choice([0, 1, 4], 4)
        gt.append(_f(b, c))
        pred.append(_f(b, c, rng.uniform(0.3, 1, 4)))
    r = evaluate_coco(gt, pred)
    assert [r[k] for k in ("mAP50", "mAP50_95", "precision", "recall")] == pytest.approx([1.0] * 4)


def test_a_box_at_iou_0_6_counts_at_0_5_but_not_at_the_strict_thresholds():
    shifted = [CAR[0] + 20, CAR[1], CAR[2] + 20, CAR[3]]  # IoU = 60·50 / (2·80·50 − 60·50) = 0.6
    r = evaluate_coco([_f([CAR], [0])], [_f([shifted], [0], [0.9])])
    assert r["mAP50"] == pytest.approx(1.0)
    assert r["mAP50_95"] == pytest.approx(0.3, abs=1e-6)  # matched at 0.50, 0.55 and 0.60 of the ten thresholds
    r = evaluate_coco([_f([CAR], [0])], [_f([shifted], [1], [0.9])])  # wrong class
    assert r["mAP50"] == 0.0 and r["precision"] == 0.0 and r["recall"] == 0.0


def test_precision_and_recall_count_only_confident_detections():
    gt = [_f([CAR, [300, 300, 360, 340]], [0, 0])]
    pred = [_f([CAR, [300, 300, 360, 340], [10, 10, 40, 40]], [0, 0, 0], [0.9, 0.1, 0.8])]
    r = evaluate_coco(gt, pred, conf=0.25)
    assert r["precision"] == 0.5 and r["recall"] == 0.5  # the hit at 0.1 falls below the threshold
    # COCO's 101-point interpolation: precision 1 up to recall 0.5 (51 points), then 2/3 (50 points)
    assert r["AP50"] == {0: pytest.approx((51 + 50 * 2 / 3) / 101)}


def test_empty_inputs_give_documented_values():
    none = evaluate_coco([_f(np.zeros((0, 4)), [])], [_f(np.zeros((0, 4)), [], [])])
    assert math.isnan(none["mAP50"]) and none["n_gt"] == 0
    missed = evaluate_coco([_f([CAR], [0])], [_f(np.zeros((0, 4)), [], [])])
    assert missed["mAP50"] == 0.0 and missed["recall"] == 0.0


def test_bad_boxes_are_refused():
    with pytest.raises(ValueError, match=r"x1 >= x0"):
        evaluate_coco([_f([[10, 10, 5, 20]], [0])], [_f([CAR], [0], [1.0])])
    with pytest.raises(ValueError, match="one entry per image"):
        evaluate_coco([_f([CAR], [0])], [])


def test_ignored_boxes_are_neither_hits_nor_misses():
    tiny = [300.0, 300.0, 304.0, 303.0]
    gt = _f([CAR, tiny], [0, 0]) | {"ignore": np.array([False, True])}
    # missing the ignored box costs nothing
    r = evaluate_coco([gt], [_f([CAR], [0], [0.9])])
    assert (r["mAP50"], r["recall"], r["precision"], r["n_gt"], r["n_ignored"]) == (pytest.approx(1.0), 1.0, 1.0, 1, 1)
    # a detection on the ignored box is not a false positive, a detection elsewhere is
    r = evaluate_coco([gt], [_f([CAR, tiny], [0, 0], [0.9, 0.95])])
    assert r["mAP50"] == pytest.approx(1.0) and r["precision"] == 1.0
    r = evaluate_coco([gt], [_f([CAR, [0, 0, 30, 30]], [0, 0], [0.9, 0.95])])
    assert r["precision"] == 0.5 and r["mAP50"] < 1.0
    # without the flag the tiny box is a miss
    r = evaluate_coco([_f([CAR, tiny], [0, 0])], [_f([CAR], [0], [0.9])])
    assert r["recall"] == 0.5 and r["n_ignored"] == 0


def test_only_ignored_ground_truth_gives_nan_and_a_wrong_length_flag_is_refused():
    r = evaluate_coco([_f([CAR], [0]) | {"ignore": [True]}], [_f([CAR], [0], [0.9])])
    assert math.isnan(r["mAP50"]) and r["n_gt"] == 0
    with pytest.raises(ValueError, match="one entry per box"):
        evaluate_coco([_f([CAR], [0]) | {"ignore": [True, False]}], [_f([], [], [])])

"""3D detection metrics: exact IoU against shapely, known mAP / TP values, empty inputs, bad input."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fog_gym.metrics.detection3d import average_precision, evaluate, iou3d

shapely = pytest.importorskip("shapely")  # in the dev extra: never skipped in CI
from shapely.affinity import rotate, translate  # noqa: E402
from shapely.geometry import box as shapely_box  # noqa: E402

CAR = [0.0, 0.0, 0.0, 4.5, 1.9, 1.5, 0.0]


def _shapely_iou(a, b):
    def poly(x):
        p = shapely_box(-x[3] / 2, -x[4] / 2, x[3] / 2, x[4] / 2)
        return translate(rotate(p, x[6], origin=(0, 0), use_radians=True), x[0], x[1])

    dz = min(a[2] + a[5] / 2, b[2] + b[5] / 2) - max(a[2] - a[5] / 2, b[2] - b[5] / 2)
    inter = poly(a).intersection(poly(b)).area * max(dz, 0.0)
    return inter / (np.prod(a[3:6]) + np.prod(b[3:6]) - inter)


box_st = st.tuples(st.floats(-6, 6), st.floats(-6, 6), st.floats(-1, 1), st.floats(0.5, 9), st.floats(0.5, 3),
                   st.floats(0.5, 4), st.floats(-7, 7))  # fmt: skip


@settings(max_examples=300, deadline=None)
@given(box_st, box_st)
def test_iou3d_equals_shapely_and_is_symmetric(a, b):
    a, b = np.array(a), np.array(b)
    got = iou3d(a[None], b[None])[0, 0]
    assert got == pytest.approx(_shapely_iou(a, b), abs=1e-9)
    assert got == pytest.approx(iou3d(b[None], a[None])[0, 0], abs=1e-12)
    assert 0.0 <= got <= 1.0 + 1e-12


def test_iou_of_known_configurations():
    car = np.array([CAR])
    assert iou3d(car, car)[0, 0] == pytest.approx(1.0)
    assert iou3d(car, car + [10, 0, 0, 0, 0, 0, 0])[0, 0] == 0.0  # disjoint
    assert iou3d(car, car + [0, 0, 1.5, 0, 0, 0, 0])[0, 0] == 0.0  # stacked, touching
    assert iou3d(car, car + [0, 0, 0, 0, 0, 0, 2 * math.pi])[0, 0] == pytest.approx(1.0)  # yaw wrap-around
    assert iou3d(car, car + [0, 0, 0, 0, 0, 0, math.pi])[0, 0] == pytest.approx(1.0)  # a box reversed is the same box
    square = np.array([[0, 0, 0, 2, 2, 1, 0.0]])
    # a 2 × 2 square turned 45°: the intersection is an octagon of area 8(√2 − 1)
    oct_area = 8 * (math.sqrt(2) - 1)
    assert iou3d(square, square + [0, 0, 0, 0, 0, 0, math.pi / 4])[0, 0] == pytest.approx(oct_area / (8 - oct_area))
    assert iou3d(np.zeros((0, 7)), car).shape == (0, 1)


def _frames(boxes, classes, scores=None):
    f = {"boxes": np.asarray(boxes, float).reshape(-1, 7), "classes": np.asarray(classes)}
    if scores is not None:
        f["scores"] = np.asarray(scores, float)
    return f


def test_perfect_predictions_score_one_everywhere():
    rng = np.random.default_rng(0)
    gt, pred = [], []
    for _ in range(20):
        n = rng.integers(0, 6)
        b = np.c_[rng.uniform(-30, 30, (n, 2)), np.zeros(n), np.tile([4.5, 1.9, 1.5], (n, 1)), rng.uniform(-3, 3, n)]
        c = rng.choice([0, 1, 4], n)
        gt.append(_frames(b, c))
        pred.append(_frames(b, c, rng.uniform(0.1, 1, n)))
    r = evaluate(gt, pred)
    assert r["mAP"] == 1.0 and r["mean_TP"] == 1.0 and r["FDS"] == 1.0
    assert (r["ATE"], r["ASE"], r["AOE"]) == (1.0, 1.0, 1.0) and r["ATE_m"] == 0.0 and r["n_tp"] == r["n_gt"]


def test_a_half_metre_shift_is_an_ate_of_half_a_metre():
    gt = [_frames([CAR], [0])]
    pred = [_frames([np.add(CAR, [0.3, 0.4, 0, 0, 0, 0, 0])], [0], [0.8])]  # 0.5 m in the bird's-eye view
    r = evaluate(gt, pred)
    assert r["ATE_m"] == pytest.approx(0.5) and r["ATE"] == pytest.approx(0.75) and r["mAP"] == 1.0


def test_scale_and_orientation_errors_have_known_values():
    bigger = np.add(CAR, [0, 0, 0, 0.5, 0, 0, 0])  # 5.0 long instead of 4.5: scale IoU 0.9
    turned = np.add(CAR, [0, 0, 0, 0, 0, 0, 2 * math.pi - 0.1])  # wraps to 0.1 rad
    r = evaluate([_frames([CAR, np.add(CAR, [20, 0, 0, 0, 0, 0, 0])], [0, 0])],
                 [_frames([bigger, np.add(turned, [20, 0, 0, 0, 0, 0, 0])], [0, 0], [0.9, 0.8])])  # fmt: skip
    assert r["ASE_raw"] == pytest.approx(0.1 / 2) and r["AOE_rad"] == pytest.approx(0.1 / 2)
    assert r["AOE"] == pytest.approx(1 - 0.05 / math.pi)


def test_false_positives_and_misses_lower_ap_as_the_curve_says():
    gt = [_frames([CAR, np.add(CAR, [10, 0, 0, 0, 0, 0, 0])], [0, 0])]
    # scores: hit (0.9), false positive far away (0.8), second hit (0.7) → AP = 0.5·1 + 0.5·(2/3)
    pred = [_frames([CAR, np.add(CAR, [40, 0, 0, 0, 0, 0, 0]), np.add(CAR, [10, 0, 0, 0, 0, 0, 0])], [0, 0, 0],
                    [0.9, 0.8, 0.7])]  # fmt: skip
    assert evaluate(gt, pred)["mAP"] == pytest.approx(0.5 + 0.5 * 2 / 3)
    # a prediction of the wrong class does not match; classes average
    r = evaluate([_frames([CAR, np.add(CAR, [10, 0, 0, 0, 0, 0, 0])], [0, 1])],
                 [_frames([CAR, np.add(CAR, [10, 0, 0, 0, 0, 0, 0])], [0, 4], [0.9, 0.9])])  # fmt: skip
    assert r["AP"] == {0: 1.0, 1: 0.0} and r["mAP"] == 0.5
    # two predictions on one box: one true positive, one false positive
    assert average_precision(np.array([1.0, 0.0]), 1) == 1.0


def test_empty_inputs_give_the_documented_values():
    none = evaluate([_frames(np.zeros((0, 7)), [])], [_frames(np.zeros((0, 7)), [], [])])
    assert math.isnan(none["mAP"]) and math.isnan(none["FDS"]) and math.isnan(none["ATE_m"]) and none["ATE"] == 0.0
    missed = evaluate([_frames([CAR], [0])], [_frames(np.zeros((0, 7)), [], [])])
    assert missed["mAP"] == 0.0 and missed["mean_TP"] == 0.0 and missed["FDS"] == 0.0
    assert evaluate([], [])["n_gt"] == 0


@pytest.mark.parametrize("gt, pred, message", [
    ([{"boxes": np.zeros((1, 6)), "classes": [0]}], None, r"gt\[0\]\['boxes'\] must be an \(N, 7\) array"),
    ([{"boxes": [CAR], "classes": [0, 1]}], None, "one row per box"),
    ([_frames([CAR], [0])], [{"boxes": [CAR], "classes": [0]}], r'pred\[0\] must be a dict with "boxes", "classes", "scores"'),
    ([_frames([CAR], [0])], [], "one entry per frame"),
    ([{"boxes": [[0, 0, 0, -1, 1, 1, 0]], "classes": [0]}], None, "positive sizes"),
    ({"boxes": [CAR]}, None, "one dict per frame"),
])  # fmt: skip
def test_bad_input_is_refused_with_a_clear_message(gt, pred, message):
    with pytest.raises(ValueError, match=message):
        evaluate(gt, pred if pred is not None else [_frames([CAR], [0], [1.0])])

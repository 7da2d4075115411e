"""Experiment 2's YOLO-style detector: the task-aligned assigner against a hand-worked example, CIoU at known values,
DFL, NMS, shapes, and overfitting a handful of images to mAP@0.5 ≥ 0.9."""

import math

import numpy as np
import pytest

torch = pytest.importorskip("torch")  # the torch extra is part of the dev extra: never skipped in CI

from fog_gym.experiments.defog.yolo import YoloConfig, YoloDetector, anchor_points, decode, nms  # noqa: E402
from fog_gym.experiments.defog.yolo_loss import assign, ciou, detection_loss, dfl  # noqa: E402
from fog_gym.metrics.detection2d import evaluate_coco  # noqa: E402


def test_the_assigner_matches_a_hand_worked_example():
    """Three anchors in a row, two overlapping boxes; the middle anchor lies in both and goes to the one it overlaps
    more; the targets are the normalised alignments t / max t × max IoU."""
    points = torch.tensor([[2.0, 2.0], [6.0, 2.0], [10.0, 2.0]])
    pred = torch.tensor([[[0.0, 0.0, 8.0, 4.0], [3.0, 0.0, 11.0, 4.0], [4.0, 0.0, 12.0, 4.0]]])
    gt = torch.tensor([[[0.0, 0.0, 8.0, 4.0], [4.0, 0.0, 12.0, 4.0]]])
    scores = torch.full((1, 3, 3), 0.5)
    boxes, target, fg = assign(scores, pred, points, gt, torch.tensor([[0, 1]]), torch.ones(1, 2, dtype=torch.bool),
                               finest=3, top_k=2)  # fmt: skip
    assert fg.tolist() == [[True, True, True]]
    assert boxes[0].tolist() == [[0.0, 0.0, 8.0, 4.0], [4.0, 0.0, 12.0, 4.0], [4.0, 0.0, 12.0, 4.0]]
    iou_mid = 28.0 / 36.0  # the middle prediction against the second box: 7 × 4 over 32 + 32 − 28
    want = np.array([[1.0, 0.0, 0.0], [0.0, iou_mid**6, 0.0], [0.0, 1.0, 0.0]])
    np.testing.assert_allclose(target[0].numpy(), want, rtol=1e-5, atol=1e-7)
    # with one positive per box, the middle anchor is nobody's
    _, target1, fg1 = assign(scores, pred, points, gt, torch.tensor([[0, 1]]), torch.ones(1, 2, dtype=torch.bool),
                             finest=3, top_k=1)  # fmt: skip
    assert fg1.tolist() == [[True, False, True]] and target1[0, 1].sum() == 0


def test_a_box_smaller_than_every_stride_still_gets_the_nearest_finest_anchor():
    points, _ = anchor_points([(4, 4), (2, 2)], strides=(4, 8))
    gt = torch.tensor([[[5.2, 5.2, 5.8, 5.9]]])  # holds no cell centre
    a = len(points)
    pred = torch.cat([points - 2, points + 2], 1)[None]
    _, target, fg = assign(torch.full((1, a, 3), 0.5), pred, points, gt, torch.tensor([[2]]),
                           torch.ones(1, 1, dtype=torch.bool), finest=16)  # fmt: skip
    assert fg.sum() == 1 and int(fg[0].nonzero()[0]) == 5  # the centre (6, 6) of cell (1, 1)
    assert target[0, 5, 2] > 0


@pytest.mark.parametrize("a, b, want", [
    ([0, 0, 10, 10], [0, 0, 10, 10], 1.0),
    ([0, 0, 10, 10], [2.5, 2.5, 7.5, 7.5], 0.25),  # same centre and shape: CIoU = IoU
    ([0, 0, 10, 10], [5, 0, 15, 10], 1 / 3 - 25 / 325),  # same size, shifted: IoU − ρ² / c²
    ([0, 0, 10, 10], [0, 0, 20, 10], None),  # the aspect term too (computed below)
])  # fmt: skip
def test_ciou_at_known_values(a, b, want):
    if want is None:
        v = 4 / math.pi**2 * (math.atan(2.0) - math.atan(1.0)) ** 2
        want = 0.5 - 25 / 500 - v / (0.5 + v) * v
    got = float(ciou(torch.tensor([a], dtype=torch.float64), torch.tensor([b], dtype=torch.float64))[0])
    assert got == pytest.approx(want, abs=1e-7)


def test_dfl_is_smallest_at_the_target_distance():
    target = torch.tensor([[3.25, 0.0, 7.5, 14.0]])
    good = torch.full((1, 4, 16), -20.0)
    for k, t in enumerate(target[0].tolist()):
        lo = int(math.floor(t))
        good[0, k, lo], good[0, k, min(lo + 1, 15)] = math.log(lo + 1 - t + 1e-9), math.log(t - lo + 1e-9)
    bad = torch.zeros(1, 4, 16)
    assert (dfl(good, target) < dfl(bad, target)).all()
    # at its minimum the loss is the entropy of the two-bin split: 3.25 → (¾, ¼), 0 → (1, 0), 7.5 → (½, ½), 14 → (1, 0)
    h = -(0.75 * math.log(0.75) + 0.25 * math.log(0.25))
    np.testing.assert_allclose(dfl(good, target)[0].numpy(), [h, 0.0, math.log(2), 0.0], atol=1e-4)


def test_nms_is_class_aware_and_keeps_the_best_of_each_overlapping_group():
    b = np.array([[0, 0, 10, 10], [1, 0, 11, 10], [30, 30, 40, 40], [0, 0, 10, 10.0]])
    keep = nms(b, np.array([0.5, 0.9, 0.8, 0.3]), np.array([0, 0, 0, 4]), 0.6)
    assert keep.tolist() == [1, 2, 3]


def test_the_detector_outputs_one_prediction_per_cell_at_strides_4_8_16_and_refuses_odd_sizes():
    net = YoloDetector(YoloConfig(width=8))
    out = net(torch.zeros(2, 3, 64, 96))
    assert [tuple(o.shape) for o in out] == [(2, 67, 16, 24), (2, 67, 8, 12), (2, 67, 4, 6)]
    with pytest.raises(ValueError, match="multiples of 32"):
        net(torch.zeros(1, 3, 60, 96))
    with pytest.raises(ValueError, match="width must be a positive integer"):
        YoloConfig(width=0)


def _synthetic(seed: int, n: int = 4, size: int = 64):
    rng = np.random.default_rng(seed)
    colours = {0: (220, 40, 40), 1: (40, 200, 40), 2: (40, 40, 220)}
    images, boxes, classes = [], [], []
    for _ in range(n):
        img = np.full((size, size, 3), 110, np.uint8)
        bs, cs = [], []
        for _ in range(rng.integers(2, 4)):
            w, h = rng.integers(8, 24, 2)
            x, y = rng.integers(0, size - w), rng.integers(0, size - h)
            c = int(rng.integers(0, 3))
            img[y:y + h, x:x + w] = colours[c]
            bs.append([x, y, x + w, y + h])
            cs.append(c)
        images.append(img)
        boxes.append(np.array(bs, np.float32))
        classes.append(np.array(cs))
    return images, boxes, classes


def test_the_detector_overfits_a_handful_of_images():
    images, boxes, classes = _synthetic(0)
    torch.manual_seed(0)
    net = YoloDetector(YoloConfig(width=8))
    opt = torch.optim.AdamW(net.parameters(), 3e-3)
    x = torch.from_numpy(np.stack(images)).permute(0, 3, 1, 2).float() / 255
    g = max(len(b) for b in boxes)
    gb = torch.zeros(len(images), g, 4)
    gc = torch.zeros(len(images), g, dtype=torch.long)
    gm = torch.zeros(len(images), g, dtype=torch.bool)
    for k, (b, c) in enumerate(zip(boxes, classes, strict=True)):
        gb[k, : len(b)], gc[k, : len(c)], gm[k, : len(c)] = torch.from_numpy(b), torch.from_numpy(c), True
    gt = [{"boxes": b, "classes": np.array([0, 4, 1])[c]} for b, c in zip(boxes, classes, strict=True)]
    best = 0.0
    for step in range(300):
        net.train()
        loss, _ = detection_loss(net(x), gb, gc, gm)
        opt.zero_grad()
        loss.backward()
        opt.step()
        if step % 25 == 24:
            net.eval()
            with torch.no_grad():
                best = evaluate_coco(gt, decode(net(x)))["mAP50"]
            if best >= 0.9:
                break
    assert best >= 0.9

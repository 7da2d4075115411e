"""The 2D CenterNet: targets decode back to the boxes (COCO mAP 1), and training lowers the loss."""

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("pycocotools")

from fog_gym.experiments.defog.model import CLASSES, CenterNet2D, decode, loss_fn, make_targets  # noqa: E402
from fog_gym.metrics.detection2d import evaluate_coco  # noqa: E402


def _boxes():
    return np.array([[20, 30, 100, 90], [150, 100, 190, 130], [230, 40, 310, 200]], float), np.array([0, 4, 1])


def test_a_perfect_output_decodes_to_the_boxes():
    boxes, classes = _boxes()
    t = make_targets(boxes, classes, (60, 80))
    heat = torch.full((1, 3, 60, 80), -20.0)
    wh = torch.zeros((1, 2, 60 * 80))
    off = torch.zeros((1, 2, 60 * 80))
    for k, c in enumerate(classes):
        heat[0, CLASSES.index(int(c))].view(-1)[t["index"][k]] = 5.0
        wh[0, :, t["index"][k]] = torch.from_numpy(t["wh"][k])
        off[0, :, t["index"][k]] = torch.from_numpy(t["offset"][k])
    pred = decode({"heatmap": heat, "wh": wh.view(1, 2, 60, 80), "offset": off.view(1, 2, 60, 80)})
    np.testing.assert_allclose(pred[0]["boxes"][np.argsort(pred[0]["classes"])], boxes[np.argsort(classes)], atol=1e-4)
    r = evaluate_coco([{"boxes": boxes, "classes": classes}], pred)
    assert r["mAP50_95"] == pytest.approx(1.0)


def test_training_lowers_the_loss():
    rng = np.random.default_rng(0)
    boxes, classes = _boxes()
    boxes = boxes / 2  # a 160 × 120 input
    img = torch.from_numpy(rng.uniform(0.3, 0.6, (2, 3, 120, 160)).astype(np.float32))
    for b in boxes.astype(int):
        img[:, :, b[1]:b[3], b[0]:b[2]] = 0.05
    t = make_targets(boxes, classes, (30, 40))
    heat = torch.from_numpy(np.stack([t["heatmap"]] * 2))
    bidx = torch.tensor([0, 0, 0, 1, 1, 1])
    cidx = torch.from_numpy(np.concatenate([t["index"]] * 2))
    wh, off = torch.from_numpy(np.concatenate([t["wh"]] * 2)), torch.from_numpy(np.concatenate([t["offset"]] * 2))
    torch.manual_seed(0)
    model = CenterNet2D(width=8)
    opt = torch.optim.Adam(model.parameters(), 3e-3)
    losses = []
    for _ in range(20):
        loss, _ = loss_fn(model(img), heat, bidx, cidx, wh, off)
        opt.zero_grad()
        loss.backward()
        opt.step()
        losses.append(float(loss.detach()))
    assert losses[-1] < 0.5 * losses[0]

"""2D detection metrics of FogDrive's Experiment 2 through the COCO reference implementation (pycocotools).

Frames are dicts with ``"boxes"`` ``(N, 4)`` ``[x0, y0, x1, y1]`` in pixels and ``"classes"`` ``(N,)`` FogDrive class
ids; predictions also ``"scores"``; ground truth may carry ``"ignore"`` ``(N,)`` booleans: such boxes are COCO "crowd"
regions — a detection on one is neither a true nor a false positive and they do not count towards recall (KITTI's
and COCO's way of leaving out objects too small to judge). :func:`evaluate_coco` builds the COCO ground truth and results in memory, runs
``COCOeval`` (bbox, all areas, 100 detections per image) and reports ``mAP50_95`` (COCO's AP @ [.5:.95]), ``mAP50``,
per-class ``AP50``, and ``precision`` / ``recall`` at IoU 0.5 for the detections scoring at least ``conf``
(0.25, as YOLO-style tables), counted from COCOeval's own matches.

Example:
    >>> f = {"boxes": [[10, 10, 50, 40]], "classes": [0]}
    >>> r = evaluate_coco([f], [{**f, "scores": [0.9]}])
    >>> [round(r[k], 6) for k in ("mAP50", "mAP50_95", "precision", "recall")]
    [1.0, 1.0, 1.0, 1.0]
"""

from __future__ import annotations

import contextlib
import io
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np


def _frames(frames: Sequence[Mapping[str, Any]], name: str, scores: bool) -> list[tuple[np.ndarray, ...]]:
    if isinstance(frames, Mapping) or not isinstance(frames, Sequence):
        raise ValueError(f"{name} must be a list with one dict per image, got {type(frames).__name__}")
    out = []
    for k, f in enumerate(frames):
        if not isinstance(f, Mapping) or "boxes" not in f or "classes" not in f or (scores and "scores" not in f):
            raise ValueError(f"{name}[{k}] must be a dict with \"boxes\", \"classes\"" + (', "scores"' if scores else ""))
        b = np.asarray(f["boxes"], np.float64).reshape(-1, 4) if len(f["boxes"]) else np.zeros((0, 4))
        if not np.isfinite(b).all() or (b[:, 2] < b[:, 0]).any() or (b[:, 3] < b[:, 1]).any():
            raise ValueError(f"{name}[{k}]['boxes'] must be finite [x0, y0, x1, y1] rows with x1 >= x0, y1 >= y0")
        c = np.asarray(f["classes"], np.int64).reshape(-1)
        s = np.asarray(f["scores"], np.float64).reshape(-1) if scores else np.ones(len(b))
        if len(c) != len(b) or len(s) != len(b):
            raise ValueError(f"{name}[{k}]: boxes, classes and scores must have one row per box")
        ign = np.asarray(f.get("ignore", np.zeros(len(b), bool)), bool).reshape(-1) if not scores else np.zeros(len(b), bool)
        if len(ign) != len(b):
            raise ValueError(f"{name}[{k}]['ignore'] must have one entry per box, got {len(ign)} for {len(b)} boxes")
        out.append((b, c, s, ign))
    return out


def evaluate_coco(gt: Sequence[Mapping[str, Any]], pred: Sequence[Mapping[str, Any]], classes: Sequence[int] = (0, 4, 1),
                  conf: float = 0.25) -> dict[str, Any]:  # fmt: skip
    """COCO-style 2D detection metrics (module docstring). Classes without ground truth are left out of the means;
    no ground truth at all gives NaN."""
    from pycocotools.coco import COCO
    from pycocotools.cocoeval import COCOeval

    g, p = _frames(gt, "gt", False), _frames(pred, "pred", True)
    if len(g) != len(p):
        raise ValueError(f"gt and pred must have one entry per image, got {len(g)} and {len(p)}")
    images = [{"id": i + 1} for i in range(len(g))]
    cats = [{"id": int(c) + 1, "name": str(c)} for c in classes]  # COCO ids start at 1
    anns = []
    for i, (b, c, _, ign) in enumerate(g):
        for k in range(len(b)):
            w, h = b[k, 2] - b[k, 0], b[k, 3] - b[k, 1]
            anns.append({"id": len(anns) + 1, "image_id": i + 1, "category_id": int(c[k]) + 1, "iscrowd": int(ign[k]),
                         "bbox": [float(b[k, 0]), float(b[k, 1]), float(w), float(h)], "area": float(w * h)})  # fmt: skip
    dets = [{"image_id": i + 1, "category_id": int(c[k]) + 1, "score": float(s[k]),
             "bbox": [float(b[k, 0]), float(b[k, 1]), float(b[k, 2] - b[k, 0]), float(b[k, 3] - b[k, 1])]}
            for i, (b, c, s, _) in enumerate(p) for k in range(len(b))]  # fmt: skip
    present = sorted({int(a["category_id"]) for a in anns if not a["iscrowd"]})
    n_gt = sum(1 for a in anns if not a["iscrowd"])
    result: dict[str, Any] = {"n_gt": n_gt, "n_ignored": len(anns) - n_gt, "n_pred": len(dets)}
    if not n_gt:
        return result | {"mAP50_95": float("nan"), "mAP50": float("nan"), "AP50": {}, "precision": float("nan"),
                         "recall": float("nan")}  # fmt: skip
    with contextlib.redirect_stdout(io.StringIO()):  # pycocotools prints progress
        coco = COCO()
        coco.dataset = {"images": images, "categories": cats, "annotations": anns}
        coco.createIndex()
        results = coco.loadRes(dets) if dets else COCO()
        if not dets:
            results.dataset = {"images": images, "categories": cats, "annotations": []}
            results.createIndex()
        ev = COCOeval(coco, results, "bbox")
        ev.params.catIds = present
        ev.evaluate()
        ev.accumulate()
    prec = ev.eval["precision"]  # [T, R, K, A, M]; −1 where undefined
    per_class_50, per_class = {}, []
    for k, cat in enumerate(present):
        pr50 = prec[0, :, k, 0, -1]
        pr = prec[:, :, k, 0, -1]
        per_class_50[cat - 1] = float(np.mean(pr50[pr50 > -1])) if (pr50 > -1).any() else 0.0
        per_class.append(float(np.mean(pr[pr > -1])) if (pr > -1).any() else 0.0)
    tp = fp = 0
    for e in ev.evalImgs:  # area "all" entries come first per category and image
        if e is None or e["aRng"] != ev.params.areaRng[0]:
            continue
        keep = (np.asarray(e["dtScores"]) >= conf) & ~np.asarray(e["dtIgnore"][0], bool)
        matched = np.asarray(e["dtMatches"][0]) > 0
        tp += int((matched & keep).sum())
        fp += int((~matched & keep).sum())
    return result | {
        "mAP50_95": float(np.mean(per_class)), "mAP50": float(np.mean(list(per_class_50.values()))),
        "AP50": per_class_50, "precision": tp / (tp + fp) if tp + fp else 0.0, "recall": tp / n_gt,
    }  # fmt: skip

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

from fog_gym.metrics.bootstrap import nanmean


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


def coco_matches(gt: Sequence[Mapping[str, Any]], pred: Sequence[Mapping[str, Any]], classes: Sequence[int] = (0, 4, 1),
                 conf: float = 0.25) -> dict[str, Any]:  # fmt: skip
    """COCOeval's own per-image matching (pycocotools ``evaluate()``: bbox, area "all", 100 detections per image and
    class), kept per image so that :func:`coco_summarise` can score any multiset of the images — a bootstrap
    resample — without matching again. Per present class: every kept detection's image, score, match flags at
    the ten IoU thresholds and ignore flags, in COCOeval's accumulation order; the non-ignored ground truth per
    image."""
    from pycocotools.coco import COCO
    from pycocotools.cocoeval import COCOeval

    g, p = _frames(gt, "gt", False), _frames(pred, "pred", True)
    if len(g) != len(p):
        raise ValueError(f"gt and pred must have one entry per image, got {len(g)} and {len(p)}")
    images = [{"id": i + 1} for i in range(len(g))]
    cats = [{"id": int(c) + 1, "name": str(c)} for c in classes]
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
    out: dict[str, Any] = {"images": len(g), "classes": {}, "conf": conf}
    if not present:
        return out
    with contextlib.redirect_stdout(io.StringIO()):
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
    n_img, n_area, n_thr = len(ev.params.imgIds), len(ev.params.areaRng), len(ev.params.iouThrs)
    for k, cat in enumerate(present):
        scores, image, matched, ignored, n_gt = [], [], [], [], np.zeros(len(g), np.int64)
        for i in range(n_img):
            e = ev.evalImgs[k * n_area * n_img + i]  # area "all" comes first for each class
            if e is None:
                continue
            img = e["image_id"] - 1
            d = len(e["dtScores"])
            scores.append(np.asarray(e["dtScores"], np.float64))
            image.append(np.full(d, img, np.int64))
            matched.append(np.asarray(e["dtMatches"]).reshape(n_thr, d) > 0)
            ignored.append(np.asarray(e["dtIgnore"]).reshape(n_thr, d).astype(bool))
            n_gt[img] = int(np.count_nonzero(np.asarray(e["gtIgnore"]) == 0))
        s = np.concatenate(scores) if scores else np.zeros(0)
        order = np.argsort(-s, kind="mergesort")  # COCOeval.accumulate's order
        t = len(ev.params.iouThrs)
        out["classes"][cat - 1] = {
            "scores": s[order], "image": np.concatenate(image)[order] if image else np.zeros(0, np.int64),
            "matched": np.concatenate(matched, axis=1)[:, order] if matched else np.zeros((t, 0), bool),
            "ignored": np.concatenate(ignored, axis=1)[:, order] if ignored else np.zeros((t, 0), bool),
            "n_gt": n_gt,
        }  # fmt: skip
    out["rec_thrs"] = np.asarray(ev.params.recThrs)
    return out


def _coco_ap(tp: np.ndarray, fp: np.ndarray, w: np.ndarray, npig: np.ndarray, rec_thrs: np.ndarray) -> np.ndarray:
    """COCOeval.accumulate's AP (101-point interpolated precision) per row of ``w`` (R, D): each detection counted
    ``w`` times; ``npig`` (R,) non-ignored ground truth. NaN where ``npig`` is 0."""
    r = len(w)
    out = np.full(r, np.nan)
    if tp.size == 0:
        out[npig > 0] = 0.0
        return out
    tp_sum = np.cumsum(w * tp, axis=1)
    fp_sum = np.cumsum(w * fp, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        rc = tp_sum / np.where(npig > 0, npig, 1)[:, None]
    pr = tp_sum / (fp_sum + tp_sum + np.spacing(1))
    pr = np.maximum.accumulate(pr[:, ::-1], axis=1)[:, ::-1]
    nd = tp.shape[-1]
    for j in range(r):
        if npig[j] <= 0:
            continue
        idx = np.searchsorted(rc[j], rec_thrs, side="left")
        q = np.where(idx < nd, pr[j, np.minimum(idx, nd - 1)], 0.0)
        out[j] = q.mean()
    return out


def coco_summarise(m: Mapping[str, Any], weights: np.ndarray | None = None, thresholds: Sequence[int] = (0,),
                   chunk: int = 64) -> dict[str, Any]:  # fmt: skip
    """``mAP50`` (and ``mAP50_95`` when ``thresholds`` is all ten), per-class ``AP50``, ``precision`` and
    ``recall`` at the matches' ``conf`` from a :func:`coco_matches` result, each image counted ``weights[i]``
    times: ``weights`` (F,) gives scalars, (R, F) arrays over R resamples; default: every image once (then equal to
    :func:`evaluate_coco`)."""
    single = weights is None or np.ndim(weights) == 1
    w_all = np.ones((1, m["images"])) if weights is None else np.atleast_2d(np.asarray(weights, np.float64))
    if w_all.shape[1] != m["images"]:
        raise ValueError(f"weights must have one entry per image ({m['images']}), got shape {w_all.shape}")
    r = len(w_all)
    ap50: dict[int, np.ndarray] = {}
    ap_all: list[np.ndarray] = []
    tp_c = np.zeros(r)
    fp_c = np.zeros(r)
    n_gt = np.zeros(r)
    for cls, c in m.get("classes", {}).items():
        npig = w_all @ c["n_gt"].astype(np.float64)
        n_gt += npig
        per_t = []
        for t in thresholds:
            tp = (c["matched"][t] & ~c["ignored"][t]).astype(np.float64)
            fp = (~c["matched"][t] & ~c["ignored"][t]).astype(np.float64)
            vals = np.concatenate([_coco_ap(tp, fp, w_all[s:s + chunk][:, c["image"]], npig[s:s + chunk], m["rec_thrs"])
                                   for s in range(0, r, chunk)])  # fmt: skip
            per_t.append(vals)
            if t == 0:
                ap50[cls] = vals
        ap_all.append(np.mean(per_t, axis=0))
        keep = (c["scores"] >= m["conf"]) & ~c["ignored"][0]
        wd = w_all[:, c["image"]] * (npig > 0)[:, None]  # a class without ground truth in a resample is not evaluated
        tp_c += (wd * (keep & c["matched"][0])).sum(1)
        fp_c += (wd * (keep & ~c["matched"][0])).sum(1)
    with np.errstate(invalid="ignore"):
        stack = np.stack(list(ap50.values())) if ap50 else np.full((1, r), np.nan)
        out = {"mAP50": nanmean(stack) if ap50 else np.full(r, np.nan),
               "precision": np.where(n_gt > 0, np.where(tp_c + fp_c > 0, tp_c / np.maximum(tp_c + fp_c, 1e-300), 0.0), np.nan),
               "recall": np.where(n_gt > 0, tp_c / np.maximum(n_gt, 1e-300), np.nan), "AP50": ap50}  # fmt: skip
        if len(thresholds) == 10:
            out["mAP50_95"] = nanmean(np.stack(ap_all)) if ap_all else np.full(r, np.nan)
    if single:
        out = {k: ({c: float(v[0]) for c, v in x.items()} if k == "AP50" else float(x[0])) for k, x in out.items()}
    return out

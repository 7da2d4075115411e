"""3D detection metrics of FogDrive's Experiment 1: exact oriented-box IoU, mAP@0.5, TP errors, Mean TP and FDS.

Boxes are ``(N, 7)`` arrays ``[x, y, z, l, w, h, yaw]``: centre (z is the box centre), length along the heading,
width, height, yaw about +z in radians, all in the LiDAR frame. Pure numpy + numba, no torch.

:func:`evaluate` (per class, then averaged over the classes that have ground truth):

* **Matching**: predictions of a class, over all frames, in descending score; each takes the unmatched ground
  truth box of its frame and class with the highest 3D IoU if that IoU ≥ ``iou_threshold`` (0.5): a true
  positive; otherwise a false positive (greedy, as KITTI/COCO).
* **AP**: area under the precision–recall curve with precision made monotone (each precision replaced by the
  highest precision at equal or higher recall) and integrated over every recall step ("all-point
  interpolation", VOC 2010+); no ground truth of a class → the class is left out; no predictions → AP 0.
* **TP errors** over all matched pairs: translation ``ATE_m`` = bird's-eye-view centre distance [m] (nuScenes);
  scale ``ASE_raw`` = 1 − IoU of the two boxes after aligning centre and yaw (nuScenes' ASE); orientation
  ``AOE_rad`` = smallest yaw difference in [0, π]. Scores ``ATE = 1 − ATE_m / 2 m``, ``ASE = 1 − ASE_raw / 1``,
  ``AOE = 1 − AOE_rad / π``, each clipped to [0, 1]; ``mean_TP`` is their mean and ``FDS = 0.5·mAP + 0.5·mean_TP``.
* **Empty inputs**: no ground truth at all → ``mAP`` (and ``FDS``) is NaN; no matched pair → raw errors NaN and
  the three scores 0 (the worst value, as nuScenes does for classes without true positives).

Example:
    >>> box = np.array([[0.0, 0.0, 0.0, 4.0, 2.0, 1.5, 0.3]])
    >>> round(float(iou3d(box, box)[0, 0]), 9)
    1.0
    >>> r = evaluate([{"boxes": box, "classes": [0]}], [{"boxes": box, "classes": [0], "scores": [0.9]}])
    >>> r["mAP"], r["mean_TP"], r["FDS"]
    (1.0, 1.0, 1.0)
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numba import njit

from fog_gym.geometry import polygon_area
from fog_gym.metrics.bootstrap import nanmean

ATE_CAP_M = 2.0
ASE_CAP = 1.0
AOE_CAP_RAD = math.pi


def as_boxes(boxes: Any, name: str = "boxes") -> np.ndarray:
    """Validate ``(N, 7)`` finite boxes with positive sizes; returns a float64 array."""
    b = np.asarray(boxes, np.float64)
    if b.size == 0:
        return np.zeros((0, 7))
    if b.ndim != 2 or b.shape[1] != 7:
        raise ValueError(f"{name} must be an (N, 7) array [x, y, z, l, w, h, yaw], got shape {b.shape}")
    if not np.isfinite(b).all():
        raise ValueError(f"{name} must be finite")
    if (b[:, 3:6] <= 0).any():
        raise ValueError(f"{name} must have positive sizes l, w, h (columns 3-5)")
    return b


@njit(cache=True, nogil=True)
def _corners_bev(b):
    """Counter-clockwise BEV corners (4, 2) of one box (x, y, z, l, w, h, yaw)."""
    c, s = math.cos(b[6]), math.sin(b[6])
    hl, hw = b[3] / 2.0, b[4] / 2.0
    out = np.empty((4, 2))
    signs = ((1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0), (1.0, -1.0))
    for k in range(4):
        lx, ly = signs[k][0] * hl, signs[k][1] * hw
        out[k, 0] = b[0] + lx * c - ly * s
        out[k, 1] = b[1] + lx * s + ly * c
    return out


@njit(cache=True, nogil=True)
def _clip_convex(subject, n, clip):
    """Sutherland–Hodgman: polygon ``subject`` (n points) clipped by the convex CCW quadrilateral ``clip``."""
    poly = subject
    for e in range(4):
        ax, ay = clip[e, 0], clip[e, 1]
        bx, by = clip[(e + 1) % 4, 0], clip[(e + 1) % 4, 1]
        out = np.empty((n + 4, 2))
        m = 0
        for k in range(n):
            p, q = poly[k], poly[(k + 1) % n]
            dp = (bx - ax) * (p[1] - ay) - (by - ay) * (p[0] - ax)  # > 0: left of the edge (inside)
            dq = (bx - ax) * (q[1] - ay) - (by - ay) * (q[0] - ax)
            if dp >= 0:
                out[m] = p
                m += 1
            if (dp >= 0) != (dq >= 0):
                t = dp / (dp - dq)
                out[m, 0] = p[0] + t * (q[0] - p[0])
                out[m, 1] = p[1] + t * (q[1] - p[1])
                m += 1
        poly, n = out, m
        if n == 0:
            break
    return poly, n


@njit(cache=True, nogil=True)
def _iou3d(a, b):
    out = np.zeros((a.shape[0], b.shape[0]))
    for i in range(a.shape[0]):
        ca = _corners_bev(a[i])
        ra = 0.5 * math.hypot(a[i, 3], a[i, 4])
        va = a[i, 3] * a[i, 4] * a[i, 5]
        for j in range(b.shape[0]):
            rb = 0.5 * math.hypot(b[j, 3], b[j, 4])
            if math.hypot(a[i, 0] - b[j, 0], a[i, 1] - b[j, 1]) >= ra + rb:
                continue  # circumscribed circles apart: no overlap
            dz = min(a[i, 2] + a[i, 5] / 2, b[j, 2] + b[j, 5] / 2) - max(a[i, 2] - a[i, 5] / 2, b[j, 2] - b[j, 5] / 2)
            if dz <= 0:
                continue
            poly, n = _clip_convex(ca, 4, _corners_bev(b[j]))
            inter = polygon_area(poly, n) * dz
            vb = b[j, 3] * b[j, 4] * b[j, 5]
            out[i, j] = inter / (va + vb - inter)
    return out


def iou3d(a: Any, b: Any) -> np.ndarray:
    """Exact 3D IoU ``(N, M)`` of oriented boxes ``(N, 7)`` and ``(M, 7)``: rotated BEV polygon intersection times
    height overlap, over the union volume.

    >>> a = np.array([[0, 0, 0, 2, 2, 2, 0.0]]); b = np.array([[1, 0, 0, 2, 2, 2, 0.0]])
    >>> round(float(iou3d(a, b)[0, 0]), 6)  # half overlap: 4 / (8 + 8 - 4)
    0.333333
    """
    return _iou3d(np.ascontiguousarray(as_boxes(a, "a")), np.ascontiguousarray(as_boxes(b, "b")))


def _wrap(angle: np.ndarray) -> np.ndarray:
    """Smallest absolute angle difference in [0, π]."""
    return np.abs((np.asarray(angle) + np.pi) % (2 * np.pi) - np.pi)


def scale_iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """IoU of boxes with sizes ``a`` and ``b`` (…, 3) after aligning centre and orientation (nuScenes' ASE)."""
    inter = np.prod(np.minimum(a, b), axis=-1)
    return inter / (np.prod(a, axis=-1) + np.prod(b, axis=-1) - inter)


def average_precision(tp: np.ndarray, n_gt: int) -> float:
    """All-point interpolated AP of detections sorted by descending score (``tp``: 1 true / 0 false positive).

    >>> average_precision(np.array([1, 0, 1]), 2)  # recall 0.5 @ precision 1, recall 1 @ precision 2/3
    0.8333333333333333
    """
    if n_gt == 0:
        return float("nan")
    if len(tp) == 0:
        return 0.0
    tp = np.asarray(tp, np.float64)
    ctp = np.cumsum(tp)
    recall = ctp / n_gt
    precision = ctp / np.arange(1, len(tp) + 1)
    precision = np.maximum.accumulate(precision[::-1])[::-1]  # monotone envelope
    steps = np.diff(np.concatenate([[0.0], recall]))
    return float(np.sum(steps * precision))


def _concat(parts: list[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Boxes and scores of all frames stacked, with frame offsets (len + 1)."""
    sizes = np.array([len(b) for b, _ in parts], np.int64)
    offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    boxes = np.concatenate([b for b, _ in parts]) if parts else np.zeros((0, 7))
    scores = np.concatenate([s for _, s in parts]) if parts else np.zeros(0)
    return np.ascontiguousarray(boxes, np.float64).reshape(-1, 7), np.asarray(scores, np.float64), offsets


@njit(cache=True, nogil=True)
def _match(pb, ps, po, gb, go, thr):
    """Greedy matching per frame: predictions in descending score take the free ground truth of highest IoU."""
    match = np.full(pb.shape[0], -1, np.int64)
    for f in range(len(po) - 1):
        p0, p1, g0, g1 = po[f], po[f + 1], go[f], go[f + 1]
        if p1 == p0 or g1 == g0:
            continue
        iou = _iou3d(pb[p0:p1], gb[g0:g1])
        taken = np.zeros(g1 - g0, np.bool_)
        for i in np.argsort(-ps[p0:p1], kind="mergesort"):
            best, bj = thr, -1
            for j in range(g1 - g0):
                if not taken[j] and iou[i, j] >= best:
                    best, bj = iou[i, j], j
            if bj >= 0:
                taken[bj] = True
                match[p0 + i] = g0 + bj
    return match


def _check_frames(frames: Sequence[Mapping[str, Any]], name: str, scores: bool) -> list[tuple]:
    if isinstance(frames, Mapping) or not isinstance(frames, Sequence):
        raise ValueError(f"{name} must be a list with one dict per frame, got {type(frames).__name__}")
    out = []
    for k, f in enumerate(frames):
        if not isinstance(f, Mapping) or "boxes" not in f or "classes" not in f or (scores and "scores" not in f):
            keys = '"boxes", "classes"' + (', "scores"' if scores else "")
            raise ValueError(f"{name}[{k}] must be a dict with {keys}")
        b = as_boxes(f["boxes"], f"{name}[{k}]['boxes']")
        c = np.asarray(f["classes"], np.int64).reshape(-1)
        s = np.asarray(f["scores"], np.float64).reshape(-1) if scores else None
        if len(c) != len(b) or (s is not None and len(s) != len(b)):
            raise ValueError(f"{name}[{k}]: boxes, classes{' and scores' if scores else ''} must have one row per box")
        out.append((b, c, s))
    return out


def match_frames(gt: Sequence[Mapping[str, Any]], pred: Sequence[Mapping[str, Any]], iou_threshold: float = 0.5,
                 classes: Sequence[int] | None = None) -> dict[str, Any]:  # fmt: skip
    """The matching of :func:`evaluate`, kept per frame so that a metric of any multiset of the frames (a
    bootstrap resample) follows without matching again (:func:`summarise`): per class, the predictions in
    descending score with their frame and whether each is a true positive, the ground truth count per frame, and
    the TP errors of every matched pair with its frame."""
    g = _check_frames(gt, "gt", scores=False)
    p = _check_frames(pred, "pred", scores=True)
    if len(g) != len(p):
        raise ValueError(f"gt and pred must have one entry per frame, got {len(g)} and {len(p)}")
    if not 0.0 < float(iou_threshold) <= 1.0:
        raise ValueError(f"iou_threshold must lie in (0, 1], got {iou_threshold!r}")
    present = sorted({int(c) for _, cs, _ in g for c in cs})
    wanted = present if classes is None else [int(c) for c in classes]
    per_class: dict[int, dict[str, np.ndarray]] = {}
    errors, error_frames = [], []  # (translation, scale, orientation) of every matched pair, and its frame
    for cls in wanted:
        pb, ps, po = _concat([(b[cs == cls], sc[cs == cls]) for b, cs, sc in p])
        gb, _, go = _concat([(b[cs == cls], np.zeros(int((cs == cls).sum()))) for b, cs, _ in g])
        match = _match(pb, ps, po, gb, go, float(iou_threshold))  # matched gt row per prediction, or -1
        order = np.argsort(-ps, kind="stable")
        frame = np.repeat(np.arange(len(po) - 1), np.diff(po))
        per_class[cls] = {"frame": frame[order], "tp": (match[order] >= 0), "n_gt": np.diff(go)}
        hit = np.flatnonzero(match >= 0)
        if len(hit):
            a_, t_ = pb[hit], gb[match[hit]]
            errors.append(np.stack([np.hypot(a_[:, 0] - t_[:, 0], a_[:, 1] - t_[:, 1]),
                                    1.0 - scale_iou(a_[:, 3:6], t_[:, 3:6]), _wrap(a_[:, 6] - t_[:, 6])], axis=1))
            error_frames.append(frame[hit])
    return {"classes": per_class, "errors": np.concatenate(errors) if errors else np.zeros((0, 3)),
            "error_frames": np.concatenate(error_frames).astype(np.int64) if error_frames else np.zeros(0, np.int64),
            "frames": len(g), "n_pred": sum(len(cs) for _, cs, _ in p)}  # fmt: skip


def _weighted_ap(tp: np.ndarray, w: np.ndarray, n_gt: np.ndarray) -> np.ndarray:
    """All-point AP per row of ``w`` (R, D): detections in descending score with true-positive flags ``tp`` (D,),
    each counted ``w`` times (a frame drawn twice counts its detections twice); ``n_gt`` (R,). NaN where
    ``n_gt`` is 0. Equal to :func:`average_precision` of the detections repeated ``w`` times."""
    if tp.size == 0:
        return np.where(n_gt > 0, 0.0, np.nan)
    ctp = np.cumsum(w * tp, axis=1)
    cn = np.cumsum(w, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        precision = np.where(cn > 0, ctp / np.maximum(cn, 1e-300), 0.0)
        envelope = np.maximum.accumulate(precision[:, ::-1], axis=1)[:, ::-1]
        recall = ctp / np.where(n_gt > 0, n_gt, 1.0)[:, None]
        steps = np.diff(recall, axis=1, prepend=0.0)
        ap = np.sum(steps * envelope, axis=1)
    return np.where(n_gt > 0, ap, np.nan)


def summarise(m: Mapping[str, Any], weights: np.ndarray | None = None) -> dict[str, Any]:
    """The metrics of :func:`evaluate` from a :func:`match_frames` result, each frame counted ``weights[f]``
    times; ``weights`` (F,) gives scalars, (R, F) one value per row (R resamples at once); default: every frame once.
    ``AP`` per class, ``mAP`` (NaN without ground truth), TP errors and scores, ``mean_TP``, ``FDS``."""
    single = weights is None or np.ndim(weights) == 1
    w = np.ones((1, m["frames"])) if weights is None else np.atleast_2d(np.asarray(weights, np.float64))
    if w.shape[1] != m["frames"]:
        raise ValueError(f"weights must have one entry per frame ({m['frames']}), got shape {w.shape}")
    ap: dict[int, np.ndarray] = {}
    for cls, c in m["classes"].items():
        n_gt = w @ c["n_gt"].astype(np.float64)
        if n_gt.max() > 0:
            ap[cls] = _weighted_ap(c["tp"].astype(np.float64), w[:, c["frame"]], n_gt)
    with np.errstate(invalid="ignore"):
        m_ap = nanmean(np.stack(list(ap.values()))) if ap else np.full(len(w), np.nan)
    e, ew = m["errors"], w[:, m["error_frames"]]
    count = ew.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        raw = (ew @ e) / count[:, None] if len(e) else np.full((len(w), 3), np.nan)
    raw[count == 0] = np.nan
    scores = np.stack([np.where(np.isnan(raw[:, k]), 0.0, np.clip(1.0 - raw[:, k] / cap, 0.0, 1.0))
                       for k, cap in enumerate((ATE_CAP_M, ASE_CAP, AOE_CAP_RAD))], axis=1)  # fmt: skip
    mean_tp = scores.mean(axis=1)
    out = {"mAP": m_ap, "AP": ap, "ATE": scores[:, 0], "ASE": scores[:, 1], "AOE": scores[:, 2], "mean_TP": mean_tp,
           "FDS": 0.5 * m_ap + 0.5 * mean_tp, "ATE_m": raw[:, 0], "ASE_raw": raw[:, 1], "AOE_rad": raw[:, 2]}  # fmt: skip
    if single:
        out = {k: ({c: float(v[0]) for c, v in x.items()} if k == "AP" else float(x[0])) for k, x in out.items()}
    return out


def evaluate(gt: Sequence[Mapping[str, Any]], pred: Sequence[Mapping[str, Any]], iou_threshold: float = 0.5,
             classes: Sequence[int] | None = None) -> dict[str, Any]:  # fmt: skip
    """mAP@``iou_threshold`` (3D IoU), per-class AP, TP errors and scores, Mean TP and FDS (module docstring)."""
    m = match_frames(gt, pred, iou_threshold, classes)
    r = summarise(m)
    r["AP"] = {c: v for c, v in r["AP"].items() if not math.isnan(v)}
    return r | {"n_gt": int(sum(c["n_gt"].sum() for c in m["classes"].values()) if classes is None else
                            sum(len(cs) for f in gt for cs in [np.asarray(f["classes"]).reshape(-1)])),
                "n_pred": m["n_pred"], "n_tp": len(m["errors"])}  # fmt: skip


#: Distance bands of the bird's-eye distance from the sensor to a box's centre [m]: near, mid and far (the grid's
#: corners reach 40 √2 ≈ 57 m).
DISTANCE_BANDS = {"0-20 m": (0.0, 20.0), "20-40 m": (20.0, 40.0), "40+ m": (40.0, math.inf)}


def evaluate_bands(gt: Sequence[Mapping[str, Any]], pred: Sequence[Mapping[str, Any]],
                   bands: Mapping[str, tuple[float, float]] = DISTANCE_BANDS, **kwargs: Any) -> dict[str, dict[str, Any]]:
    """:func:`evaluate` per distance band: ground truth and predictions whose centre lies ``lo ≤ d < hi`` from the
    sensor (bird's-eye distance), each band on its own (a prediction just across a band's edge from its ground truth
    counts as a miss and a false positive, as in KITTI's and nuScenes' range filters).

    >>> box = np.array([[30.0, 0.0, 0.0, 4.0, 2.0, 1.5, 0.0]])
    >>> r = evaluate_bands([{"boxes": box, "classes": [0]}], [{"boxes": box, "classes": [0], "scores": [0.9]}])
    >>> {k: v["mAP"] for k, v in r.items()}
    {'0-20 m': nan, '20-40 m': 1.0, '40+ m': nan}
    """

    def within(frames: Sequence[Mapping[str, Any]], lo: float, hi: float, scores: bool) -> list[dict[str, Any]]:
        out = []
        for f in frames:
            b = as_boxes(f["boxes"])
            d = np.hypot(b[:, 0], b[:, 1])
            m = (d >= lo) & (d < hi)
            item = {"boxes": b[m], "classes": np.asarray(f["classes"]).reshape(-1)[m]}
            if scores:
                item["scores"] = np.asarray(f["scores"], np.float64).reshape(-1)[m]
            out.append(item)
        return out

    return {name: evaluate(within(gt, lo, hi, False), within(pred, lo, hi, True), **kwargs) for name, (lo, hi) in bands.items()}

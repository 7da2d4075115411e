"""Training targets and losses of the YOLO-style detector (:mod:`~.yolo`), written from the papers.

**Task-aligned assignment** (TOOD, Feng et al., ICCV 2021), :func:`assign`. For every ground-truth box ``g`` and
every cell centre (anchor point) ``a`` inside it, the alignment metric ``t = s^α · u^β`` combines the predicted
score ``s`` of ``g``'s class at ``a`` with the IoU ``u`` of ``a``'s predicted box with ``g``; the ``top_k`` anchors
of highest ``t`` become ``g``'s positives. An anchor claimed by several boxes keeps the one it overlaps most. The
class target of a positive is the normalised alignment ``t̂ = t / max_g(t) · max_g(u)`` (the box's best anchor gets
the box's best IoU), zero elsewhere; ``t̂`` also weights the box losses. Constants: ``α = 0.5``, ``β = 6``,
``top_k = 10`` (YOLOv8's choice within TOOD's scheme; TOOD itself uses α = 1, β = 6, top 13). A box that holds no
cell centre of any level (narrower or lower than the finest stride) takes the finest level's cell nearest its
centre as its only candidate, so that no box is unlearnable.

**Losses** (:func:`detection_loss`), each normalised by the sum of the class targets: binary cross-entropy of the
class logits against ``t̂`` (gain 0.5), ``1 − CIoU`` of the positives' boxes weighted by ``t̂`` (gain 7.5) and the
Distribution Focal Loss of their side distances (GFL, Li et al., NeurIPS 2020; gain 1.5) — YOLOv8's gains.

**CIoU** (Zheng et al., AAAI 2020), :func:`ciou`: ``IoU − ρ²/c² − α v`` with ``ρ`` the centres' distance, ``c`` the
diagonal of the smallest enclosing box, ``v = 4/π² (arctan(w_g/h_g) − arctan(w/h))²`` and ``α = v / (1 − IoU + v)``.

Example:
    >>> a = torch.tensor([[0.0, 0.0, 10.0, 10.0]])
    >>> float(ciou(a, a)), round(float(box_iou(a, torch.tensor([[5.0, 0.0, 15.0, 10.0]]))[0, 0]), 4)
    (1.0, 0.3333)
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F

from fog_gym.experiments.defog.yolo import anchor_points, boxes_from_distances, distances, flatten

ALPHA, BETA, TOP_K = 0.5, 6.0, 10
GAINS = {"box": 7.5, "cls": 0.5, "dfl": 1.5}
EPS = 1e-9


def box_iou(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """IoU ``(N, M)`` of boxes ``a`` (N, 4) and ``b`` (M, 4), ``[x0, y0, x1, y1]``."""
    lt = torch.maximum(a[:, None, :2], b[None, :, :2])
    rb = torch.minimum(a[:, None, 2:], b[None, :, 2:])
    inter = (rb - lt).clamp(min=0).prod(-1)
    area_a = (a[:, 2:] - a[:, :2]).clamp(min=0).prod(-1)
    area_b = (b[:, 2:] - b[:, :2]).clamp(min=0).prod(-1)
    return inter / (area_a[:, None] + area_b[None, :] - inter + EPS)


def ciou(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Elementwise CIoU of matching rows of ``a`` and ``b`` (…, 4) (module docstring); 1 for identical boxes."""
    w1, h1 = (a[..., 2] - a[..., 0]).clamp(min=EPS), (a[..., 3] - a[..., 1]).clamp(min=EPS)
    w2, h2 = (b[..., 2] - b[..., 0]).clamp(min=EPS), (b[..., 3] - b[..., 1]).clamp(min=EPS)
    iw = (torch.minimum(a[..., 2], b[..., 2]) - torch.maximum(a[..., 0], b[..., 0])).clamp(min=0)
    ih = (torch.minimum(a[..., 3], b[..., 3]) - torch.maximum(a[..., 1], b[..., 1])).clamp(min=0)
    inter = iw * ih
    iou = inter / (w1 * h1 + w2 * h2 - inter + EPS)
    cw = torch.maximum(a[..., 2], b[..., 2]) - torch.minimum(a[..., 0], b[..., 0])
    ch = torch.maximum(a[..., 3], b[..., 3]) - torch.minimum(a[..., 1], b[..., 1])
    c2 = cw**2 + ch**2 + EPS
    rho2 = ((a[..., 0] + a[..., 2] - b[..., 0] - b[..., 2]) ** 2 + (a[..., 1] + a[..., 3] - b[..., 1] - b[..., 3]) ** 2) / 4
    v = (4 / math.pi**2) * (torch.atan(w2 / h2) - torch.atan(w1 / h1)) ** 2
    with torch.no_grad():
        alpha = v / ((1.0 - iou) + v + 1e-7)
    return iou - (rho2 / c2 + v * alpha)


@torch.no_grad()
def assign(scores: torch.Tensor, pred_boxes: torch.Tensor, points: torch.Tensor, gt_boxes: torch.Tensor,
           gt_classes: torch.Tensor, gt_mask: torch.Tensor, finest: int, top_k: int = TOP_K, alpha: float = ALPHA,
           beta: float = BETA) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:  # fmt: skip
    """Task-aligned assignment (module docstring) for a batch.

    ``scores`` (B, A, K) predicted class probabilities, ``pred_boxes`` (B, A, 4) pixels, ``points`` (A, 2) anchor
    points, ``gt_boxes`` (B, G, 4), ``gt_classes`` (B, G) channel indices, ``gt_mask`` (B, G) real boxes (the rest
    padding), ``finest``: the number of anchors of the finest level (they come first). Returns ``target_boxes``
    (B, A, 4), ``target_scores`` (B, A, K) and ``fg`` (B, A) booleans.
    """
    b, a, k = scores.shape
    g = gt_boxes.shape[1]
    if g == 0:
        return torch.zeros_like(pred_boxes), torch.zeros_like(scores), torch.zeros(b, a, dtype=torch.bool, device=scores.device)
    px, py = points[:, 0], points[:, 1]
    inside = ((px[None, None] > gt_boxes[..., 0:1]) & (py[None, None] > gt_boxes[..., 1:2]) &
              (px[None, None] < gt_boxes[..., 2:3]) & (py[None, None] < gt_boxes[..., 3:4]))  # (B, G, A)  # fmt: skip
    # a box with no anchor inside: the finest level's anchor nearest its centre
    empty = ~inside.any(-1) & gt_mask
    if empty.any():
        centre = (gt_boxes[..., :2] + gt_boxes[..., 2:]) / 2  # (B, G, 2)
        d = ((points[None, None, :finest] - centre[..., None, :]) ** 2).sum(-1)  # (B, G, finest)
        nearest = d.argmin(-1)
        bi, gi = empty.nonzero(as_tuple=True)
        inside[bi, gi, nearest[bi, gi]] = True
    inside &= gt_mask[..., None]
    cls_idx = gt_classes.clamp(min=0).long()
    s = scores.gather(2, cls_idx[:, None, :].expand(b, a, g)).transpose(1, 2)  # (B, G, A): score of g's class
    iou = torch.zeros(b, g, a, dtype=scores.dtype, device=scores.device)
    for i in range(b):  # per image: (G, A)
        iou[i] = box_iou(gt_boxes[i], pred_boxes[i])
    iou = iou * inside
    metric = s.pow(alpha) * iou.pow(beta) * inside
    kk = min(top_k, a)
    top = metric.topk(kk, dim=-1).indices  # (B, G, k)
    chosen = torch.zeros_like(inside)
    chosen.scatter_(-1, top, True)
    pos = chosen & inside  # the top-k candidates (with fewer than k candidates, all of them)
    # an anchor claimed by several boxes keeps the box it overlaps most
    multi = pos.sum(1) > 1  # (B, A)
    if multi.any():
        best = (iou * pos).argmax(1)  # (B, A)
        keep = F.one_hot(best, g).transpose(1, 2).bool()  # (B, G, A)
        pos = torch.where(multi[:, None, :], pos & keep, pos)
    fg = pos.any(1)  # (B, A)
    which = pos.float().argmax(1)  # (B, A): the assigned box
    target_boxes = gt_boxes.gather(1, which[..., None].expand(b, a, 4))
    target_cls = cls_idx.gather(1, which)
    # normalised alignment: t / max over the box's positives of t × max over them of IoU
    metric = metric * pos
    iou_pos = iou * pos
    norm = metric / (metric.amax(-1, keepdim=True) + EPS) * iou_pos.amax(-1, keepdim=True)
    t_hat = norm.amax(1)  # (B, A)
    target_scores = F.one_hot(target_cls, k).to(scores.dtype) * (t_hat * fg)[..., None]
    return target_boxes, target_scores, fg


def dfl(dist_logits: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Distribution Focal Loss per side: cross-entropy with the two bins around the target distance ``target``
    (stride units, clamped into ``[0, reg_max − 1 − 0.01]``), weighted by proximity; (N, 4, R) and (N, 4) → (N, 4)."""
    r = dist_logits.shape[-1]
    t = target.clamp(0, r - 1 - 0.01)
    left = t.floor().long()
    wl = left + 1 - t
    logp = dist_logits.log_softmax(-1)
    return -(logp.gather(-1, left[..., None])[..., 0] * wl + logp.gather(-1, (left + 1)[..., None])[..., 0] * (1 - wl))


def detection_loss(outputs: list[torch.Tensor], gt_boxes: torch.Tensor, gt_classes: torch.Tensor,
                   gt_mask: torch.Tensor, reg_max: int = 16,
                   strides=(4, 8, 16)) -> tuple[torch.Tensor, dict[str, float]]:  # fmt: skip
    """The training loss of a batch (module docstring): ``outputs`` from the network, ground truth padded to
    ``(B, G, 4)`` pixels with class channel indices ``(B, G)`` and a mask of the real boxes; returns the loss (scaled
    by the batch size, as YOLOv8) and its parts."""
    dist_logits, cls_logits = flatten(outputs, reg_max)
    shapes = [tuple(o.shape[-2:]) for o in outputs]
    points, stride = anchor_points(shapes, strides, outputs[0].device)
    dist = distances(dist_logits.float())  # (B, A, 4) stride units
    pred_boxes = boxes_from_distances(points, dist * stride[:, None])
    target_boxes, target_scores, fg = assign(cls_logits.detach().sigmoid().float(), pred_boxes.detach(), points,
                                             gt_boxes.float(), gt_classes, gt_mask, shapes[0][0] * shapes[0][1])  # fmt: skip
    norm = target_scores.sum().clamp(min=1.0)
    l_cls = F.binary_cross_entropy_with_logits(cls_logits.float(), target_scores, reduction="sum") / norm
    if fg.any():
        w = target_scores.sum(-1)[fg]
        l_box = ((1.0 - ciou(pred_boxes[fg], target_boxes[fg])) * w).sum() / norm
        st = stride[None].expand(fg.shape)[fg][:, None]
        p = points[None].expand(fg.shape[0], -1, -1)[fg]
        target_ltrb = torch.cat([p - target_boxes[fg][:, :2], target_boxes[fg][:, 2:] - p], -1) / st
        l_dfl = (dfl(dist_logits[fg].float(), target_ltrb).mean(-1) * w).sum() / norm
    else:
        l_box = l_dfl = dist_logits.sum() * 0.0
    b = cls_logits.shape[0]
    loss = (GAINS["box"] * l_box + GAINS["cls"] * l_cls + GAINS["dfl"] * l_dfl) * b
    return loss, {"box": float(l_box.detach()), "cls": float(l_cls.detach()), "dfl": float(l_dfl.detach()),
                  "positives": int(fg.sum())}  # fmt: skip


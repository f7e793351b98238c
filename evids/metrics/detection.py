"""Detection and tracking metrics: IoU matching, AP50, Anti-UAV state accuracy, MOTA/IDF1.

Boxes are ``[x, y, w, h]`` (top-left + size, pixels) unless ``fmt="xyxy"``.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from evids.metrics._arrays import as_numpy, bool_1d
from evids.metrics.classification import uauc

BoxFormat = Literal["xywh", "xyxy"]

__all__ = [
    "DetectionMatch",
    "average_precision",
    "box_iou",
    "detection_uauc",
    "match_detections",
    "mot_metrics",
    "state_accuracy",
]


def _boxes(b: Any, name: str, fmt: BoxFormat) -> np.ndarray:
    if fmt not in ("xywh", "xyxy"):
        raise ValueError(f"fmt must be 'xywh' or 'xyxy', got {fmt!r}")
    a = as_numpy(b, name).astype(np.float64)
    if a.size == 0:
        return np.zeros((0, 4))
    if a.ndim == 1:
        a = a[None, :]
    if a.ndim != 2 or a.shape[1] != 4:
        raise ValueError(f"{name} must have shape (N, 4), got {a.shape}")
    if not np.isfinite(a).all():
        raise ValueError(f"{name} contains non-finite values")
    if fmt == "xywh":
        if (a[:, 2:] < 0).any():
            raise ValueError(f"{name} has negative width/height")
        a = np.concatenate([a[:, :2], a[:, :2] + a[:, 2:]], axis=1)
    elif ((a[:, 2:] - a[:, :2]) < 0).any():
        raise ValueError(f"{name} has x2 < x1 or y2 < y1")
    return a


def box_iou(boxes_a: Any, boxes_b: Any, fmt: BoxFormat = "xywh") -> np.ndarray:
    """Pairwise IoU matrix (N, M); 0 where the union is empty."""
    a = _boxes(boxes_a, "boxes_a", fmt)
    b = _boxes(boxes_b, "boxes_b", fmt)
    lt = np.maximum(a[:, None, :2], b[None, :, :2])
    rb = np.minimum(a[:, None, 2:], b[None, :, 2:])
    inter = np.clip(rb - lt, 0.0, None).prod(axis=2)
    area_a = (a[:, 2:] - a[:, :2]).prod(axis=1)
    area_b = (b[:, 2:] - b[:, :2]).prod(axis=1)
    union = area_a[:, None] + area_b[None, :] - inter
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(union > 0, inter / np.where(union > 0, union, 1.0), 0.0)


@dataclass(frozen=True)
class DetectionMatch:
    """``is_tp`` (N,) per prediction, ``gt_index`` (N,) matched ground truth or -1, ``iou`` (N,) IoU
    with the matched ground truth (0 if unmatched), and ``num_gt``."""

    is_tp: np.ndarray
    gt_index: np.ndarray
    iou: np.ndarray
    num_gt: int


def match_detections(
    pred_boxes: Any,
    scores: Any,
    gt_boxes: Any,
    iou_threshold: float = 0.5,
    fmt: BoxFormat = "xywh",
) -> DetectionMatch:
    """Greedy one-to-one matching in descending score order (PASCAL VOC / COCO style): each
    prediction takes the unmatched ground truth with the highest IoU if that IoU >= threshold."""
    if not 0.0 < iou_threshold <= 1.0:
        raise ValueError(f"iou_threshold must be in (0, 1], got {iou_threshold!r}")
    p = _boxes(pred_boxes, "pred_boxes", fmt)
    g = _boxes(gt_boxes, "gt_boxes", fmt)
    s = as_numpy(scores, "scores").astype(np.float64).reshape(-1)
    if s.shape[0] != p.shape[0]:
        raise ValueError(f"scores must have {p.shape[0]} entries (one per prediction), got {s.shape[0]}")
    ious = box_iou(p, g, fmt="xyxy")
    is_tp = np.zeros(p.shape[0], dtype=bool)
    gt_index = np.full(p.shape[0], -1, dtype=np.int64)
    matched_iou = np.zeros(p.shape[0])
    taken = np.zeros(g.shape[0], dtype=bool)
    for i in np.argsort(-s, kind="stable"):
        if g.shape[0] == 0:
            break
        cand = np.where(taken, -1.0, ious[i])
        j = int(np.argmax(cand))
        if cand[j] >= iou_threshold:
            taken[j] = True
            is_tp[i] = True
            gt_index[i] = j
            matched_iou[i] = ious[i, j]
    return DetectionMatch(is_tp, gt_index, matched_iou, int(g.shape[0]))


def average_precision(
    images: Sequence[tuple[Any, Any, Any]],
    iou_threshold: float = 0.5,
    fmt: BoxFormat = "xywh",
    interpolation: Literal["all", "coco101"] = "all",
) -> float:
    """AP at ``iou_threshold`` (AP50 by default) over images given as ``(pred_boxes, scores,
    gt_boxes)``. Predictions from all images are ranked by score; precision is made monotone
    (running max from the right) and integrated over recall at every recall step (``"all"``, VOC
    2010+) or sampled at 101 recall points (``"coco101"``). NaN when there is no ground truth."""
    if interpolation not in ("all", "coco101"):
        raise ValueError(f"interpolation must be 'all' or 'coco101', got {interpolation!r}")
    all_scores, all_tp, num_gt = [], [], 0
    for k, item in enumerate(images):
        if len(item) != 3:
            raise ValueError(f"images[{k}] must be (pred_boxes, scores, gt_boxes)")
        m = match_detections(item[0], item[1], item[2], iou_threshold, fmt)
        all_scores.append(as_numpy(item[1], "scores").astype(np.float64).reshape(-1))
        all_tp.append(m.is_tp)
        num_gt += m.num_gt
    if num_gt == 0:
        return float("nan")
    scores = np.concatenate(all_scores) if all_scores else np.zeros(0)
    tp = np.concatenate(all_tp) if all_tp else np.zeros(0, dtype=bool)
    order = np.argsort(-scores, kind="stable")
    tp = tp[order]
    ctp = np.cumsum(tp)
    cfp = np.cumsum(~tp)
    recall = ctp / num_gt
    precision = ctp / np.maximum(ctp + cfp, 1)
    envelope = np.maximum.accumulate(precision[::-1])[::-1] if precision.size else precision
    if interpolation == "all":
        r = np.concatenate([[0.0], recall])
        return float(np.sum((r[1:] - r[:-1]) * envelope))
    points = np.linspace(0.0, 1.0, 101)
    idx = np.searchsorted(recall, points, side="left")
    vals = np.zeros(points.size)
    valid = idx < envelope.size
    vals[valid] = envelope[idx[valid]]
    return float(np.mean(vals))


def detection_uauc(uncertainty: Any, is_tp: Any) -> float:
    """UAUC at detection level: AUROC of the detection's uncertainty for being a false positive."""
    tp = bool_1d(is_tp, None, "is_tp")
    return uauc(uncertainty, ~tp)


def _frame_box(x: Any) -> np.ndarray | None:
    """A frame's box or None for 'no box' (None, [], [0], or a box with zero width/height)."""
    if x is None:
        return None
    a = np.asarray(x, dtype=np.float64).reshape(-1)
    if a.size == 0 or (a.size == 1 and a[0] == 0):
        return None
    if a.size != 4 or not np.isfinite(a).all():
        raise ValueError(f"a frame box must be [x, y, w, h], [] or [0], got {x!r}")
    if a[2] <= 0 or a[3] <= 0:
        return None
    return a


def state_accuracy(
    pred_boxes: Sequence[Any],
    gt_boxes: Sequence[Any],
    exist: Sequence[Any] | np.ndarray,
    variant: Literal["plain", "penalised"] = "plain",
) -> float:
    """Anti-UAV state accuracy of one sequence (boxes ``[x, y, w, h]``; no box = None, [] or [0]).

    Per frame: IoU(pred, gt) where the target exists (0 without a prediction), and 1 for an empty
    prediction (else 0) where it does not. ``"plain"`` (Anti-UAV410/600 toolkit): the mean of the
    per-frame values. ``"penalised"`` (EDTC / challenge form): that mean minus
    ``0.2 * (mean penalty)^0.3``, the penalty being 1 on target-present frames with no prediction
    or a non-overlapping one (IoU = 0), averaged over the target-present frames (0 if none).
    """
    if variant not in ("plain", "penalised"):
        raise ValueError(f"variant must be 'plain' or 'penalised', got {variant!r}")
    if not (len(pred_boxes) == len(gt_boxes) == len(exist)):
        raise ValueError(
            f"pred_boxes, gt_boxes and exist must have equal length, got {len(pred_boxes)}, {len(gt_boxes)}, "
            f"{len(exist)}"
        )
    if len(exist) == 0:
        raise ValueError("state_accuracy needs at least one frame")
    values, penalties = [], []
    for t, (pb, gb, ex) in enumerate(zip(pred_boxes, gt_boxes, exist)):
        p = _frame_box(pb)
        if bool(ex):
            g = _frame_box(gb)
            if g is None:
                raise ValueError(f"frame {t}: exist is 1 but gt_boxes has no box ({gb!r})")
            iou = 0.0 if p is None else float(box_iou(p, g)[0, 0])
            values.append(iou)
            penalties.append(1.0 if iou == 0.0 else 0.0)
        else:
            values.append(1.0 if p is None else 0.0)
    acc = float(np.mean(values))
    if variant == "penalised" and penalties:
        acc -= 0.2 * float(np.mean(penalties)) ** 0.3
    return acc


def mot_metrics(
    gt: Sequence[tuple[Any, Any]],
    hyp: Sequence[tuple[Any, Any]],
    iou_threshold: float = 0.5,
    fmt: BoxFormat = "xywh",
) -> dict[str, float]:
    """MOTA, MOTP, IDF1, ID switches, precision and recall via ``motmetrics`` (optional dependency).

    ``gt`` and ``hyp`` list, per frame, ``(ids, boxes)``. A pair is a match candidate when
    IoU >= ``iou_threshold`` (distance ``1 - IoU``, as in the MOTChallenge protocol). For HOTA
    (not provided by motmetrics) see ``evids.metrics.hota``.
    """
    try:
        import motmetrics as mm
    except ImportError as exc:
        raise ImportError("mot_metrics needs the 'motmetrics' package: pip install motmetrics") from exc
    if len(gt) != len(hyp):
        raise ValueError(f"gt and hyp must cover the same frames, got {len(gt)} and {len(hyp)}")
    if not 0.0 < iou_threshold <= 1.0:
        raise ValueError(f"iou_threshold must be in (0, 1], got {iou_threshold!r}")
    acc = mm.MOTAccumulator(auto_id=True)
    for t, ((gid, gbox), (hid, hbox)) in enumerate(zip(gt, hyp)):
        gid_l = list(np.asarray(gid).reshape(-1).tolist())
        hid_l = list(np.asarray(hid).reshape(-1).tolist())
        ious = box_iou(gbox, hbox, fmt)
        if ious.shape != (len(gid_l), len(hid_l)):
            raise ValueError(f"frame {t}: ids and boxes disagree in length")
        dist = np.where(ious >= iou_threshold, 1.0 - ious, np.nan)
        acc.update(gid_l, hid_l, dist)
    names = ["mota", "motp", "idf1", "num_switches", "precision", "recall"]
    summary = mm.metrics.create().compute(acc, metrics=names, name="all")
    return {k: float(summary[k].iloc[0]) for k in names}

"""Tracking metrics via ``trackeval`` (the PyPI package, 1.3.0: runs on NumPy 2 as is, no shim):
HOTA (Luiten et al., IJCV 2021), CLEAR MOT (MOTA, MOTP, ID switches) and Identity (IDF1).

One sequence at a time from per-frame ``(ids, boxes)``; similarity is box IoU. CLEAR and Identity
match at IoU >= 0.5 (the MOTChallenge / MM-UAV toolkit threshold); HOTA averages over
alpha = 0.05 .. 0.95. ``trackeval`` is an optional dependency (the ``tracking`` and ``dev`` extras).
"""
from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from evids.metrics.detection import BoxFormat, box_iou

__all__ = ["hota", "track_scores"]


def _frame_ids(ids: Any, t: int, name: str) -> list[Any]:
    out = list(np.asarray(ids).reshape(-1).tolist())
    if len(set(out)) != len(out):
        raise ValueError(f"frame {t}: {name} ids must be unique within a frame, got {out}")
    return out


def _import_trackeval():
    try:
        from trackeval import metrics
    except ImportError as exc:
        raise ImportError("tracking metrics need the 'trackeval' package: pip install --no-deps trackeval==1.3.0 "
                          "(plus pycocotools, tabulate; --no-deps keeps opencv-python from replacing the "
                          "headless OpenCV)") from exc
    return metrics


def _sequence_data(gt: Sequence[tuple[Any, Any]], hyp: Sequence[tuple[Any, Any]], fmt: BoxFormat) -> dict[str, Any]:
    """trackeval's per-sequence dict (ids relabelled 0..n-1, IoU similarity per frame)."""
    if len(gt) != len(hyp):
        raise ValueError(f"gt and hyp must cover the same frames, got {len(gt)} and {len(hyp)}")
    gt_index: dict[Any, int] = {}
    hyp_index: dict[Any, int] = {}
    gt_ids: list[np.ndarray] = []
    hyp_ids: list[np.ndarray] = []
    sims: list[np.ndarray] = []
    for t, ((gid, gbox), (hid, hbox)) in enumerate(zip(gt, hyp)):
        gid_l = _frame_ids(gid, t, "gt")
        hid_l = _frame_ids(hid, t, "hyp")
        ious = box_iou(gbox, hbox, fmt)
        if ious.shape != (len(gid_l), len(hid_l)):
            raise ValueError(f"frame {t}: ids and boxes disagree in length")
        gt_ids.append(np.array([gt_index.setdefault(i, len(gt_index)) for i in gid_l], dtype=int))
        hyp_ids.append(np.array([hyp_index.setdefault(i, len(hyp_index)) for i in hid_l], dtype=int))
        sims.append(ious)
    return {
        "gt_ids": gt_ids, "tracker_ids": hyp_ids, "similarity_scores": sims,
        "num_gt_ids": len(gt_index), "num_tracker_ids": len(hyp_index),
        "num_gt_dets": sum(len(i) for i in gt_ids), "num_tracker_dets": sum(len(i) for i in hyp_ids),
        "num_timesteps": len(gt),
    }


def hota(
    gt: Sequence[tuple[Any, Any]],
    hyp: Sequence[tuple[Any, Any]],
    fmt: BoxFormat = "xywh",
) -> dict[str, float]:
    """HOTA, DetA and AssA of one sequence via ``trackeval``'s ``HOTA.eval_sequence``.

    ``gt`` and ``hyp`` list, per frame, ``(ids, boxes)`` as in ``mot_metrics``. Similarity is box
    IoU; each score is trackeval's mean over the 19 IoU thresholds alpha = 0.05, 0.10, ..., 0.95
    (so there is no ``iou_threshold``). An empty hypothesis (or empty ground truth) gives 0.
    """
    metrics = _import_trackeval()
    res = metrics.HOTA().eval_sequence(_sequence_data(gt, hyp, fmt))
    return {k.lower(): float(np.mean(res[k])) for k in ("HOTA", "DetA", "AssA")}


def track_scores(
    gt: Sequence[tuple[Any, Any]],
    hyp: Sequence[tuple[Any, Any]],
    fmt: BoxFormat = "xywh",
) -> dict[str, float]:
    """HOTA, DetA, AssA, MOTA, MOTP, IDF1, IDSW, FP and FN of one sequence, all via ``trackeval``
    (HOTA over alpha = 0.05..0.95; CLEAR and Identity at IoU >= 0.5, as the MM-UAV toolkit runs them)."""
    metrics = _import_trackeval()
    data = _sequence_data(gt, hyp, fmt)
    h = metrics.HOTA().eval_sequence(data)
    config = {"THRESHOLD": 0.5, "PRINT_CONFIG": False}
    c = metrics.CLEAR(config).eval_sequence(data)
    i = metrics.Identity(config).eval_sequence(data)
    out = {k.lower(): float(np.mean(h[k])) for k in ("HOTA", "DetA", "AssA")}
    out.update({"mota": float(c["MOTA"]), "motp": float(c["MOTP"]), "idf1": float(i["IDF1"]),
                "idsw": float(c["IDSW"]), "fp": float(c["CLR_FP"]), "fn": float(c["CLR_FN"])})
    return out

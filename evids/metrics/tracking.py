"""HOTA tracking metric (Luiten et al., IJCV 2021) via ``trackeval`` (optional dependency)."""
from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from evids.metrics.detection import BoxFormat, box_iou

__all__ = ["hota"]


def _frame_ids(ids: Any, t: int, name: str) -> list[Any]:
    out = list(np.asarray(ids).reshape(-1).tolist())
    if len(set(out)) != len(out):
        raise ValueError(f"frame {t}: {name} ids must be unique within a frame, got {out}")
    return out


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
    try:
        from trackeval.metrics import HOTA
    except ImportError as exc:
        raise ImportError("hota needs the 'trackeval' package: pip install trackeval") from exc
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
        # trackeval wants ids relabelled to 0..num_ids-1 over the whole sequence
        gt_ids.append(np.array([gt_index.setdefault(i, len(gt_index)) for i in gid_l], dtype=int))
        hyp_ids.append(np.array([hyp_index.setdefault(i, len(hyp_index)) for i in hid_l], dtype=int))
        sims.append(ious)
    data = {
        "gt_ids": gt_ids,
        "tracker_ids": hyp_ids,
        "similarity_scores": sims,
        "num_gt_ids": len(gt_index),
        "num_tracker_ids": len(hyp_index),
        "num_gt_dets": sum(len(i) for i in gt_ids),
        "num_tracker_dets": sum(len(i) for i in hyp_ids),
        "num_timesteps": len(gt),
    }
    res = HOTA().eval_sequence(data)
    return {k.lower(): float(np.mean(res[k])) for k in ("HOTA", "DetA", "AssA")}
